// RGB-D sequences in the TUM RGB-D benchmark layout (Sturm et al., IROS 2012), written from
// rendered frames and read back (or read from real TUM sequences).
//
// Layout of a sequence directory DIR:
//   DIR/rgb/<t>.png       8-bit colour PNG (3 channels)
//   DIR/depth/<t>.png     16-bit PNG, depth z in units of 1/depth_scale m (TUM: 5000 units per
//                         metre), 0 = no return
//   DIR/rgb.txt, DIR/depth.txt   "timestamp filename" per line, filename relative to DIR
//   DIR/groundtruth.txt   "timestamp tx ty tz qx qy qz qw": the pose of the camera optical frame
//                         in the world (world_T_camera, TUM's convention); optional on reading
//   DIR/camera.txt        the intrinsics (moslam's addition; TUM publishes them on its web page):
//                         one line "fx fy cx cy width height depth_scale"
// <t> is the timestamp in seconds with 6 decimals. Lines starting with '#' and blank lines are
// comments (TUM's files start with three of them). Timestamps are seconds (double).
//
// Reading associates every colour image with the depth image nearest in time, within
// max_time_difference, each used once (TUM's associate.py: candidate pairs sorted by time
// difference, accepted greedily), and each such frame with the nearest ground-truth pose within
// the same tolerance, when there is ground truth. Malformed files throw InvalidInputError naming
// the file, the line number and what is wrong.
#pragma once

#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/render/rgbd.h"

namespace moslam {

struct TumFrame {
  double rgb_timestamp = 0.0;
  std::string rgb_file;  // relative to the sequence directory
  double depth_timestamp = 0.0;
  std::string depth_file;
  std::optional<SE3> world_T_camera;  // from groundtruth.txt, when associated
};

struct TumSequence {
  std::string directory;
  PinholeIntrinsics intrinsics;
  double depth_scale = 5000.0;  // depth PNG units per metre
  std::vector<TumFrame> frames;  // by rgb timestamp
};

struct TumReadOptions {
  double max_time_difference = 0.02;  // s (associate.py's default)
  // Used when DIR/camera.txt is missing (real TUM sequences); an error when both are missing.
  std::optional<PinholeIntrinsics> intrinsics;
  double depth_scale = 5000.0;  // used with `intrinsics`
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// Throws InvalidInputError on a missing or malformed file.
TumSequence ReadTumSequence(const std::string& directory, const TumReadOptions& options = {});

// The text files of a sequence directory, as ReadTumSequence reads them.
struct TumSequenceText {
  std::optional<std::string> camera;       // camera.txt, when there is one
  std::string rgb, depth;                  // rgb.txt, depth.txt
  std::optional<std::string> groundtruth;  // groundtruth.txt, when there is one
};
// ReadTumSequence on texts already read: `directory` is where the frames' images are and names
// the files in the messages. Throws InvalidInputError as ReadTumSequence.
TumSequence ParseTumSequence(const TumSequenceText& text, const std::string& directory,
                             const TumReadOptions& options = {});

// Loads frame i (colour BGR CV_8UC3, depth CV_32FC1 metres, the intrinsics, the rgb timestamp).
// Throws InvalidInputError when an image is missing, unreadable or of the wrong size or type.
RgbdFrame LoadTumFrame(const TumSequence& sequence, std::size_t i);

// Parses the one data line of a camera.txt (for tests and tools). `where` names it in errors.
void ParseTumCamera(const std::string& text, const std::string& where,
                    PinholeIntrinsics* intrinsics, double* depth_scale);

// Writes a sequence frame by frame. The text files are flushed by close() (or the destructor).
class TumSequenceWriter {
 public:
  // Creates DIR, DIR/rgb, DIR/depth and writes camera.txt. Throws moslam::Error when it cannot.
  TumSequenceWriter(const std::string& directory, const PinholeIntrinsics& intrinsics,
                    double depth_scale = 5000.0);
  ~TumSequenceWriter();
  TumSequenceWriter(const TumSequenceWriter&) = delete;
  TumSequenceWriter& operator=(const TumSequenceWriter&) = delete;

  // Writes frame.rgb/depth at frame.timestamp and the ground-truth pose. Depth beyond the 16-bit
  // range (65535 / depth_scale m) is written as 0 (no return). Throws InvalidInputError when the
  // frame does not match the intrinsics, the timestamp is not increasing, or moslam::Error on a
  // write failure.
  void add(const RgbdFrame& frame, const SE3& world_T_camera);
  void close();
  int size() const { return count_; }

 private:
  std::string dir_;
  PinholeIntrinsics intrinsics_;
  double depth_scale_;
  std::ofstream rgb_, depth_, gt_;
  int count_ = 0;
  double last_timestamp_ = 0.0;
  bool closed_ = false;
};

}  // namespace moslam
