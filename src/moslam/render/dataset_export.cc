#include "moslam/render/dataset_export.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/sim/robots.h"

namespace moslam {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

nlohmann::json PoseJson(const SE3& x) {
  const Eigen::Vector4d q = x.rotation().quaternionWxyz();
  const Vector3& t = x.translation();
  return {{"translation", {t.x(), t.y(), t.z()}}, {"rotation", {q[1], q[2], q[3], q[0]}}};
}

int ClassIndex(const std::vector<ObjectClass>& classes, const std::string& label) {
  for (std::size_t i = 0; i < classes.size(); ++i) {
    if (classes[i].label == label) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

void ScenarioViewsConfig::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("ScenarioViewsConfig: " + m); };
  if (scenario != "chairs25" && scenario != "house" && scenario != "generated") {
    bad("scenario must be chairs25, house or generated (got '" + scenario + "')");
  }
  if (num_robots < 1 || num_robots > 1024) bad("num_robots must be in [1, 1024]");
  if (poses_per_robot < 1 || poses_per_robot > 1000000) {
    bad("poses_per_robot must be in [1, 1000000]");
  }
  if (frames_per_robot < 0) bad("frames_per_robot must be >= 0");
  if (!(yaw_jitter_deg >= 0.0 && yaw_jitter_deg <= 180.0)) bad("yaw_jitter_deg must be in [0, 180]");
  if (!(pitch_jitter_deg >= 0.0 && pitch_jitter_deg <= 45.0)) {
    bad("pitch_jitter_deg must be in [0, 45]");
  }
  if (!(height_jitter_m >= 0.0 && height_jitter_m <= 0.45)) {
    bad("height_jitter_m must be in [0, 0.45] (the camera stays above the floor)");
  }
}

ScenarioViews MakeScenarioViews(const ScenarioViewsConfig& config) {
  config.validate();
  ScenarioViews out;
  out.config = config;
  out.world = MakeScenarioWorld(config.scenario, config.seed, config.num_robots);
  TrajectoryConfig tc;
  tc.num_robots = config.num_robots;
  tc.poses_per_robot = config.poses_per_robot;
  tc.seed = config.seed;
  const auto trajectories = GenerateTrajectories(out.world, tc);
  std::mt19937 rng(config.seed ^ 0x5eed1234U);
  std::uniform_real_distribution<double> sym(-1.0, 1.0);
  const int P = config.poses_per_robot;
  const int K = config.frames_per_robot == 0 ? P : std::min(config.frames_per_robot, P);
  for (int r = 0; r < config.num_robots; ++r) {
    for (int k = 0; k < K; ++k) {
      // Evenly spread: step = floor((k + 0.5) P / K).
      const int step = std::min(P - 1, static_cast<int>((k + 0.5) * P / K));
      View v;
      v.robot = r;
      v.step = step;
      const SE3& x = trajectories[static_cast<std::size_t>(r)][static_cast<std::size_t>(step)];
      const double yaw = config.yaw_jitter_deg * kDegToRad * sym(rng);
      const double pitch = config.pitch_jitter_deg * kDegToRad * sym(rng);
      const double dz = config.height_jitter_m * sym(rng);
      const SO3 R = SO3::Exp(Vector3(0.0, 0.0, yaw)) * x.rotation() *
                    SO3::Exp(Vector3(0.0, pitch, 0.0));
      v.world_T_body = SE3(R, x.translation() + Vector3(0.0, 0.0, dz));
      out.views.push_back(v);
    }
  }
  return out;
}

void YoloLabelConfig::validate() const {
  if (min_visible_pixels < 1) {
    throw InvalidInputError("YoloLabelConfig: min_visible_pixels must be >= 1");
  }
  if (!(min_in_image_fraction >= 0.0 && min_in_image_fraction <= 1.0)) {
    throw InvalidInputError("YoloLabelConfig: min_in_image_fraction must be in [0, 1]");
  }
  if (min_labels_per_frame < 0) {
    throw InvalidInputError("YoloLabelConfig: min_labels_per_frame must be >= 0");
  }
}

namespace {

// Lines of the standard-class objects that pass (labelled = true) or fail (labelled = false)
// the label filters.
std::vector<std::string> BoxLines(const RenderedFrame& frame,
                                  const std::vector<ObjectClass>& classes,
                                  const YoloLabelConfig& config, bool labelled) {
  config.validate();
  const double W = frame.rgbd.intrinsics.width, H = frame.rgbd.intrinsics.height;
  std::vector<std::string> lines;
  for (const VisibleObject& o : frame.objects) {
    const int c = ClassIndex(classes, o.label);
    if (c < 0 || o.box.width <= 0 || o.box.height <= 0) continue;
    const bool passes = o.visible_pixels >= config.min_visible_pixels &&
                        o.in_image_fraction >= config.min_in_image_fraction;
    if (passes != labelled) continue;
    // Pixel (u, v) covers [u, u + 1) x [v, v + 1) in these normalised coordinates.
    const double cx = (o.box.x + 0.5 * o.box.width) / W, cy = (o.box.y + 0.5 * o.box.height) / H;
    lines.push_back(fmt::format("{} {:.6f} {:.6f} {:.6f} {:.6f}", c, cx, cy, o.box.width / W,
                                o.box.height / H));
  }
  return lines;
}

void WriteLines(const std::string& path, const std::vector<std::string>& lines) {
  std::ofstream f(path);
  for (const auto& l : lines) f << l << "\n";
  if (!f) throw Error("cannot write '" + path + "'");
}

// The dataset's folders (images, labels, ignore) and its classes.txt.
void PrepareDatasetFolder(const std::string& dir, const std::vector<ObjectClass>& classes) {
  namespace fs = std::filesystem;
  for (const char* folder : {"images", "labels", "ignore"}) {
    CreateFolder(fs::path(dir) / folder, "YOLO dataset");
  }
  std::ofstream f(fs::path(dir) / "classes.txt");
  for (const auto& c : classes) f << c.label << "\n";
  if (!f) throw Error("cannot write '" + dir + "/classes.txt'");
}

// A written frame's record in the frames file: its view and the ground truth of its objects.
nlohmann::json FrameJson(int index, const View& v, const RenderedFrame& frame) {
  nlohmann::json objects = nlohmann::json::array();
  for (const auto& o : frame.objects) {
    nlohmann::json j = PoseJson(o.camera_T_object);
    j["id"] = o.id;
    j["label"] = o.label;
    j["box"] = {o.box.x, o.box.y, o.box.width, o.box.height};
    j["visible_pixels"] = o.visible_pixels;
    j["in_image_fraction"] = o.in_image_fraction;
    objects.push_back(j);
  }
  return {{"index", index},
          {"robot", v.robot},
          {"step", v.step},
          {"world_T_camera", PoseJson(frame.world_T_camera)},
          {"camera_T_object", objects}};
}

nlohmann::json IntrinsicsJson(const PinholeIntrinsics& K) {
  return {{"width", K.width}, {"height", K.height}, {"fx", K.fx},
          {"fy", K.fy},       {"cx", K.cx},         {"cy", K.cy}};
}

}  // namespace

std::vector<std::string> YoloLabelLines(const RenderedFrame& frame,
                                        const std::vector<ObjectClass>& classes,
                                        const YoloLabelConfig& config) {
  return BoxLines(frame, classes, config, true);
}

std::vector<std::string> YoloIgnoreLines(const RenderedFrame& frame,
                                         const std::vector<ObjectClass>& classes,
                                         const YoloLabelConfig& config) {
  return BoxLines(frame, classes, config, false);
}

YoloExportSummary ExportYoloDataset(const Renderer& renderer, const ScenarioViews& views,
                                    const std::string& dir, int first_index,
                                    const YoloLabelConfig& labels,
                                    const std::function<void(int, int)>& progress) {
  namespace fs = std::filesystem;
  using Clock = std::chrono::steady_clock;
  labels.validate();
  if (first_index < 0 || first_index + static_cast<long>(views.views.size()) > 1000000) {
    throw InvalidInputError("ExportYoloDataset: frame indices must stay in [0, 999999]");
  }
  const auto t0 = Clock::now();
  const std::vector<ObjectClass> classes = StandardObjectClasses();
  PrepareDatasetFolder(dir, classes);
  YoloExportSummary s;
  s.labels_per_class.assign(classes.size(), 0);
  nlohmann::json frames = nlohmann::json::array();
  const int total = static_cast<int>(views.views.size());
  for (int i = 0; i < total; ++i) {
    const View& v = views.views[static_cast<std::size_t>(i)];
    const int index = first_index + s.frames;
    const auto r0 = Clock::now();
    // The noise key is the view's position in the run, so a view renders the same whether or
    // not earlier views were skipped.
    const RenderedFrame frame =
        renderer.render(v.world_T_body, static_cast<std::uint64_t>(first_index + i));
    s.render_seconds += std::chrono::duration<double>(Clock::now() - r0).count();
    const auto lines = YoloLabelLines(frame, classes, labels);
    if (static_cast<int>(lines.size()) < labels.min_labels_per_frame) {
      ++s.skipped_frames;
      if (progress) progress(i + 1, total);
      continue;
    }
    const std::string name = fmt::format("{:06d}", index);
    const std::string image = (fs::path(dir) / "images" / (name + ".png")).string();
    if (!cv::imwrite(image, frame.rgbd.rgb)) throw Error("cannot write '" + image + "'");
    WriteLines((fs::path(dir) / "labels" / (name + ".txt")).string(), lines);
    for (const auto& l : lines) {
      ++s.labels;
      ++s.labels_per_class[static_cast<std::size_t>(std::stoi(l.substr(0, l.find(' '))))];
    }
    const auto ignore_lines = YoloIgnoreLines(frame, classes, labels);
    WriteLines((fs::path(dir) / "ignore" / (name + ".txt")).string(), ignore_lines);
    s.ignored += static_cast<int>(ignore_lines.size());
    frames.push_back(FrameJson(index, v, frame));
    ++s.frames;
    if (progress) progress(i + 1, total);
  }
  const nlohmann::json meta = {{"scenario", views.config.scenario},
                               {"seed", views.config.seed},
                               {"robots", views.config.num_robots},
                               {"poses_per_robot", views.config.poses_per_robot},
                               {"intrinsics", IntrinsicsJson(renderer.config().intrinsics)},
                               {"min_visible_pixels", labels.min_visible_pixels},
                               {"min_in_image_fraction", labels.min_in_image_fraction},
                               {"min_labels_per_frame", labels.min_labels_per_frame},
                               {"skipped_views", s.skipped_frames},
                               {"frames", frames}};
  const std::string meta_path =
      (fs::path(dir) / fmt::format("frames_{:06d}-{:06d}.json", first_index,
                                   first_index + std::max(0, s.frames - 1)))
          .string();
  std::ofstream m(meta_path);
  m << meta.dump(1) << "\n";
  if (!m) throw Error("cannot write '" + meta_path + "'");
  s.total_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return s;
}

}  // namespace moslam
