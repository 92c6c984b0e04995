// A single-stage (YOLO-style) object detector run on the CPU with OpenCV DNN.
//
// Conventions:
//   Input images are CV_8UC3 BGR (cv::imread order, render/rgbd.h RgbdFrame::rgb). They are
//   resized to the network input size (DetectorConfig::input_width x input_height), converted
//   to RGB and scaled to [0, 1] (NCHW float blob), the layout of the training script
//   training/train_detector.py and of common YOLO exports.
//   Boxes are cv::Rect2f in pixels of the INPUT image (x, y = top-left corner, width, height),
//   clipped to the image.
//   Score of a box = objectness x class probability of its best class (formats without
//   objectness: the class probability); boxes with a score below confidence_threshold are
//   dropped (0.3, the paper's class probability threshold; with flip_test, below, the mean score
//   of the image's and its mirror image's pass), then
//   non-maximum suppression runs over all boxes whatever their class (class_agnostic_nms, the
//   default; YOLOv5's --agnostic-nms), or per class (cv::dnn::NMSBoxes either way). A box keeps
//   only its best class.
//
// Supported network outputs (DetectorConfig::format):
//   kMoslam  the project's grid head (training/train_detector.py): one or more outputs of shape
//            [1, 5 + C, Gh, Gw], one per scale, already activated; channel 0..1 = box centre
//            offset from its cell's top-left corner in cell units (x right, y down; the
//            project's model emits [-0.5, 1.5], YOLOv5-style), 2..3 = box width and height as
//            fractions of the network input width and height, 4 = objectness probability,
//            5..5+C-1 = class probabilities. Cell (gy, gx) covers input pixels
//            [gx W / Gw, (gx + 1) W / Gw) x [gy H / Gh, (gy + 1) H / Gh).
//   kYolov5  the common YOLOv5/YOLOv8-style ONNX export with objectness: output [1, N, 5 + C] (or
//            [N, 5 + C]); per row cx, cy, w, h in network input pixels, objectness, C class
//            probabilities (already sigmoid-activated, as `export.py` writes them).
//   kYolov8  the YOLOv8 / YOLO11 ONNX export (what `yolo export format=onnx` writes today): output
//            [1, 4 + C, N] (or [4 + C, N]), one COLUMN per box: cx, cy, w, h in network input
//            pixels, then C class probabilities; no objectness column, so the score is the best
//            class probability.
//   kDarknet readNetFromDarknet(cfg, weights): the [N, 5 + C] rows of OpenCV's Region layers; cx,
//            cy, w, h as fractions of the network input; OpenCV already multiplies the class
//            scores by the objectness, so the score is the class column itself.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace moslam {

struct Detection {
  int class_id = -1;
  std::string label;
  float confidence = 0.0f;  // objectness x class probability, in [0, 1]
  cv::Rect2f box;           // pixels of the input image
};

enum class DetectorOutputFormat { kMoslam, kYolov5, kYolov8, kDarknet };

// "moslam", "yolov5", "yolov8" (or "yolo11"), "darknet" -> the format; throws InvalidInputError for anything else.
DetectorOutputFormat ParseDetectorOutputFormat(const std::string& name);
std::string ToString(DetectorOutputFormat format);

// How an image is brought to the network input size.
enum class ResizeMode {
  kStretch,    // plain resize to input_width x input_height (aspect ratio not kept); the mode
               // the project's model is trained with
  kLetterbox,  // uniform scale to fit, centred, padded with grey (114), as YOLOv5 does
};

struct DetectorConfig {
  DetectorOutputFormat format = DetectorOutputFormat::kMoslam;
  std::string model_path;  // .onnx file (kMoslam, kYolov5) or Darknet .weights (kDarknet)
  std::string darknet_cfg_path;  // Darknet .cfg (kDarknet only)
  // Class names in class-id order: either listed here or read from class_names_file (one name
  // per line, blank lines ignored, e.g. classes.txt or coco.names). Listing both is an error.
  std::vector<std::string> class_names;
  std::string class_names_file;
  int input_width = 320;   // network input, pixels
  int input_height = 240;  // network input, pixels
  ResizeMode resize_mode = ResizeMode::kStretch;
  float confidence_threshold = 0.3f;  // on objectness x class probability (paper: 0.3)
  float nms_iou_threshold = 0.4f;  // of two boxes overlapping more than this, the lower goes
  // NMS over all boxes (the default): of two boxes overlapping more than nms_iou_threshold only
  // the higher score survives even when their classes differ (one object seen as two classes by
  // neighbouring cells gives one detection, not a true and a false one); false: per class.
  // Chosen with the IoU on the project's model-selection frames as the setting of highest recall
  // with strict precision >= 0.9 (per class reaches 0.898 at best); on the held-out frames
  // precision / recall / mAP 0.899 / 0.900 / 0.873 (per class, IoU 0.45) -> 0.906 / 0.874 /
  // 0.842: a table under a chair's overlapping box is lost (table recall 0.93 -> 0.71), and the
  // perception front-end's accepted views on the held-out sequences are the same
  // (models/detector/README.md).
  bool class_agnostic_nms = true;
  // Flip test (test-time augmentation, an ensemble of the image and its mirror image): the
  // network runs on both, the boxes of each pass suppressed on their own (scores >= 0.05 whatever
  // the confidence threshold), paired one to one across the passes (same class, IoU >=
  // flip_match_iou); a pair scores the mean of its two scores (box: their score-weighted mean), a
  // box seen in one pass half its score; then confidence_threshold and NMS as above. A box must
  // score on average >= the threshold over both passes. Twice the network's time. On by default:
  // on the project's model-selection frames precision / recall 0.870 / 0.923 -> 0.891 / 0.932
  // (models/detector/README.md).
  bool flip_test = true;
  float flip_match_iou = 0.5f;

  // Throws InvalidInputError naming the first bad field: empty model_path, missing cfg for
  // kDarknet, no class names or both sources, non-positive input size, thresholds outside
  // [0, 1].
  void validate() const;
};

// Class names from the text of a class names file (`origin` names it in errors): one per line,
// surrounding whitespace trimmed, blank lines skipped. Throws InvalidInputError naming the origin
// (and the line) when it holds no name, a name holds a control character, or a name repeats an
// earlier one (each class one name: a detection's label must say which class it is).
std::vector<std::string> ParseClassNames(const std::string& text, const std::string& origin);
// ParseClassNames of the file's text; InvalidInputError naming the file if it cannot be read.
std::vector<std::string> ReadClassNames(const std::string& path);

class Detector {
 public:
  // Validates the config, reads the class names, loads the network (CPU backend) and runs it
  // once on a blank image to check that its output fits the format and class count. Throws
  // InvalidInputError for a bad config, a missing/unreadable model file or an output shape
  // that does not fit; Error if OpenCV fails otherwise.
  explicit Detector(DetectorConfig config);
  ~Detector();
  Detector(Detector&&) noexcept;
  Detector& operator=(Detector&&) noexcept;
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  // Detections on one BGR image (CV_8UC3, or CV_8UC1 which is expanded to three channels),
  // sorted by decreasing confidence. Throws InvalidInputError for an empty image or another
  // type.
  std::vector<Detection> detect(const cv::Mat& bgr);

  const DetectorConfig& config() const;
  const std::vector<std::string>& classNames() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace moslam
