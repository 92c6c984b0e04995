#include "moslam/detection/detector.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

bool FileReadable(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return in.good();
}

std::string ShapeString(const cv::Mat& m) {
  std::ostringstream s;
  s << "[";
  for (int i = 0; i < m.dims; ++i) s << (i ? ", " : "") << m.size[i];
  s << "]";
  return s.str();
}

// A box before non-maximum suppression, in network input pixels.
struct Candidate {
  cv::Rect2d box;
  float score = 0.0f;
  int class_id = 0;
};

// Index and value of the largest of n probabilities starting at p (stride between values).
std::pair<int, float> BestClass(const float* p, int n, std::size_t stride) {
  int best = 0;
  float best_value = p[0];
  for (int c = 1; c < n; ++c) {
    const float v = p[static_cast<std::size_t>(c) * stride];
    if (v > best_value) {
      best_value = v;
      best = c;
    }
  }
  return {best, best_value};
}

void Push(std::vector<Candidate>& out, double cx, double cy, double w, double h, float score,
          int class_id, float threshold) {
  if (!std::isfinite(score) || score < threshold) return;
  if (!std::isfinite(cx) || !std::isfinite(cy) || !std::isfinite(w) || !std::isfinite(h)) return;
  if (w <= 0.0 || h <= 0.0) return;
  out.push_back({cv::Rect2d(cx - 0.5 * w, cy - 0.5 * h, w, h), score, class_id});
}

// The flip test's per-pass score floor, whatever the confidence threshold: a box below it in one
// pass counts as unseen there (so that detections at the threshold are the same whether the
// detector runs at it or lower, as `moslam detect --data` does for the AP).
constexpr float kFlipCandidateThreshold = 0.05f;

// How the image was mapped onto the network input: net = image * scale + pad.
struct InputMapping {
  double scale_x = 1.0, scale_y = 1.0;
  double pad_x = 0.0, pad_y = 0.0;
};

}  // namespace

DetectorOutputFormat ParseDetectorOutputFormat(const std::string& name) {
  if (name == "moslam") return DetectorOutputFormat::kMoslam;
  if (name == "yolov5") return DetectorOutputFormat::kYolov5;
  if (name == "yolov8" || name == "yolo11") return DetectorOutputFormat::kYolov8;
  if (name == "darknet") return DetectorOutputFormat::kDarknet;
  throw InvalidInputError("detector format '" + name +
                          "' is unknown (expected moslam, yolov5, yolov8, yolo11 or darknet)");
}

std::string ToString(DetectorOutputFormat format) {
  switch (format) {
    case DetectorOutputFormat::kMoslam:
      return "moslam";
    case DetectorOutputFormat::kYolov5:
      return "yolov5";
    case DetectorOutputFormat::kYolov8:
      return "yolov8";
    case DetectorOutputFormat::kDarknet:
      return "darknet";
  }
  return "unknown";
}

void DetectorConfig::validate() const {
  if (model_path.empty()) throw InvalidInputError("DetectorConfig.model_path is empty");
  if (format == DetectorOutputFormat::kDarknet && darknet_cfg_path.empty()) {
    throw InvalidInputError("DetectorConfig.darknet_cfg_path is empty (needed by format darknet)");
  }
  if (class_names.empty() && class_names_file.empty()) {
    throw InvalidInputError(
        "DetectorConfig.class_names is empty and class_names_file is not set (give one)");
  }
  if (!class_names.empty() && !class_names_file.empty()) {
    throw InvalidInputError(
        "DetectorConfig.class_names and class_names_file are both set (give only one)");
  }
  for (std::size_t i = 0; i < class_names.size(); ++i) {
    if (class_names[i].empty()) {
      throw InvalidInputError("DetectorConfig.class_names[" + std::to_string(i) + "] is empty");
    }
    const auto earlier = std::find(class_names.begin(), class_names.begin() + i, class_names[i]);
    if (earlier != class_names.begin() + i) {
      throw InvalidInputError(
          "DetectorConfig.class_names[" + std::to_string(i) + "] '" + class_names[i] +
          "' repeats class_names[" + std::to_string(earlier - class_names.begin()) +
          "] (each class needs a name of its own)");
    }
  }
  if (input_width <= 0) throw InvalidInputError("DetectorConfig.input_width must be positive");
  if (input_height <= 0) throw InvalidInputError("DetectorConfig.input_height must be positive");
  if (!(confidence_threshold >= 0.0f && confidence_threshold <= 1.0f)) {
    throw InvalidInputError("DetectorConfig.confidence_threshold must be in [0, 1]");
  }
  if (!(nms_iou_threshold >= 0.0f && nms_iou_threshold <= 1.0f)) {
    throw InvalidInputError("DetectorConfig.nms_iou_threshold must be in [0, 1]");
  }
  if (!(flip_match_iou > 0.0f && flip_match_iou <= 1.0f)) {
    throw InvalidInputError("DetectorConfig.flip_match_iou must be in (0, 1]");
  }
}

std::vector<std::string> ParseClassNames(const std::string& text, const std::string& origin) {
  std::vector<std::string> names;
  std::map<std::string, int> line_of;  // a name -> the line that gave it
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto first = line.find_first_not_of(" \t\r\n");
    if (first == std::string::npos) continue;
    const auto last = line.find_last_not_of(" \t\r\n");
    std::string name = line.substr(first, last - first + 1);
    const auto control = std::find_if(name.begin(), name.end(), [](char c) {
      const auto u = static_cast<unsigned char>(c);
      return u < 0x20 || u == 0x7f;
    });
    if (control != name.end()) {
      throw InvalidInputError("class names '" + origin + "', line " + std::to_string(number) +
                              ": the name holds control character " +
                              std::to_string(static_cast<unsigned char>(*control)) +
                              " (a binary file?)");
    }
    const auto [it, added] = line_of.emplace(name, number);
    if (!added) {
      throw InvalidInputError("class names '" + origin + "', line " + std::to_string(number) +
                              ": '" + name + "' repeats line " + std::to_string(it->second) +
                              " (each class needs a name of its own)");
    }
    names.push_back(std::move(name));
  }
  if (names.empty()) throw InvalidInputError("class names '" + origin + "' hold no name");
  return names;
}

std::vector<std::string> ReadClassNames(const std::string& path) {
  std::string why;
  const std::optional<std::string> text = ReadWholeFile(path, &why);
  if (!text) {
    throw InvalidInputError("cannot read class names file '" + path + "' (" +
                            (why.empty() ? "no such file" : why) + ")");
  }
  return ParseClassNames(*text, path);
}

struct Detector::Impl {
  DetectorConfig config;
  std::vector<std::string> names;
  cv::dnn::Net net;
  std::vector<std::string> output_names;

  int numClasses() const { return static_cast<int>(names.size()); }

  void load() {
    if (!FileReadable(config.model_path)) {
      throw InvalidInputError("detector model file '" + config.model_path +
                              "' does not exist or cannot be read");
    }
    try {
      if (config.format == DetectorOutputFormat::kDarknet) {
        if (!FileReadable(config.darknet_cfg_path)) {
          throw InvalidInputError("Darknet cfg file '" + config.darknet_cfg_path +
                                  "' does not exist or cannot be read");
        }
        net = cv::dnn::readNetFromDarknet(config.darknet_cfg_path, config.model_path);
      } else {
        net = cv::dnn::readNetFromONNX(config.model_path);
      }
    } catch (const cv::Exception& e) {
      throw InvalidInputError("cannot load detector model '" + config.model_path +
                              "' (format " + ToString(config.format) + "): " + e.what());
    }
    if (net.empty()) {
      throw InvalidInputError("detector model '" + config.model_path + "' holds no network");
    }
    net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
    net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
    output_names = net.getUnconnectedOutLayersNames();
  }

  cv::Mat preprocess(const cv::Mat& bgr, InputMapping& mapping) const {
    const int W = config.input_width, H = config.input_height;
    const double w = bgr.cols, h = bgr.rows;
    if (config.resize_mode == ResizeMode::kStretch) {
      mapping.scale_x = W / w;
      mapping.scale_y = H / h;
      return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, cv::Size(W, H), cv::Scalar(), true, false,
                                    CV_32F);
    }
    const double s = std::min(W / w, H / h);
    const int nw = std::clamp(static_cast<int>(std::lround(w * s)), 1, W);
    const int nh = std::clamp(static_cast<int>(std::lround(h * s)), 1, H);
    cv::Mat resized;
    cv::resize(bgr, resized, cv::Size(nw, nh), 0, 0, cv::INTER_LINEAR);
    const int left = (W - nw) / 2, top = (H - nh) / 2;
    cv::Mat padded;
    cv::copyMakeBorder(resized, padded, top, H - nh - top, left, W - nw - left,
                       cv::BORDER_CONSTANT, cv::Scalar(114, 114, 114));
    mapping.scale_x = nw / w;
    mapping.scale_y = nh / h;
    mapping.pad_x = left;
    mapping.pad_y = top;
    return cv::dnn::blobFromImage(padded, 1.0 / 255.0, cv::Size(), cv::Scalar(), true, false,
                                  CV_32F);
  }

  [[noreturn]] void badShape(std::size_t i, const cv::Mat& out, const std::string& expected) const {
    throw InvalidInputError("detector model '" + config.model_path + "': output '" +
                            (i < output_names.size() ? output_names[i] : std::to_string(i)) +
                            "' has shape " + ShapeString(out) + ", but format " +
                            ToString(config.format) + " with " + std::to_string(numClasses()) +
                            " classes expects " + expected);
  }

  void decodeMoslam(std::size_t i, const cv::Mat& out, float threshold,
                    std::vector<Candidate>& cands) const {
    const int C = numClasses();
    if (out.dims != 4 || out.size[0] != 1 || out.size[1] != 5 + C || out.type() != CV_32F) {
      badShape(i, out, "[1, " + std::to_string(5 + C) + ", Gh, Gw] float");
    }
    const int gh = out.size[2], gw = out.size[3];
    const std::size_t plane = static_cast<std::size_t>(gh) * static_cast<std::size_t>(gw);
    const float* data = out.ptr<float>();
    const double W = config.input_width, H = config.input_height;
    for (int gy = 0; gy < gh; ++gy) {
      for (int gx = 0; gx < gw; ++gx) {
        const float* p = data + static_cast<std::size_t>(gy) * static_cast<std::size_t>(gw) +
                         static_cast<std::size_t>(gx);
        const float objectness = p[4 * plane];
        const auto [cls, prob] = BestClass(p + 5 * plane, C, plane);
        const double cx = (gx + static_cast<double>(p[0])) * W / gw;
        const double cy = (gy + static_cast<double>(p[plane])) * H / gh;
        Push(cands, cx, cy, p[2 * plane] * W, p[3 * plane] * H, objectness * prob, cls,
             threshold);
      }
    }
  }

  void decodeRows(std::size_t i, const cv::Mat& out, float threshold,
                  std::vector<Candidate>& cands) const {
    const int C = numClasses();
    int rows = 0;
    if (config.format == DetectorOutputFormat::kYolov5 && out.dims == 3 && out.size[0] == 1 &&
        out.size[2] == 5 + C) {
      rows = out.size[1];
    } else if (out.dims == 2 && out.size[1] == 5 + C) {
      rows = out.size[0];
    } else {
      badShape(i, out,
               config.format == DetectorOutputFormat::kYolov5
                   ? "[1, N, " + std::to_string(5 + C) + "] or [N, " + std::to_string(5 + C) + "]"
                   : "[N, " + std::to_string(5 + C) + "]");
    }
    if (out.type() != CV_32F) badShape(i, out, "a float tensor");
    const float* data = out.ptr<float>();
    const bool darknet = config.format == DetectorOutputFormat::kDarknet;
    const double sx = darknet ? config.input_width : 1.0;
    const double sy = darknet ? config.input_height : 1.0;
    for (int r = 0; r < rows; ++r) {
      const float* p = data + static_cast<std::size_t>(r) * static_cast<std::size_t>(5 + C);
      const auto [cls, prob] = BestClass(p + 5, C, 1);
      const float score = darknet ? prob : p[4] * prob;
      Push(cands, p[0] * sx, p[1] * sy, p[2] * sx, p[3] * sy, score, cls,
           threshold);
    }
  }

  // YOLOv8 / YOLO11: [1, 4 + C, N] (or [4 + C, N]), one column per box, no objectness.
  void decodeColumns(std::size_t i, const cv::Mat& out, float threshold,
                     std::vector<Candidate>& cands) const {
    const int C = numClasses();
    int n = 0;
    if (out.dims == 3 && out.size[0] == 1 && out.size[1] == 4 + C) {
      n = out.size[2];
    } else if (out.dims == 2 && out.size[0] == 4 + C) {
      n = out.size[1];
    } else {
      badShape(i, out,
               "[1, " + std::to_string(4 + C) + ", N] or [" + std::to_string(4 + C) + ", N]");
    }
    if (out.type() != CV_32F) badShape(i, out, "a float tensor");
    const float* data = out.ptr<float>();
    const auto at = [&](int row, int column) {
      return data[static_cast<std::size_t>(row) * static_cast<std::size_t>(n) +
                  static_cast<std::size_t>(column)];
    };
    const std::size_t stride = static_cast<std::size_t>(n);
    for (int c = 0; c < n; ++c) {
      const auto [cls, prob] =
          BestClass(data + 4 * stride + static_cast<std::size_t>(c), C, stride);
      Push(cands, at(0, c), at(1, c), at(2, c), at(3, c), prob, cls, threshold);
    }
  }

  // The network's boxes on `bgr` scoring >= threshold, in image pixels, clipped to the image
  // (empty boxes dropped).
  std::vector<Candidate> candidates(const cv::Mat& bgr, float threshold) {
    InputMapping mapping;
    const cv::Mat blob = preprocess(bgr, mapping);
    std::vector<cv::Mat> outs;
    try {
      net.setInput(blob);
      net.forward(outs, output_names);
    } catch (const cv::Exception& e) {
      throw Error("detector model '" + config.model_path + "' failed to run on a " +
                  std::to_string(config.input_width) + "x" + std::to_string(config.input_height) +
                  " input (is the configured input size right for this model?): " + e.what());
    }
    std::vector<Candidate> cands;
    for (std::size_t i = 0; i < outs.size(); ++i) {
      if (config.format == DetectorOutputFormat::kMoslam) {
        decodeMoslam(i, outs[i], threshold, cands);
      } else if (config.format == DetectorOutputFormat::kYolov8) {
        decodeColumns(i, outs[i], threshold, cands);
      } else {
        decodeRows(i, outs[i], threshold, cands);
      }
    }
    const cv::Rect2d frame(0.0, 0.0, bgr.cols, bgr.rows);
    std::vector<Candidate> in_image;
    for (const Candidate& c : cands) {
      const cv::Rect2d& b = c.box;
      const cv::Rect2d box = cv::Rect2d((b.x - mapping.pad_x) / mapping.scale_x,
                                        (b.y - mapping.pad_y) / mapping.scale_y,
                                        b.width / mapping.scale_x, b.height / mapping.scale_y) &
                             frame;
      if (box.width > 0.0 && box.height > 0.0) in_image.push_back({box, c.score, c.class_id});
    }
    return in_image;
  }

  // NMS per class (or over all boxes: one group), boxes scoring below `threshold` dropped;
  // sorted by decreasing score.
  std::vector<Candidate> suppress(const std::vector<Candidate>& cands, float threshold) const {
    std::map<int, std::vector<std::size_t>> by_class;
    for (std::size_t k = 0; k < cands.size(); ++k) {
      by_class[config.class_agnostic_nms ? 0 : cands[k].class_id].push_back(k);
    }
    std::vector<Candidate> kept;
    for (const auto& [group, members] : by_class) {
      std::vector<cv::Rect2d> class_boxes;
      std::vector<float> class_scores;
      for (std::size_t k : members) {
        class_boxes.push_back(cands[k].box);
        class_scores.push_back(cands[k].score);
      }
      std::vector<int> keep;
      cv::dnn::NMSBoxes(class_boxes, class_scores, threshold, config.nms_iou_threshold, keep);
      for (int j : keep) kept.push_back(cands[members[static_cast<std::size_t>(j)]]);
    }
    std::stable_sort(kept.begin(), kept.end(),
                     [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    return kept;
  }

  // Flip test (DetectorConfig::flip_test): the boxes of the image and of its mirror image, each
  // suppressed on its own, paired one to one (same class, IoU >= flip_match_iou, greedily by
  // score); a pair's score is the mean of its two, its box their score-weighted mean; a box
  // without a partner scores half its own (its partner 0).
  std::vector<Candidate> flipTest(const cv::Mat& bgr) {
    const float low = kFlipCandidateThreshold;
    const std::vector<Candidate> a = suppress(candidates(bgr, low), low);
    cv::Mat mirrored;
    cv::flip(bgr, mirrored, 1);
    std::vector<Candidate> b = suppress(candidates(mirrored, low), low);
    for (Candidate& c : b) c.box.x = bgr.cols - c.box.x - c.box.width;
    std::vector<bool> b_used(b.size(), false);
    std::vector<Candidate> fused;
    for (const Candidate& x : a) {  // a is sorted by decreasing score
      int best = -1;
      double best_iou = config.flip_match_iou;
      for (std::size_t k = 0; k < b.size(); ++k) {
        if (b_used[k] || b[k].class_id != x.class_id) continue;
        const double inter = (x.box & b[k].box).area();
        const double iou = inter / (x.box.area() + b[k].box.area() - inter);
        if (iou >= best_iou) {
          best_iou = iou;
          best = static_cast<int>(k);
        }
      }
      if (best < 0) {
        fused.push_back({x.box, 0.5f * x.score, x.class_id});
        continue;
      }
      const Candidate& y = b[static_cast<std::size_t>(best)];
      b_used[static_cast<std::size_t>(best)] = true;
      const double sum = static_cast<double>(x.score) + y.score;
      const double wx = sum > 0.0 ? x.score / sum : 0.5, wy = 1.0 - wx;
      const cv::Rect2d box(wx * x.box.x + wy * y.box.x, wx * x.box.y + wy * y.box.y,
                           wx * x.box.width + wy * y.box.width,
                           wx * x.box.height + wy * y.box.height);
      fused.push_back({box, 0.5f * (x.score + y.score), x.class_id});
    }
    for (std::size_t k = 0; k < b.size(); ++k) {
      if (!b_used[k]) fused.push_back({b[k].box, 0.5f * b[k].score, b[k].class_id});
    }
    return fused;
  }

  std::vector<Detection> detect(const cv::Mat& image) {
    if (image.empty()) throw InvalidInputError("Detector::detect: the image is empty");
    cv::Mat bgr;
    if (image.type() == CV_8UC3) {
      bgr = image;
    } else if (image.type() == CV_8UC1) {
      cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
    } else {
      throw InvalidInputError("Detector::detect: the image must be CV_8UC3 (BGR) or CV_8UC1");
    }
    const std::vector<Candidate> kept =
        suppress(config.flip_test ? flipTest(bgr) : candidates(bgr, config.confidence_threshold),
                 config.confidence_threshold);
    std::vector<Detection> detections;
    for (const Candidate& c : kept) {
      Detection d;
      d.class_id = c.class_id;
      d.label = names[static_cast<std::size_t>(c.class_id)];
      d.confidence = c.score;
      d.box = cv::Rect2f(static_cast<float>(c.box.x), static_cast<float>(c.box.y),
                         static_cast<float>(c.box.width), static_cast<float>(c.box.height));
      detections.push_back(std::move(d));
    }
    return detections;
  }
};

Detector::Detector(DetectorConfig config) : impl_(std::make_unique<Impl>()) {
  config.validate();
  impl_->config = std::move(config);
  impl_->names = impl_->config.class_names.empty()
                     ? ReadClassNames(impl_->config.class_names_file)
                     : impl_->config.class_names;
  impl_->load();
  // One run on a blank image: a model whose output does not fit the format fails here, at load.
  impl_->detect(cv::Mat(impl_->config.input_height, impl_->config.input_width, CV_8UC3,
                        cv::Scalar(0, 0, 0)));
}

Detector::~Detector() = default;
Detector::Detector(Detector&&) noexcept = default;
Detector& Detector::operator=(Detector&&) noexcept = default;

std::vector<Detection> Detector::detect(const cv::Mat& bgr) { return impl_->detect(bgr); }

const DetectorConfig& Detector::config() const { return impl_->config; }

const std::vector<std::string>& Detector::classNames() const { return impl_->names; }

}  // namespace moslam
