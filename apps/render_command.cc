// `moslam render`: rendered RGB-D frames of a simulated scenario, along the robots' trajectories.
//
//   moslam render --scenario chairs25|house|generated --robots N --poses P --seed S
//                 --width W --height H --out DIR --format yolo|tum [--frames-per-robot K]
//                 [--first-index I] [--hfov DEG] [--min-pixels 150] [--min-labels 0]
//                 [--no-noise] [--no-walls]
//
// yolo: a detector training set (render/dataset_export.h): DIR/images, DIR/labels, DIR/ignore,
//       DIR/classes.txt; the viewpoint is jittered (--yaw-jitter 10 deg, --pitch-jitter 3 deg,
//       --height-jitter 0.05 m by default) and the room colours vary with the seed. Runs with
//       different --first-index append to the same DIR.
// tum:  one TUM RGB-D sequence per robot, DIR/robot<R>/ (render/tum_sequence.h), timestamps
//       step * --frame-period, no jitter by default, and DIR/world.json (sim/world.h) as the
//       ground truth of the objects.
#include <fmt/core.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/render/dataset_export.h"
#include "moslam/render/renderer.h"
#include "moslam/render/tum_sequence.h"

namespace moslam::cli {

namespace {

struct RenderArgs {
  std::string scenario = "chairs25";
  int robots = 2;
  int poses = 100;
  unsigned seed = 1;
  int width = 320;
  int height = 240;
  double hfov = 60.0;
  std::string out;
  std::string format = "yolo";
  int frames_per_robot = 0;
  int first_index = 0;
  int min_pixels = 150;
  int min_labels = 0;
  double min_in_image = 0.5;
  double yaw_jitter = -1.0;  // < 0: the format's default
  double pitch_jitter = -1.0;
  double height_jitter = -1.0;
  double frame_period = 1.0;
  bool no_noise = false;
  bool no_walls = false;
  bool plain_style = false;
};

void Progress(int done, int total) {
  if (done == total || done % 50 == 0) {
    fmt::print(stderr, "\rrendered {}/{} frames", done, total);
    if (done == total) fmt::print(stderr, "\n");
  }
}

ScenarioViews MakeViews(const RenderArgs& a) {
  const bool yolo = a.format == "yolo";
  ScenarioViewsConfig vc;
  vc.scenario = a.scenario;
  vc.num_robots = a.robots;
  vc.poses_per_robot = a.poses;
  vc.seed = a.seed;
  vc.frames_per_robot = a.frames_per_robot;
  vc.yaw_jitter_deg = a.yaw_jitter >= 0.0 ? a.yaw_jitter : (yolo ? 10.0 : 0.0);
  vc.pitch_jitter_deg = a.pitch_jitter >= 0.0 ? a.pitch_jitter : (yolo ? 3.0 : 0.0);
  vc.height_jitter_m = a.height_jitter >= 0.0 ? a.height_jitter : (yolo ? 0.05 : 0.0);
  return MakeScenarioViews(vc);
}

RenderConfig MakeRenderConfig(const RenderArgs& a) {
  RenderConfig rc;
  rc.intrinsics = PinholeIntrinsics::FromHorizontalFov(a.width, a.height, a.hfov);
  rc.seed = a.seed;
  rc.draw_walls = !a.no_walls;
  if (!a.plain_style) rc.style = RandomSceneStyle(a.seed);
  if (a.no_noise) {
    rc.depth_noise = false;
    rc.colour_noise_sigma = 0.0;
  }
  return rc;
}

// --format yolo: the YOLO dataset (dataset_export.h) and its summary.
void WriteYolo(const RenderArgs& a, const Renderer& renderer, const ScenarioViews& views) {
  YoloLabelConfig lc;
  lc.min_visible_pixels = a.min_pixels;
  lc.min_in_image_fraction = a.min_in_image;
  lc.min_labels_per_frame = a.min_labels;
  const auto s = ExportYoloDataset(renderer, views, a.out, a.first_index, lc, Progress);
  fmt::print(
      "wrote {} frames ({:06d}-{:06d}) and {} labels to {} ({} views with fewer than {} "
      "labels skipped)\n",
      s.frames, a.first_index, a.first_index + std::max(0, s.frames - 1), s.labels, a.out,
      s.skipped_frames, a.min_labels);
  const auto classes = StandardObjectClasses();
  std::string per_class;
  for (std::size_t c = 0; c < classes.size(); ++c) {
    per_class +=
        fmt::format("{}{} {}", c == 0 ? "" : ", ", classes[c].label, s.labels_per_class[c]);
  }
  fmt::print("labels per class: {}\n", per_class);
  fmt::print("{} visible objects not labelled (ignore regions) written to {}/ignore\n", s.ignored,
             a.out);
  fmt::print("render {:.2f} ms/frame, total (with PNG writing) {:.2f} ms/frame\n",
             1e3 * s.render_seconds / std::max(1, s.frames),
             1e3 * s.total_seconds / std::max(1, s.frames));
}

// --format tum: one sequence per robot, and the world.
void WriteTum(const RenderArgs& a, const Renderer& renderer, const ScenarioViews& views) {
  using Clock = std::chrono::steady_clock;
  namespace fs = std::filesystem;
  CreateFolder(a.out, "render --out");
  SaveWorld((fs::path(a.out) / "world.json").string(), views.world);
  double render_seconds = 0.0;
  int frames = 0;
  const int total = static_cast<int>(views.views.size());
  std::unique_ptr<TumSequenceWriter> writer;
  int current_robot = -1;
  for (const View& v : views.views) {
    if (v.robot != current_robot) {
      if (writer) writer->close();
      current_robot = v.robot;
      writer = std::make_unique<TumSequenceWriter>(
          (fs::path(a.out) / fmt::format("robot{}", v.robot)).string(),
          renderer.config().intrinsics);
    }
    const auto t0 = Clock::now();
    const std::uint64_t key = static_cast<std::uint64_t>(v.robot) * 1000003ULL +
                              static_cast<std::uint64_t>(v.step);
    const RenderedFrame f = renderer.render(v.world_T_body, key, v.step * a.frame_period);
    render_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    writer->add(f.rgbd, f.world_T_camera);
    Progress(++frames, total);
  }
  if (writer) writer->close();
  fmt::print("wrote {} sequences ({} frames) and world.json to {}; render {:.2f} ms/frame\n",
             a.robots, frames, a.out, 1e3 * render_seconds / std::max(1, frames));
}

int Run(const RenderArgs& a) {
  const ScenarioViews views = MakeViews(a);
  const Renderer renderer(views.world, MakeRenderConfig(a));
  fmt::print("scenario {} (seed {}): {} objects, {} robots, {} views at {}x{} (hfov {} deg)\n",
             a.scenario, a.seed, views.world.objects.size(), a.robots, views.views.size(), a.width,
             a.height, a.hfov);
  if (a.format == "yolo") {
    WriteYolo(a, renderer, views);
  } else {
    WriteTum(a, renderer, views);
  }
  return 0;
}

}  // namespace

Runner RegisterRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  CLI::App* sub = app.add_subcommand("render", kRenderDescription);
  sub->add_option("--scenario", a->scenario, "chairs25 | house | generated")
      ->check(CLI::IsMember({"chairs25", "house", "generated"}));
  sub->add_option("--robots", a->robots, "number of robots (trajectories)")
      ->check(CLI::Range(1, 1024));
  sub->add_option("--poses", a->poses, "poses per robot")->check(CLI::Range(1, 1000000));
  sub->add_option("--seed", a->seed, "world, trajectories, jitter, colours and noise");
  sub->add_option("--width", a->width, "image width (pixels)")->check(CLI::Range(16, 4096));
  sub->add_option("--height", a->height, "image height (pixels)")->check(CLI::Range(16, 4096));
  sub->add_option("--hfov", a->hfov, "horizontal field of view (deg)")->check(InRange(10.0, 170.0));
  sub->add_option("--out", a->out, "output directory")->required();
  sub->add_option("--format", a->format, "yolo (detector dataset) | tum (RGB-D sequences)")
      ->check(CLI::IsMember({"yolo", "tum"}));
  sub->add_option("--frames-per-robot", a->frames_per_robot,
                  "views per robot evenly spread over its poses (0 = every pose)")
      ->check(NonNegative());
  sub->add_option("--first-index", a->first_index, "yolo: index of the first frame written")
      ->check(CLI::Range(0, 999999));
  sub->add_option("--min-pixels", a->min_pixels, "yolo: visible pixels needed for a label")
      ->check(Positive());
  sub->add_option("--min-labels", a->min_labels,
                  "yolo: skip views with fewer labelled objects (1 drops bare walls/floor)")
      ->check(NonNegative());
  sub->add_option("--min-in-image", a->min_in_image,
                  "yolo: share of the projected extent box inside the image needed for a label")
      ->check(InRange(0.0, 1.0));
  sub->add_option("--yaw-jitter", a->yaw_jitter, "deg (default 10 for yolo, 0 for tum)")
      ->check(InRange(0.0, 180.0));
  sub->add_option("--pitch-jitter", a->pitch_jitter, "deg (default 3 for yolo, 0 for tum)")
      ->check(InRange(0.0, 45.0));
  sub->add_option("--height-jitter", a->height_jitter, "m (default 0.05 for yolo, 0 for tum)")
      ->check(InRange(0.0, 0.45));
  sub->add_option("--frame-period", a->frame_period, "tum: seconds between time steps")
      ->check(Positive());
  sub->add_flag("--no-noise", a->no_noise, "no depth or colour noise");
  sub->add_flag("--no-walls", a->no_walls, "do not draw the rooms' walls");
  sub->add_flag("--plain-style", a->plain_style,
                "default floor/wall colours and light instead of ones drawn from the seed");
  return [a] { return Run(*a); };
}

}  // namespace moslam::cli
