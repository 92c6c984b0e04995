#include "moslam/render/tum_sequence.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <tuple>

#include "moslam/common/errors.h"
#include "moslam/common/number_text.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

struct Line {
  int number;
  std::vector<std::string> tokens;
};

// Data lines of a text (comments and blank lines skipped), split on whitespace.
std::vector<Line> DataLines(const std::string& text) {
  std::istringstream f(text);
  std::vector<Line> out;
  std::string row;
  int n = 0;
  while (std::getline(f, row)) {
    ++n;
    if (!row.empty() && row.back() == '\r') row.pop_back();
    const auto first = row.find_first_not_of(" \t");
    if (first == std::string::npos || row[first] == '#') continue;
    std::istringstream s(row);
    Line l{n, {}};
    std::string tok;
    while (s >> tok) l.tokens.push_back(tok);
    out.push_back(std::move(l));
  }
  return out;
}

[[noreturn]] void Fail(const std::string& path, int line, const std::string& what) {
  throw InvalidInputError(fmt::format("{}:{}: {}", path, line, what));
}

double Number(const std::string& tok, const std::string& path, int line, const char* field) {
  double v = 0.0;
  if (ParseNumberToken(tok, v) != NumberStatus::kOk) {
    Fail(path, line, fmt::format("{} '{}' is not a finite number", field, tok));
  }
  return v;
}

struct Stamped {
  double t;
  std::string file;
};

std::vector<Stamped> ParseFileList(const std::string& text, const std::string& path) {
  std::vector<Stamped> out;
  for (const Line& l : DataLines(text)) {
    if (l.tokens.size() != 2) {
      Fail(path, l.number,
           fmt::format("expected 'timestamp filename', got {} fields", l.tokens.size()));
    }
    out.push_back({Number(l.tokens[0], path, l.number, "timestamp"), l.tokens[1]});
  }
  return out;
}

struct StampedPose {
  double t;
  SE3 pose;
};

std::vector<StampedPose> ParseGroundTruth(const std::string& text, const std::string& path) {
  std::vector<StampedPose> out;
  static const char* kFields[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  for (const Line& l : DataLines(text)) {
    if (l.tokens.size() != 8) {
      Fail(path, l.number,
           fmt::format("expected 'timestamp tx ty tz qx qy qz qw', got {} fields",
                       l.tokens.size()));
    }
    double v[8];
    for (std::size_t i = 0; i < 8; ++i) v[i] = Number(l.tokens[i], path, l.number, kFields[i]);
    if (v[4] == 0.0 && v[5] == 0.0 && v[6] == 0.0 && v[7] == 0.0) {
      Fail(path, l.number, "the quaternion is zero");
    }
    // Finite and not zero: FromQuaternion normalises it whatever its norm.
    out.push_back({v[0], SE3(SO3::FromQuaternion(v[7], v[4], v[5], v[6]),
                             Vector3(v[1], v[2], v[3]))});
  }
  std::sort(out.begin(), out.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.t < b.t; });
  return out;
}

// associate.py: all pairs within the tolerance, by increasing time difference, each item once.
std::vector<std::pair<std::size_t, std::size_t>> Associate(const std::vector<double>& a,
                                                           const std::vector<double>& b,
                                                           double tolerance) {
  std::vector<std::tuple<double, std::size_t, std::size_t>> candidates;
  std::vector<std::size_t> order(b.size());
  for (std::size_t j = 0; j < b.size(); ++j) order[j] = j;
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return b[x] < b[y]; });
  std::vector<double> sorted_b(b.size());
  for (std::size_t j = 0; j < b.size(); ++j) sorted_b[j] = b[order[j]];
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto it = std::lower_bound(sorted_b.begin(), sorted_b.end(), a[i] - tolerance);
    for (; it != sorted_b.end() && *it <= a[i] + tolerance; ++it) {
      const auto j = order[static_cast<std::size_t>(it - sorted_b.begin())];
      // The window's ends are rounded sums: the difference itself decides (0.1 - 0.08 is
      // 0.020000000000000004 while 0.1 - 0.02 rounds to 0.08).
      const double difference = std::abs(a[i] - b[j]);
      if (difference <= tolerance) candidates.emplace_back(difference, i, j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> used_a(a.size(), false), used_b(b.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (const auto& [d, i, j] : candidates) {
    if (used_a[i] || used_b[j]) continue;
    used_a[i] = used_b[j] = true;
    out.emplace_back(i, j);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string Stamp(double t) { return fmt::format("{:.6f}", t); }

}  // namespace

void TumReadOptions::validate() const {
  if (!(max_time_difference >= 0.0) || !std::isfinite(max_time_difference)) {
    throw InvalidInputError("TumReadOptions: max_time_difference must be >= 0 and finite");
  }
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale)) {
    throw InvalidInputError("TumReadOptions: depth_scale must be positive and finite");
  }
  if (intrinsics) intrinsics->validate();
}

void ParseTumCamera(const std::string& text, const std::string& where,
                    PinholeIntrinsics* intrinsics, double* depth_scale) {
  std::istringstream in(text);
  std::string row;
  int n = 0;
  bool found = false;
  while (std::getline(in, row)) {
    ++n;
    const auto first = row.find_first_not_of(" \t\r");
    if (first == std::string::npos || row[first] == '#') continue;
    if (found) Fail(where, n, "more than one data line");
    found = true;
    std::istringstream s(row);
    std::vector<std::string> tok;
    std::string t;
    while (s >> t) tok.push_back(t);
    if (tok.size() != 7) {
      Fail(where, n,
           fmt::format("expected 'fx fy cx cy width height depth_scale', got {} fields",
                       tok.size()));
    }
    static const char* kFields[] = {"fx", "fy", "cx", "cy", "width", "height", "depth_scale"};
    double v[7];
    for (std::size_t i = 0; i < 7; ++i) v[i] = Number(tok[i], where, n, kFields[i]);
    for (const std::size_t i : {std::size_t{4}, std::size_t{5}}) {
      if (v[i] != std::floor(v[i]) || v[i] < 1.0 || v[i] > 16384.0) {
        Fail(where, n, fmt::format("{} must be an integer in [1, 16384]", kFields[i]));
      }
    }
    PinholeIntrinsics k;
    k.fx = v[0];
    k.fy = v[1];
    k.cx = v[2];
    k.cy = v[3];
    k.width = static_cast<int>(v[4]);
    k.height = static_cast<int>(v[5]);
    try {
      k.validate();
    } catch (const InvalidInputError& e) {
      Fail(where, n, e.what());
    }
    if (!(v[6] > 0.0)) Fail(where, n, "depth_scale must be positive");
    *intrinsics = k;
    *depth_scale = v[6];
  }
  if (!found) Fail(where, n, "no data line 'fx fy cx cy width height depth_scale'");
}

TumSequence ReadTumSequence(const std::string& directory, const TumReadOptions& options) {
  options.validate();
  const fs::path dir(directory);
  if (!fs::is_directory(dir)) throw InvalidInputError(directory + ": not a directory");
  TumSequenceText text;
  auto read = [&dir](const char* name) { return ReadWholeFileOrThrow((dir / name).string()); };
  if (fs::exists(dir / "camera.txt")) text.camera = read("camera.txt");
  text.rgb = read("rgb.txt");
  text.depth = read("depth.txt");
  if (fs::exists(dir / "groundtruth.txt")) text.groundtruth = read("groundtruth.txt");
  return ParseTumSequence(text, directory, options);
}

TumSequence ParseTumSequence(const TumSequenceText& text, const std::string& directory,
                             const TumReadOptions& options) {
  options.validate();
  TumSequence seq;
  seq.directory = directory;
  const fs::path dir(directory);
  const fs::path camera = dir / "camera.txt";
  if (text.camera) {
    ParseTumCamera(*text.camera, camera.string(), &seq.intrinsics, &seq.depth_scale);
  } else if (options.intrinsics) {
    seq.intrinsics = *options.intrinsics;
    seq.depth_scale = options.depth_scale;
  } else {
    throw InvalidInputError(camera.string() +
                            ": missing, and no intrinsics were given (TumReadOptions::intrinsics)");
  }
  const auto rgb = ParseFileList(text.rgb, (dir / "rgb.txt").string());
  const auto depth = ParseFileList(text.depth, (dir / "depth.txt").string());
  std::vector<double> ta, tb;
  for (const auto& s : rgb) ta.push_back(s.t);
  for (const auto& s : depth) tb.push_back(s.t);
  const auto pairs = Associate(ta, tb, options.max_time_difference);
  std::vector<StampedPose> gt;
  if (text.groundtruth) {
    gt = ParseGroundTruth(*text.groundtruth, (dir / "groundtruth.txt").string());
  }
  std::vector<double> tg;
  for (const auto& g : gt) tg.push_back(g.t);
  for (const auto& [i, j] : pairs) {
    TumFrame f;
    f.rgb_timestamp = rgb[i].t;
    f.rgb_file = rgb[i].file;
    f.depth_timestamp = depth[j].t;
    f.depth_file = depth[j].file;
    seq.frames.push_back(f);
  }
  std::sort(seq.frames.begin(), seq.frames.end(),
            [](const TumFrame& a, const TumFrame& b) { return a.rgb_timestamp < b.rgb_timestamp; });
  // Ground truth: the nearest pose in time (poses may be shared by frames: they are a trajectory).
  for (auto& f : seq.frames) {
    auto it = std::lower_bound(tg.begin(), tg.end(), f.rgb_timestamp);
    std::size_t best = tg.size();
    double best_d = options.max_time_difference;
    for (auto c : {it, it == tg.begin() ? it : it - 1}) {
      if (c == tg.end()) continue;
      const double d = std::abs(*c - f.rgb_timestamp);
      if (d <= best_d) {
        best_d = d;
        best = static_cast<std::size_t>(c - tg.begin());
      }
    }
    if (best < tg.size()) f.world_T_camera = gt[best].pose;
  }
  return seq;
}

RgbdFrame LoadTumFrame(const TumSequence& seq, std::size_t i) {
  if (i >= seq.frames.size()) {
    throw InvalidInputError(fmt::format("{}: frame {} does not exist ({} frames)", seq.directory,
                                        i, seq.frames.size()));
  }
  const TumFrame& f = seq.frames[i];
  const std::string rgb_path = (fs::path(seq.directory) / f.rgb_file).string();
  const std::string depth_path = (fs::path(seq.directory) / f.depth_file).string();
  RgbdFrame out;
  out.intrinsics = seq.intrinsics;
  out.timestamp = f.rgb_timestamp;
  out.rgb = cv::imread(rgb_path, cv::IMREAD_COLOR);
  if (out.rgb.empty()) throw InvalidInputError(rgb_path + ": cannot read the colour image");
  const cv::Mat raw = cv::imread(depth_path, cv::IMREAD_ANYDEPTH);
  if (raw.empty()) throw InvalidInputError(depth_path + ": cannot read the depth image");
  if (raw.type() != CV_16UC1) {
    throw InvalidInputError(depth_path + ": depth must be a 16-bit single-channel PNG");
  }
  const cv::Size size(seq.intrinsics.width, seq.intrinsics.height);
  if (out.rgb.size() != size || raw.size() != size) {
    throw InvalidInputError(fmt::format("{}: images are {}x{} / {}x{}, the intrinsics say {}x{}",
                                        seq.directory, out.rgb.cols, out.rgb.rows, raw.cols,
                                        raw.rows, size.width, size.height));
  }
  raw.convertTo(out.depth, CV_32FC1, 1.0 / seq.depth_scale);
  return out;
}

TumSequenceWriter::TumSequenceWriter(const std::string& directory,
                                     const PinholeIntrinsics& intrinsics, double depth_scale)
    : dir_(directory), intrinsics_(intrinsics), depth_scale_(depth_scale) {
  intrinsics_.validate();
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale)) {
    throw InvalidInputError("TumSequenceWriter: depth_scale must be positive and finite");
  }
  CreateFolder(fs::path(dir_) / "rgb", "TumSequenceWriter");
  CreateFolder(fs::path(dir_) / "depth", "TumSequenceWriter");
  std::ofstream cam(fs::path(dir_) / "camera.txt");
  cam << "# pinhole intrinsics (pixels) and depth PNG units per metre\n"
      << "# fx fy cx cy width height depth_scale\n"
      << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {} {} {:.17g}\n", intrinsics_.fx,
                     intrinsics_.fy, intrinsics_.cx, intrinsics_.cy, intrinsics_.width,
                     intrinsics_.height, depth_scale_);
  if (!cam) throw Error("cannot write '" + dir_ + "/camera.txt'");
  rgb_.open(fs::path(dir_) / "rgb.txt");
  depth_.open(fs::path(dir_) / "depth.txt");
  gt_.open(fs::path(dir_) / "groundtruth.txt");
  if (!rgb_ || !depth_ || !gt_) throw Error("cannot write the lists in '" + dir_ + "'");
  const std::string name = fs::path(dir_).filename().string();
  rgb_ << "# color images\n# file: '" << name << "'\n# timestamp filename\n";
  depth_ << "# depth maps\n# file: '" << name << "'\n# timestamp filename\n";
  gt_ << "# ground truth trajectory\n# file: '" << name << "'\n# timestamp tx ty tz qx qy qz qw\n";
}

TumSequenceWriter::~TumSequenceWriter() {
  try {
    close();
  } catch (...) {  // destructors must not throw; close() explicitly to see errors
  }
}

void TumSequenceWriter::add(const RgbdFrame& frame, const SE3& world_T_camera) {
  if (closed_) throw Error("TumSequenceWriter: add() after close()");
  const cv::Size size(intrinsics_.width, intrinsics_.height);
  if (frame.rgb.type() != CV_8UC3 || frame.rgb.size() != size) {
    throw InvalidInputError("TumSequenceWriter: rgb must be CV_8UC3 of the intrinsics' size");
  }
  if (frame.depth.type() != CV_32FC1 || frame.depth.size() != size) {
    throw InvalidInputError("TumSequenceWriter: depth must be CV_32FC1 of the intrinsics' size");
  }
  if (!std::isfinite(frame.timestamp) || (count_ > 0 && !(frame.timestamp > last_timestamp_))) {
    throw InvalidInputError("TumSequenceWriter: timestamps must be finite and increasing");
  }
  const std::string t = Stamp(frame.timestamp);
  const std::string rgb_file = "rgb/" + t + ".png", depth_file = "depth/" + t + ".png";
  cv::Mat d16(size, CV_16UC1);
  for (int v = 0; v < size.height; ++v) {
    const auto* d = frame.depth.ptr<float>(v);
    auto* o = d16.ptr<std::uint16_t>(v);
    for (int u = 0; u < size.width; ++u) {
      const double units = std::round(static_cast<double>(d[u]) * depth_scale_);
      o[u] = (units > 0.0 && units <= 65535.0) ? static_cast<std::uint16_t>(units) : 0;
    }
  }
  const std::string rgb_path = (fs::path(dir_) / rgb_file).string();
  const std::string depth_path = (fs::path(dir_) / depth_file).string();
  if (!cv::imwrite(rgb_path, frame.rgb)) throw Error("cannot write '" + rgb_path + "'");
  if (!cv::imwrite(depth_path, d16)) throw Error("cannot write '" + depth_path + "'");
  rgb_ << t << " " << rgb_file << "\n";
  depth_ << t << " " << depth_file << "\n";
  const Eigen::Vector4d q = world_T_camera.rotation().quaternionWxyz();
  const Vector3& p = world_T_camera.translation();
  gt_ << fmt::format("{} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}\n", t, p.x(), p.y(),
                     p.z(), q[1], q[2], q[3], q[0]);
  last_timestamp_ = frame.timestamp;
  ++count_;
}

void TumSequenceWriter::close() {
  if (closed_) return;
  closed_ = true;
  rgb_.close();
  depth_.close();
  gt_.close();
  if (rgb_.fail() || depth_.fail() || gt_.fail()) {
    throw Error("cannot finish the lists in '" + dir_ + "'");
  }
}

}  // namespace moslam
