// `moslam detect`: runs the object detector (src/moslam/detection) on one image, or evaluates
// it on a dataset in the YOLO layout (precision / recall at the threshold, AP per class,
// mAP@0.5, time per frame). With --data, the strict metrics (labels only) are always printed;
// when DIR/ignore/ exists (datasets of `moslam render --format yolo`), the metrics with those
// ignore regions (detection/evaluation.h) are printed after them (JSON: "with_ignore").
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "detector_flags.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/detection/detector.h"
#include "moslam/detection/evaluation.h"
#include "moslam/detection/yolo_dataset.h"

namespace moslam::cli {
namespace {

struct DetectArgs {
  std::string model = CommittedDetectorModel();
  std::string format = "moslam";
  std::string cfg;
  std::string classes;  // default: classes.txt beside the model
  std::string input_size = "320x240";
  bool letterbox = false;
  DetectorFlags detector;
  float iou = 0.5f;
  std::string data;
  std::string image;
  std::string annotate;
  bool json = false;
};

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

cv::Mat ReadImage(const std::string& path) {
  cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
  if (img.empty()) throw InvalidInputError("cannot read image '" + path + "'");
  return img;
}

DetectorConfig MakeConfig(const DetectArgs& a, float threshold) {
  DetectorConfig c;
  c.format = ParseDetectorOutputFormat(a.format);
  c.model_path = a.model;
  c.darknet_cfg_path = a.cfg;
  c.class_names_file = a.classes.empty()
                           ? (std::filesystem::path(a.model).parent_path() / "classes.txt").string()
                           : a.classes;
  const auto x = a.input_size.find('x');
  try {
    if (x == std::string::npos) throw std::invalid_argument("no x");
    std::size_t used = 0;
    c.input_width = std::stoi(a.input_size.substr(0, x), &used);
    if (used != x) throw std::invalid_argument("width");
    c.input_height = std::stoi(a.input_size.substr(x + 1), &used);
    if (used != a.input_size.size() - x - 1) throw std::invalid_argument("height");
  } catch (const std::logic_error&) {
    throw InvalidInputError("--input-size '" + a.input_size + "' is not WIDTHxHEIGHT");
  }
  c.resize_mode = a.letterbox ? ResizeMode::kLetterbox : ResizeMode::kStretch;
  a.detector.applyTo(&c);
  c.confidence_threshold = threshold;
  return c;
}

nlohmann::json ToJson(const Detection& d) {
  return {{"class_id", d.class_id},
          {"label", d.label},
          {"confidence", d.confidence},
          {"box", {d.box.x, d.box.y, d.box.width, d.box.height}}};
}

void Annotate(cv::Mat& img, const std::vector<Detection>& dets) {
  for (const Detection& d : dets) {
    cv::rectangle(img, cv::Rect(d.box), cv::Scalar(0, 255, 0), 1);
    cv::putText(img, fmt::format("{} {:.2f}", d.label, d.confidence),
                cv::Point(static_cast<int>(d.box.x), std::max(8, static_cast<int>(d.box.y) - 2)),
                cv::FONT_HERSHEY_SIMPLEX, 0.3, cv::Scalar(0, 255, 0), 1);
  }
}

// Writes an annotated image, its format chosen by the path's extension. Throws InvalidInputError
// when it cannot (no folder, no right, an extension OpenCV has no writer for).
void WriteAnnotatedImage(const std::string& path, const cv::Mat& img) {
  bool written = false;
  std::string why;
  try {
    written = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    why = ": OpenCV has no writer for its extension (.png, .jpg, .bmp, ...): " + e.err;
  }
  if (!written) throw InvalidInputError("cannot write annotated image '" + path + "'" + why);
}

int RunOnImage(const DetectArgs& a) {
  Detector detector(MakeConfig(a, a.detector.threshold));
  cv::Mat img = ReadImage(a.image);
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Detection> dets = detector.detect(img);
  const double ms = MsSince(t0);
  if (!a.annotate.empty()) {
    Annotate(img, dets);
    WriteAnnotatedImage(a.annotate, img);
  }
  if (a.json) {
    nlohmann::json j = {{"image", a.image}, {"ms", ms}, {"detections", nlohmann::json::array()}};
    for (const Detection& d : dets) j["detections"].push_back(ToJson(d));
    fmt::print("{}\n", j.dump());
    return 0;
  }
  fmt::print("{}: {} detection(s) in {:.1f} ms\n", a.image, dets.size(), ms);
  for (const Detection& d : dets) {
    fmt::print("  {:<14} {:.3f}  x {:.1f} y {:.1f} w {:.1f} h {:.1f}\n", d.label, d.confidence,
               d.box.x, d.box.y, d.box.width, d.box.height);
  }
  return 0;
}

nlohmann::json MetricsJson(const DetectionMetrics& m) {
  nlohmann::json j = {{"frames", m.frames},
                      {"ground_truths", m.ground_truths},
                      {"true_positives", m.true_positives},
                      {"false_positives", m.false_positives},
                      {"ignored_detections", m.ignored_detections},
                      {"ignore_boxes", m.ignore_boxes},
                      {"precision", m.precision},
                      {"recall", m.recall},
                      {"map50", m.mean_average_precision},
                      {"per_class", nlohmann::json::array()}};
  for (const ClassMetrics& c : m.per_class) {
    j["per_class"].push_back({{"label", c.label},
                              {"ground_truths", c.ground_truths},
                              {"true_positives", c.true_positives},
                              {"false_positives", c.false_positives},
                              {"ignored_detections", c.ignored_detections},
                              {"precision", c.precision},
                              {"recall", c.recall},
                              {"ap50", c.average_precision}});
  }
  return j;
}

void PrintMetrics(const DetectionMetrics& m, bool ignored_column) {
  fmt::print("{:<14} {:>6} {:>6} {:>6} {:>9} {:>7} {:>7}{}\n", "class", "gt", "tp", "fp",
             "precision", "recall", "AP@0.5", ignored_column ? "  ignored" : "");
  auto row = [&](const std::string& label, int gt, int tp, int fp, double p, double r, double ap,
                 int ign, const char* tail) {
    fmt::print("{:<14} {:>6} {:>6} {:>6} {:>9.3f} {:>7.3f} {:>7.3f}{}{}\n", label, gt, tp, fp, p,
               r, ap, ignored_column ? fmt::format(" {:>8}", ign) : "", tail);
  };
  for (const ClassMetrics& c : m.per_class) {
    if (c.ground_truths == 0 && c.true_positives + c.false_positives == 0) continue;
    row(c.label, c.ground_truths, c.true_positives, c.false_positives, c.precision, c.recall,
        c.average_precision, c.ignored_detections, "");
  }
  row("all", m.ground_truths, m.true_positives, m.false_positives, m.precision, m.recall,
      m.mean_average_precision, m.ignored_detections, " (mAP)");
}

std::vector<GroundTruthBox> InPixels(const std::vector<YoloLabel>& labels, const cv::Mat& img) {
  std::vector<GroundTruthBox> boxes;
  for (const YoloLabel& l : labels) boxes.push_back(l.toPixels(img.cols, img.rows));
  return boxes;
}

// --annotate: the image with the detections at or above the threshold, under its own name.
void WriteAnnotated(const DetectArgs& a, const std::string& image_path, cv::Mat& img,
                    std::vector<Detection> dets) {
  dets.erase(
      std::remove_if(dets.begin(), dets.end(),
                     [&](const Detection& d) { return d.confidence < a.detector.threshold; }),
      dets.end());
  Annotate(img, dets);
  const auto out = std::filesystem::path(a.annotate) / std::filesystem::path(image_path).filename();
  WriteAnnotatedImage(out.string(), img);
}

// The text report: strict metrics, those with the ignore regions (when the dataset has them) and
// the detector's time per frame.
void PrintDatasetReport(const DetectArgs& a, const DetectionMetrics* with_ignore,
                        const DetectionMetrics& m, double mean_ms, double median_ms) {
  fmt::print("{}: {} frames, threshold {:.2f}, IoU {:.2f}\n", a.data, m.frames,
             a.detector.threshold, a.iou);
  fmt::print("strict (every detection that matches no label is a false positive):\n");
  PrintMetrics(m, false);
  if (with_ignore != nullptr) {
    fmt::print(
        "with ignore regions ({} boxes of visible, unlabelled objects in {}/ignore; a "
        "detection on one is dropped, VOC 'difficult' style):\n",
        with_ignore->ignore_boxes, a.data);
    PrintMetrics(*with_ignore, true);
  } else {
    fmt::print("(no {}/ignore folder: strict metrics only)\n", a.data);
  }
  fmt::print(
      "time per frame: mean {:.2f} ms, median {:.2f} ms (detect only, 1 thread unless "
      "OpenCV uses more)\n",
      mean_ms, median_ms);
}

int RunOnDataset(const DetectArgs& a) {
  const YoloDataset data = ReadYoloDataset(a.data);
  // Detections down to 0.01 enter the AP; precision and recall count those >= --threshold
  // (NMS keeps the same boxes above the threshold either way: only a higher-scoring box
  // suppresses one).
  Detector detector(MakeConfig(a, std::min(a.detector.threshold, 0.01f)));
  if (detector.classNames() != data.class_names) {
    throw InvalidInputError("the dataset classes (" + a.data +
                            "/classes.txt) differ from the model's class names");
  }
  EvaluationOptions eo;
  eo.iou_threshold = a.iou;
  eo.confidence_threshold = a.detector.threshold;
  DetectionEvaluator evaluator(data.class_names, eo);    // strict: labels only
  DetectionEvaluator with_ignore(data.class_names, eo);  // plus DIR/ignore/ regions
  if (!a.annotate.empty()) CreateFolder(a.annotate, "detect --annotate");
  std::vector<double> times;
  for (const YoloSample& s : data.samples) {
    cv::Mat img = ReadImage(s.image_path);
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<Detection> dets = detector.detect(img);
    times.push_back(MsSince(t0));
    const std::vector<GroundTruthBox> gt = InPixels(s.labels, img);
    evaluator.addFrame(dets, gt);
    with_ignore.addFrame(dets, gt, InPixels(s.ignore, img));
    if (!a.annotate.empty()) WriteAnnotated(a, s.image_path, img, std::move(dets));
  }
  const DetectionMetrics m = evaluator.compute();
  const DetectionMetrics mi = with_ignore.compute();
  std::vector<double> sorted = times;
  std::sort(sorted.begin(), sorted.end());
  double mean = 0.0;
  for (double t : times) mean += t;
  mean /= static_cast<double>(times.size());
  const double median = sorted[sorted.size() / 2];  // the upper of two middles
  if (a.json) {
    nlohmann::json j = MetricsJson(m);
    j["data"] = a.data;
    j["model"] = a.model;
    j["threshold"] = a.detector.threshold;
    j["iou"] = a.iou;
    j["ms_per_frame_mean"] = mean;
    j["ms_per_frame_median"] = median;
    if (data.has_ignore) j["with_ignore"] = MetricsJson(mi);
    fmt::print("{}\n", j.dump());
    return 0;
  }
  PrintDatasetReport(a, data.has_ignore ? &mi : nullptr, m, mean, median);
  return 0;
}

}  // namespace

Runner RegisterDetect(CLI::App& app) {
  auto args = std::make_shared<DetectArgs>();
  CLI::App* sub = app.add_subcommand("detect", kDetectDescription);
  sub->add_option("--model", args->model, "ONNX model (or Darknet .weights with --format darknet)")
      ->capture_default_str();
  sub->add_option("--format", args->format, "network output format")
      ->check(CLI::IsMember({"moslam", "yolov5", "yolov8", "yolo11", "darknet"}))
      ->capture_default_str();
  sub->add_option("--cfg", args->cfg, "Darknet .cfg (with --format darknet)");
  sub->add_option("--classes", args->classes,
                  "class names, one per line (default: classes.txt beside the model)");
  sub->add_option("--input-size", args->input_size, "network input WIDTHxHEIGHT")
      ->capture_default_str();
  sub->add_flag("--letterbox", args->letterbox,
                "keep the aspect ratio and pad (default: stretch, as moslam's model is trained)");
  AddDetectorFlags(sub, &args->detector);
  sub->add_option("--iou", args->iou, "IoU for a detection to match a ground-truth box")
      ->check(InRange(0.0, 1.0))
      ->capture_default_str();
  auto* data = sub->add_option("--data", args->data,
                               "evaluate on a dataset: DIR/classes.txt, images/, labels/ "
                               "(and ignore/, then both strict and with-ignore metrics)");
  auto* image = sub->add_option("--image", args->image, "detect on one image");
  data->excludes(image);
  sub->add_option("--annotate", args->annotate,
                  "write annotated image(s): a file with --image, a folder with --data");
  sub->add_flag("--json", args->json, "print one JSON object");
  return [args] {
    if (args->data.empty() && args->image.empty()) {
      throw InvalidInputError("moslam detect: give --data DIR or --image FILE");
    }
    return args->data.empty() ? RunOnImage(*args) : RunOnDataset(*args);
  };
}

}  // namespace moslam::cli
