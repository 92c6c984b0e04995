// `moslam simulate --perception rendered` in the perception executable: the experiments'
// perception hook (ExperimentConfig::perceive) runs the front-end on rendered frames
// (perception/rendered_sensing.h) and records its statistics in the run's metrics.
#include <pcl/console/print.h>

#include <fmt/core.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/experiments/perception_cache.h"
#include "moslam/perception/rendered_sensing.h"
#include "moslam/render/visible_sensing.h"
#include "moslam/sim/sensing.h"

namespace moslam::cli {
namespace {

// --detection-log: one JSON object per detection and line (NaN errors as null); `run` counts the
// command's runs in order (a row's runs, then the next row's).
void WriteDetectionLog(std::ofstream& out, const std::string& path, int run,
                       const SimulationData& data, const std::vector<DetectionRecord>& records) {
  const auto number = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nullptr; };
  for (const DetectionRecord& d : records) {
    const nlohmann::json j = {{"scenario", data.world.name},
                              {"robots", data.numRobots()},
                              {"run", run},
                              {"robot", d.robot},
                              {"pose", d.pose},
                              {"label", d.label},
                              {"status", ToString(d.status)},
                              {"object", d.object >= 0 ? nlohmann::json(d.object) : nullptr},
                              {"visible_fraction", d.visible_fraction},
                              {"depth", d.depth},
                              {"translation_error", number(d.translation_error)},
                              {"rotation_error_deg", number(d.rotation_error_deg)},
                              {"inliers", d.inliers},
                              {"refined_inliers", d.refined_inliers},
                              {"segment_points", d.segment_points},
                              {"geometric_agreement", d.geometric_agreement},
                              {"covered_agreement", d.covered_agreement},
                              {"colour_agreement", d.colour_agreement}};
    out << j.dump() << '\n';
  }
  out.flush();
  if (!out) throw Error("simulate: cannot write the detection log '" + path + "'");
}

// FNV-1a 64 of a file's bytes, continuing from `state`. Throws InvalidInputError naming the file
// when it cannot be read.
std::uint64_t FileDigest(const std::string& path, std::uint64_t state) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInputError("simulate --perception-cache: cannot read '" + path + "'");
  std::vector<char> buffer(std::size_t{1} << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    state = Fnv1a64(buffer.data(), static_cast<std::size_t>(in.gcount()), state);
  }
  if (!in.eof()) throw InvalidInputError("simulate --perception-cache: read error in '" + path + "'");
  return state;
}

// The perception cache's front-end digest (experiments/perception_cache.h): this executable (the
// front-end's code and its compiled defaults), the detector's model and class names, the templates
// replacing the built-in models (each file's name and bytes, in name order) and the options the
// result depends on. The template cache is left out: it holds what the templates make.
std::uint64_t FrontEndDigest(const RenderedPerceptionArgs& args) {
  std::uint64_t h = FileDigest("/proc/self/exe", kFnvOffset);
  h = FileDigest(args.model, h);
  h = FileDigest(args.classes, h);
  if (!args.templates.empty()) {
    std::vector<std::filesystem::path> files;
    std::error_code ec;
    for (std::filesystem::directory_iterator it(args.templates, ec), end; !ec && it != end;
         it.increment(ec)) {
      if (it->is_regular_file()) files.push_back(it->path());
    }
    if (ec) {
      throw InvalidInputError("simulate --perception-cache: cannot list the templates folder '" +
                              args.templates + "': " + ec.message());
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      const std::string name = f.filename().string();
      h = Fnv1a64(name.data(), name.size(), h);
      h = FileDigest(f.string(), h);
    }
  }
  const int options[] = {args.every, args.template_views, args.depth_smoothing ? 1 : 0};
  return Fnv1a64(options, sizeof options, h);
}

// --perception visible: every object the frames show, measured with Gaussian noise.
ExperimentConfig::Perceive VisiblePerception(const RenderedPerceptionArgs& args) {
  VisibleSensingConfig config;
  config.every = args.every;
  config.noise.sigma_rotation_deg = args.visible_sigma_rotation_deg;
  config.noise.sigma_translation = args.visible_sigma_translation;
  config.keep_probability = args.visible_keep;
  config.validate();
  return [config](SimulationData& data, RunMetrics& m) {
    const VisibleSensingStats v = MeasureVisibleObjects(data, config);
    m.perception_frames = v.frames;
    m.perception_ms_render = v.render_ms / std::max(1, v.frames);
    fmt::print(stderr,
               "visible, {} ({} robots): {} object measurements of the {} frames, of {} objects "
               "seen >= {:.0f} % within {} m (sampled: {})\n",
               data.world.name, data.numRobots(), v.measured, v.frames, v.seen_enough,
               100.0 * config.min_visible_fraction, config.render.max_depth, v.replaced);
  };
}

// The front-end's measurements of one run into its metrics.
void PerceptionMetrics(const RenderedSensingStats& p, const SimulationData& data,
                       const PointCloudModel& point_cloud, RunMetrics& m) {
  const double frames = std::max(1, p.frames);
  m.perception_frames = p.frames;
  m.perception_detections = p.detections;
  const AcceptanceCounts all = p.total();
  m.perception_true_detections = all.true_detections;
  m.perception_accepted = p.accepted;
  m.perception_accepted_true = all.accepted;
  m.perception_true_visible = all.true_visible;
  m.perception_accepted_visible = all.accepted_visible;
  m.perception_rejected_inliers = p.rejected_inliers;
  m.perception_rejected_inliers_false = p.rejected_inliers_false;
  m.perception_median_error_m = p.medianTranslationError();
  m.perception_median_error_deg = p.medianRotationErrorDeg();
  m.perception_ms_render = p.render_ms / frames;
  m.perception_ms_detect = p.times.detect / frames;
  m.perception_ms_segment = (p.times.prepare + p.times.segment) / frames;
  m.perception_ms_register = p.times.register_ / frames;
  m.perception_pcd_bytes =
      static_cast<double>(p.valid_depth_points) * point_cloud.bytes_per_point / data.numRobots();
}

// One run's report (the tables average runs): acceptance per class and by the object's depth,
// the accepted false detections and the accepted true ones far off.
std::string PerceptionReport(const RenderedSensingStats& p, const SimulationData& data,
                             double min_visible_fraction) {
  std::string line = fmt::format(
      "perception, {} ({} robots): accepted of true detections of objects >= {:.0f} % "
      "visible (of all true detections), by class:",
      data.world.name, data.numRobots(), 100.0 * min_visible_fraction);
  for (const auto& [label, c] : p.by_class) {
    line += fmt::format(" {} {}/{} (all {}/{})", label, c.accepted_visible, c.true_visible,
                        c.accepted, c.true_detections);
  }
  line += "\nby the object's depth (m):";
  for (const auto& [bin, c] : p.by_depth) {
    line += fmt::format(" {}{} {}/{} (all {}/{})", bin,
                        bin == RenderedSensingStats::kDepthBins - 1 ? "+" : "", c.accepted_visible,
                        c.true_visible, c.accepted, c.true_detections);
  }
  // The accepted detections that are not true, against the nearest same-label object seen.
  int near = 0;
  std::string errors;
  for (const auto& [t, r] : p.false_accepted_errors) {
    near += t <= 0.1 && r <= 10.0 ? 1 : 0;
    errors += fmt::format(" {:.2f} m / {:.0f} deg;", t, r);
  }
  line += fmt::format(
      "\naccepted false detections: {}, {} of them within 10 cm / 10 deg of a "
      "same-label object seen (nearest:{})",
      p.false_accepted_errors.size(), near, errors);
  line += fmt::format(
      "\naccepted true detections more than 10 cm / 10 deg off: {} of {}, {} of "
      "them within 10 cm of another same-label object seen",
      p.accepted_true_off, p.total().accepted, p.accepted_true_other_object);
  return line;
}

}  // namespace

ExperimentConfig::Perceive MakeRenderedPerception(const RenderedPerceptionArgs& args) {
  if (args.visible) return VisiblePerception(args);
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);  // SAC-IA's per-sample warnings
  auto config = std::make_shared<RenderedSensingConfig>();
  config->perception.detector.model_path = args.model;
  config->perception.detector.class_names_file = args.classes;
  config->perception.templates_dir = args.templates;
  config->perception.template_cache_dir = TemplateCacheDir(args.template_cache);
  config->perception.template_views.views = args.template_views;
  config->perception.segmentation.smoothing.enabled = args.depth_smoothing;
  config->every = args.every;
  config->record_detections = !args.detection_log.empty();
  config->validate();
  std::shared_ptr<std::ofstream> log;
  if (config->record_detections) {
    log = std::make_shared<std::ofstream>(args.detection_log, std::ios::trunc);
    if (!*log) {
      throw Error("simulate: cannot open the detection log '" + args.detection_log + "'");
    }
  }
  const PointCloudModel point_cloud;
  auto run = std::make_shared<int>(0);
  // The front-end on the run's frames; returns the run's report.
  ReportingPerceive perceive = [config, point_cloud, log, run, path = args.detection_log](
                                   SimulationData& data, RunMetrics& m) {
    const RenderedSensingStats p = PerceiveSimulation(data, *config);
    if (log) WriteDetectionLog(*log, path, (*run)++, data, p.records);
    PerceptionMetrics(p, data, point_cloud, m);
    return PerceptionReport(p, data, config->min_visible_fraction);
  };
  const auto print = [](const std::string& report) { fmt::print(stderr, "{}\n", report); };
  if (args.perception_cache.empty()) {
    return [perceive, print](SimulationData& data, RunMetrics& m) { print(perceive(data, m)); };
  }
  return CachedPerception(perceive, PerceptionCache(args.perception_cache),
                          FrontEndDigest(args), print);
}

}  // namespace moslam::cli
