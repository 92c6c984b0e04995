// `moslam perceive <sequence dir>`: the perception front-end on an RGB-D sequence in the TUM RGB-D
// layout (render/tum_sequence.h): detections and object poses per frame, as JSON.
//
//   moslam perceive DIR [--model M.onnx --classes classes.txt] [--threshold S] [--nms IOU]
//                   [--agnostic-nms|--per-class-nms] [--no-flip-test] [--templates DIR]
//                   [--every K]
//                   [--max-frames N] [--out detections.json] [--annotate DIR] [--world world.json]
//                   [--template-cache DIR|none] [--consensus prerejective|sac-ia] [--threads N]
//                   [--template-views N] [--no-depth-smoothing]
//                   [--json]
//
// Every K-th frame runs detect -> segment -> register (perception/object_perception.h). --out
// writes the per-frame results; --annotate writes each frame's colour image with its boxes
// (green: accepted, red: rejected by the 12-inlier gate, orange: other rejections) and labels.
// --world (a sim/world.h JSON, e.g. the world.json `moslam render --format tum` writes) with the
// sequence's groundtruth.txt evaluates each accepted pose against the nearest world object of its
// label: world_T_camera * camera_T_object vs world_T_object. A progress bar goes to stderr when
// it is a terminal (one line per 10% otherwise).
#include <fmt/core.h>
#include <pcl/console/print.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "cli.h"
#include "commands.h"
#include "detector_flags.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/perception/object_perception.h"
#include "moslam/render/tum_sequence.h"

namespace moslam::cli {
namespace {

struct PerceiveArgs {
  std::string sequence;
  std::string model = CommittedDetectorModel();
  std::string classes = CommittedDetectorClasses();
  DetectorFlags detector;
  std::string templates;
  int every = 1;
  int max_frames = 0;
  std::string out;
  std::string annotate;
  std::string world;
  std::string template_cache = DefaultTemplateCacheDir();
  std::string consensus = "prerejective";
  int template_views = TemplateViews{}.views;
  bool depth_smoothing = DepthSmoothingConfig{}.enabled;
  int threads = 2;
  bool json = false;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(at));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (at - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

// Per class (and "all"): detections, registered, accepted, pose errors and per-detection
// registration times (one thread's time: the latency of one detection).
struct ClassStats {
  int detections = 0, registered = 0, accepted = 0;
  std::vector<double> ms, prepare, consensus, gate, gicp, t_err, r_err;
  void add(const PerceivedObject& o) {
    ++detections;
    if (o.status == PerceptionStatus::kNoTemplate ||
        o.status == PerceptionStatus::kSegmentationFailed) {
      return;
    }
    ++registered;
    accepted += o.accepted();
    const RegistrationTimes& t = o.registration.times;
    ms.push_back(t.total());
    prepare.push_back(t.prepare);
    consensus.push_back(t.consensus);
    gate.push_back(t.gate);
    gicp.push_back(t.gicp + t.information);
  }
};

nlohmann::json PoseJson(const SE3& x) {
  const Eigen::Vector4d q = x.rotation().quaternionWxyz();
  const Vector3& t = x.translation();
  return {{"t", {t.x(), t.y(), t.z()}}, {"q_xyzw", {q[1], q[2], q[3], q[0]}}};
}

double Median(std::vector<double> v) { return Percentile(std::move(v), 0.5); }

nlohmann::json Number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

void Annotate(cv::Mat& image, const FramePerception& seen) {
  for (const PerceivedObject& o : seen.objects) {
    const cv::Scalar colour = o.accepted() ? cv::Scalar(0, 200, 0)
                              : o.status == PerceptionStatus::kTooFewInliers
                                  ? cv::Scalar(0, 0, 230)
                                  : cv::Scalar(0, 140, 255);
    const cv::Rect box(o.detection.box);
    cv::rectangle(image, box, colour, 1);
    const std::string text = fmt::format("{} {:.2f}{}", o.detection.label,
                                         o.detection.confidence,
                                         o.accepted() ? "" : std::string(" ") + ToString(o.status));
    cv::putText(image, text, cv::Point(box.x, std::max(10, box.y - 3)), cv::FONT_HERSHEY_PLAIN,
                0.8, colour, 1);
  }
}

class Progress {
 public:
  explicit Progress(int total) : total_(total), tty_(isatty(STDERR_FILENO) != 0) {}
  void update(int done, int accepted) {
    if (total_ <= 0) return;
    if (tty_) {
      const int width = 30;
      const int filled = width * done / total_;
      fmt::print(stderr, "\r[{}{}] {}/{} frames, {} objects", std::string(filled, '='),
                 std::string(width - filled, ' '), done, total_, accepted);
      if (done == total_) fmt::print(stderr, "\n");
    } else if (done * 10 / total_ != last_decile_ || done == total_) {
      last_decile_ = done * 10 / total_;
      fmt::print(stderr, "perceive: {}/{} frames, {} objects\n", done, total_, accepted);
    }
  }

 private:
  int total_;
  bool tty_;
  int last_decile_ = 0;
};

PerceptionConfig PerceiveConfig(const PerceiveArgs& a) {
  PerceptionConfig config;
  config.detector.model_path = a.model;
  config.detector.class_names_file = a.classes;
  a.detector.applyTo(&config.detector);
  config.templates_dir = a.templates;
  config.template_cache_dir = TemplateCacheDir(a.template_cache);
  config.template_views.views = a.template_views;
  config.segmentation.smoothing.enabled = a.depth_smoothing;
  config.threads = a.threads;
  config.registration.consensus =
      a.consensus == "sac-ia" ? Consensus::kSacIa : Consensus::kPrerejective;
  return config;
}

// One detection as --out writes it: box, status, the registration's diagnostics and, when it
// registered, its times; accepted, its fitness and information.
nlohmann::json ObjectJson(const PerceivedObject& o) {
  const cv::Rect2f& b = o.detection.box;
  nlohmann::json j = {{"label", o.detection.label},
                      {"confidence", o.detection.confidence},
                      {"box", {b.x, b.y, b.width, b.height}},
                      {"status", ToString(o.status)},
                      {"inliers", o.registration.inliers},
                      {"refined_inliers", o.registration.refined_inliers},
                      {"geometric_agreement", o.registration.geometric_agreement},
                      {"colour_agreement", o.registration.colour_agreement},
                      {"covered_agreement", o.registration.covered_agreement},
                      {"hypothesis", o.registration.hypothesis}};
  if (o.status == PerceptionStatus::kSegmentationFailed) {
    const SegmentationResult& sr = o.segmentation;
    j["segmentation"] = {{"status", ToString(sr.status)},
                         {"valid_points_in_box", sr.valid_points_in_box},
                         {"structure_points_in_box", sr.structure_points_in_box},
                         {"planes_dropped", sr.planes_dropped},
                         {"components", sr.components}};
  }
  if (o.status != PerceptionStatus::kNoTemplate &&
      o.status != PerceptionStatus::kSegmentationFailed) {
    const RegistrationTimes& rt = o.registration.times;
    j["register_ms"] = rt.total();
    j["stage_ms"] = {{"prepare", rt.prepare},
                     {"consensus", rt.consensus},
                     {"gate", rt.gate},
                     {"gicp", rt.gicp + rt.information}};
  }
  if (o.accepted()) {
    j["fitness"] = o.registration.fitness;
    std::vector<double> info(o.registration.information.data(),
                             o.registration.information.data() + 36);
    j["information"] = info;
  }
  return j;
}

// A rejected registration keeps the pose it rejected (RegistrationResult::camera_T_object): its
// error tells a right pose turned away from a wrong one. Only accepted poses enter the medians.
bool HasPose(const PerceivedObject& o) {
  return o.status == PerceptionStatus::kAccepted || o.status == PerceptionStatus::kTooFewInliers ||
         o.status == PerceptionStatus::kShapeMismatch ||
         o.status == PerceptionStatus::kBoxMismatch ||
         o.status == PerceptionStatus::kColourMismatch;
}

// An estimated object pose against the nearest world object of its label.
struct GroundTruthError {
  const ObjectInstance* object = nullptr;  // null: the world has none of the label
  double translation = 0.0;                // m
  double rotation_deg = 0.0;
};

GroundTruthError AgainstWorld(const World& world, const std::string& label,
                              const SE3& world_T_object) {
  GroundTruthError e;
  double best = std::numeric_limits<double>::infinity();
  for (const ObjectInstance& w : world.objects) {
    if (w.label != label) continue;
    const double d = (w.pose.translation() - world_T_object.translation()).norm();
    if (d < best) {
      best = d;
      e.object = &w;
    }
  }
  if (e.object == nullptr) return e;
  e.translation = best;
  e.rotation_deg =
      SO3::Log(e.object->pose.rotation().inverse() * world_T_object.rotation()).norm() * 180.0 /
      M_PI;
  return e;
}

// What the run counted over every perceived frame.
struct PerceiveTotals {
  std::size_t frames = 0;
  StageTimes times;
  int detections = 0, accepted = 0, gate_rejects = 0;
  std::vector<double> t_err, r_err;  // accepted poses against the world
  std::map<std::string, ClassStats> by_class;
};

nlohmann::json SummaryJson(const PerceiveArgs& a, const PerceiveTotals& t,
                           const ObjectPerception& perception, bool evaluated) {
  const double nf = std::max<double>(1.0, static_cast<double>(t.frames));
  nlohmann::json summary = {
      {"sequence", a.sequence},
      {"frames", t.frames},
      {"detections", t.detections},
      {"accepted", t.accepted},
      {"rejected_by_inlier_gate", t.gate_rejects},
      {"ms_per_frame",
       {{"detect", t.times.detect / nf},
        {"segment", (t.times.prepare + t.times.segment) / nf},
        {"register", t.times.register_ / nf},
        {"total", t.times.total() / nf}}},
      {"template_seconds", perception.templateSeconds()},
      {"templates_from_cache", perception.templatesFromCache()},
      {"detector",
       {{"threshold", a.detector.threshold},
        {"nms", a.detector.nms},
        {"agnostic_nms", a.detector.agnostic_nms},
        {"flip_test", a.detector.flip_test}}},
      {"consensus", a.consensus},
      {"depth_smoothing", a.depth_smoothing},
      {"threads", a.threads},
  };
  nlohmann::json classes = nlohmann::json::object();
  for (const auto& [label, c] : t.by_class) {
    nlohmann::json j = {
        {"detections", c.detections},
        {"registered", c.registered},
        {"accepted", c.accepted},
        {"register_ms", {{"median", Number(Median(c.ms))}, {"p90", Number(Percentile(c.ms, 0.9))}}},
        {"stage_ms_median",
         {{"prepare", Number(Median(c.prepare))},
          {"consensus", Number(Median(c.consensus))},
          {"gate", Number(Median(c.gate))},
          {"gicp", Number(Median(c.gicp))}}}};
    if (evaluated) {
      j["evaluated"] = c.t_err.size();
      j["median_translation_error"] = Number(Median(c.t_err));
      j["median_rotation_error_deg"] = Number(Median(c.r_err));
    }
    classes[label] = std::move(j);
  }
  summary["classes"] = std::move(classes);
  if (evaluated) {
    summary["evaluated"] = t.t_err.size();
    summary["median_translation_error"] = Number(Median(t.t_err));
    summary["median_rotation_error_deg"] = Number(Median(t.r_err));
  }
  return summary;
}

// One perceived object as JSON (its pose, and against the world's objects when given), counted
// into the totals.
nlohmann::json ObjectRecord(const PerceivedObject& o, const TumFrame& f,
                            const std::optional<World>& world, PerceiveTotals& t) {
  ++t.detections;
  t.by_class[o.detection.label].add(o);
  t.by_class["all"].add(o);
  if (o.status == PerceptionStatus::kTooFewInliers) ++t.gate_rejects;
  if (o.accepted()) ++t.accepted;
  nlohmann::json j = ObjectJson(o);
  const bool has_pose = HasPose(o);
  if (has_pose) j["camera_T_object"] = PoseJson(o.registration.camera_T_object);
  if (!world || !f.world_T_camera || !has_pose) return j;
  const GroundTruthError e =
      AgainstWorld(*world, o.detection.label, *f.world_T_camera * o.registration.camera_T_object);
  if (!e.object) return j;
  if (o.accepted()) {
    t.t_err.push_back(e.translation);
    t.r_err.push_back(e.rotation_deg);
    for (const char* key : {"all", o.detection.label.c_str()}) {
      t.by_class[key].t_err.push_back(e.translation);
      t.by_class[key].r_err.push_back(e.rotation_deg);
    }
  }
  j["ground_truth"] = {{"object", e.object->id},
                       {"translation_error", e.translation},
                       {"rotation_error_deg", e.rotation_deg}};
  return j;
}

// The frames perceived: every a.every-th, at most a.max_frames (0: all).
std::vector<std::size_t> FramesToPerceive(const TumSequence& sequence, const PerceiveArgs& a) {
  std::vector<std::size_t> frames;
  for (std::size_t i = 0; i < sequence.frames.size(); i += static_cast<std::size_t>(a.every)) {
    if (a.max_frames > 0 && static_cast<int>(frames.size()) >= a.max_frames) break;
    frames.push_back(i);
  }
  return frames;
}

// The frame with its boxes and statuses drawn, into the --annotate folder.
void WriteAnnotated(const PerceiveArgs& a, const TumFrame& f, RgbdFrame& frame,
                    const FramePerception& seen) {
  Annotate(frame.rgb, seen);
  const std::string path =
      (std::filesystem::path(a.annotate) / std::filesystem::path(f.rgb_file).filename()).string();
  if (!cv::imwrite(path, frame.rgb)) throw Error("perceive: cannot write '" + path + "'");
}

void PrintPerceiveSummary(const PerceiveArgs& a, const PerceiveTotals& t, bool evaluated) {
  const double nf = std::max<double>(1.0, static_cast<double>(t.frames));
  fmt::print(
      "{}: {} frames, {} detections, {} accepted, {} rejected by the 12-inlier gate; "
      "ms/frame detect {:.1f}, segment {:.1f}, register {:.1f}\n",
      a.sequence, t.frames, t.detections, t.accepted, t.gate_rejects, t.times.detect / nf,
      (t.times.prepare + t.times.segment) / nf, t.times.register_ / nf);
  if (evaluated) {
    fmt::print("pose error against ground truth ({} objects): median {:.3f} m, {:.2f} deg\n",
               t.t_err.size(), Median(t.t_err), Median(t.r_err));
  }
}

int RunPerceive(const PerceiveArgs& a) {
  // SAC-IA warns on stderr for every relaxed sample distance; the statuses say what matters.
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);
  if (!a.out.empty()) CheckOutputFile(a.out, "perceive: --out");
  const TumSequence sequence = ReadTumSequence(a.sequence);
  std::optional<World> world;
  if (!a.world.empty()) world = LoadWorld(a.world);
  if (!a.annotate.empty()) CreateFolder(a.annotate, "perceive --annotate");
  ObjectPerception perception(PerceiveConfig(a), world ? world->classes : StandardObjectClasses());

  const std::vector<std::size_t> frames = FramesToPerceive(sequence, a);
  Progress progress(static_cast<int>(frames.size()));
  nlohmann::json out_frames = nlohmann::json::array();
  PerceiveTotals t;
  t.frames = frames.size();
  for (std::size_t n = 0; n < frames.size(); ++n) {
    const std::size_t i = frames[n];
    const TumFrame& f = sequence.frames[i];
    RgbdFrame frame = LoadTumFrame(sequence, i);
    const FramePerception seen = perception.perceive(frame);
    t.times.detect += seen.times.detect;
    t.times.prepare += seen.times.prepare;
    t.times.segment += seen.times.segment;
    t.times.register_ += seen.times.register_;
    nlohmann::json objects = nlohmann::json::array();
    for (const PerceivedObject& o : seen.objects) objects.push_back(ObjectRecord(o, f, world, t));
    out_frames.push_back(
        {{"timestamp", f.rgb_timestamp}, {"rgb", f.rgb_file}, {"objects", std::move(objects)}});
    if (!a.annotate.empty()) WriteAnnotated(a, f, frame, seen);
    progress.update(static_cast<int>(n + 1), t.accepted);
  }

  const nlohmann::json summary = SummaryJson(a, t, perception, world.has_value());
  if (!a.out.empty()) {
    std::ofstream file(a.out);
    file << nlohmann::json({{"summary", summary}, {"frames", out_frames}}).dump(1) << "\n";
    if (!file) throw Error("perceive: cannot write '" + a.out + "'");
  }
  for (const std::string& note : perception.templateNotes()) {
    fmt::print(stderr, "perceive: template cache: {}\n", note);
  }
  if (a.json) {
    fmt::print("{}\n", summary.dump());
  } else {
    PrintPerceiveSummary(a, t, world.has_value());
  }
  return 0;
}

}  // namespace

Runner RegisterPerceive(CLI::App& app) {
  auto args = std::make_shared<PerceiveArgs>();
  CLI::App* sub = app.add_subcommand("perceive", kPerceiveDescription);
  sub->add_option("sequence", args->sequence,
                  "sequence directory (rgb.txt, depth.txt, camera.txt, optional groundtruth.txt)")
      ->required();
  sub->add_option("--model", args->model, "detector ONNX model")->capture_default_str();
  sub->add_option("--classes", args->classes, "detector class names, one per line")
      ->capture_default_str();
  AddDetectorFlags(sub, &args->detector);
  sub->add_option("--templates", args->templates,
                  "folder of <label>.pcd templates replacing the built-in models");
  sub->add_option("--every", args->every, "perceive every K-th frame")
      ->check(Positive())
      ->capture_default_str();
  sub->add_option("--max-frames", args->max_frames, "stop after N perceived frames (0: all)")
      ->check(NonNegative());
  sub->add_option("--out", args->out, "write every frame's detections and poses (JSON)");
  sub->add_option("--annotate", args->annotate, "write annotated colour images to this folder");
  sub->add_option("--world", args->world,
                  "ground-truth world (JSON) to evaluate the poses with groundtruth.txt");
  sub->add_option("--template-cache", args->template_cache,
                  "folder caching the built templates (none: no cache)")
      ->capture_default_str();
  sub->add_option("--consensus", args->consensus,
                  "initial alignment: prerejective (fast) or sac-ia (the paper's)")
      ->check(CLI::IsMember({"prerejective", "sac-ia"}))
      ->capture_default_str();
  sub->add_option("--template-views", args->template_views,
                  "template features from this many rendered views of each built-in model (0: "
                  "from the whole model)")
      ->check(NonNegative())
      ->capture_default_str();
  sub->add_flag("!--no-depth-smoothing", args->depth_smoothing,
                "register far segments as measured (default: their depths smoothed along the "
                "pixels' rays where the sensor's noise is large, "
                "pose_estimation/depth_smoothing.h)");
  sub->add_option("--threads", args->threads, "detections of a frame registered in parallel")
      ->check(Positive())
      ->capture_default_str();
  sub->add_flag("--json", args->json, "print the summary as one JSON object on the last line");
  return [args] { return RunPerceive(*args); };
}

}  // namespace moslam::cli
