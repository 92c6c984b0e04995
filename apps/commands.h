// Subcommands of the `moslam` tool. Each registers its options on the app and runs when chosen;
// a run returns the process exit code (0 success, 1 bad input or failed solve).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <functional>
#include <string>

#include "cli.h"
#include "moslam/experiments/simulation_experiment.h"
#include "moslam/io/g2o.h"

namespace moslam::cli {

// One-line descriptions of the commands that run in another executable than `moslam` (cli.h):
// the same text in `moslam --help` and in their own.
inline constexpr const char* kRobotDescription =
    "One robot as a process: its g2o file (--data) or its part of a simulated scenario "
    "(--scenario: object SLAM and rendezvous), DGS with the others over Cyclone DDS";
inline constexpr const char* kTeamDescription =
    "Start one `moslam robot` process per robot on loopback and collect the results";
inline constexpr const char* kRenderDescription =
    "Rendered RGB-D frames of a scenario: YOLO detector dataset or TUM sequences";
inline constexpr const char* kDetectDescription =
    "Run the object detector on an image, or evaluate it on a YOLO-layout dataset";
inline constexpr const char* kPerceiveDescription =
    "The perception front-end on a TUM RGB-D layout sequence: detections and object poses (JSON)";

// simulate, robot and team refuse --rendezvous-constellation with --initial-poses unknown.
inline constexpr const char* kConstellationNeedsKnownPoses =
    "--rendezvous-constellation refines the transform of known initial poses; with "
    "--initial-poses unknown every rendezvous aligns the two object maps by their constellation "
    "already";

// The g2o reading flags of every subcommand that reads g2o input: --objects and
// --drop-indefinite-coupling, written into `options` (which must outlive the parse).
inline void AddG2oReadFlags(CLI::App* sub, G2oReadOptions* options) {
  sub->add_flag_callback(
      "--objects", [options] { options->scheme = KeyScheme::kWithObjects; },
      "upper-case Symbol keys are objects of robots 0-25 (not poses of robots 26-51)");
  sub->add_flag("--drop-indefinite-coupling", options->drop_indefinite_coupling,
                "read information matrices that only their rotation-translation coupling makes "
                "indefinite (cubicle.g2o) without that coupling; the count is reported");
}

// `moslam solve <file.g2o | folder>`: centralized Gauss-Newton / LM.
Runner RegisterSolve(CLI::App& app);

// `moslam dgs <folder | file --robots N>`: distributed Gauss-Seidel (two stages, optional
// distributed refinement), compared with centralized Gauss-Newton.
Runner RegisterDgs(CLI::App& app);

// `moslam spoil <folder> --fraction P --seed S --out DIR`: wrong separators added (robust/spoil.h).
Runner RegisterSpoil(CLI::App& app);

// `moslam robot --robot R --data <folder> | --scenario <name>`: one robot process (a simulated
// robot: object SLAM and rendezvous first), DGS over Cyclone DDS.
Runner RegisterRobot(CLI::App& app);
// `moslam team --data <folder> | --scenario <name> --robots N`: N robot processes on loopback,
// results collected and compared with the in-process run.
Runner RegisterTeam(CLI::App& app);
// The options of `simulate --perception rendered`, and what turns them into the experiments'
// perception hook (ExperimentConfig::perceive). `moslam` passes one that hands the whole command
// to the perception executable (it never returns); `moslam-perception` one that runs the
// front-end.
struct RenderedPerceptionArgs {
  std::string model, classes, templates;
  int every = 1;
  std::string template_cache;  // "" = none
  int template_views = 8;  // TemplateViews::views (perception/view_template.h); 0: whole model
  bool depth_smoothing = true;  // DepthSmoothingConfig::enabled (pose_estimation/depth_smoothing.h)
  std::string detection_log;    // JSON lines, one per detection ("" = none; --detection-log)
  std::string perception_cache;  // folder of perceived runs ("" = none; --perception-cache)
  // --perception visible: the ideal front-end (render/visible_sensing.h) instead of this one; the
  // options above but `every` do not apply.
  bool visible = false;
  double visible_sigma_rotation_deg = 5.0, visible_sigma_translation = 0.2;  // --visible-noise
  double visible_keep = 1.0;                                                  // --visible-keep
};

// Where built templates are cached unless --template-cache says otherwise:
// $XDG_CACHE_HOME/moslam/templates, else $HOME/.cache/moslam/templates, else none ("").
inline std::string DefaultTemplateCacheDir() {
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) {
    return std::string(x) + "/moslam/templates";
  }
  if (const char* h = std::getenv("HOME"); h && *h) {
    return std::string(h) + "/.cache/moslam/templates";
  }
  return "";
}
// --template-cache: "none" disables the cache.
inline std::string TemplateCacheDir(const std::string& option) {
  return option == "none" ? std::string() : option;
}
using MakePerception = std::function<ExperimentConfig::Perceive(const RenderedPerceptionArgs&)>;

// `moslam simulate --scenario chairs25 --robots 6`: simulated experiments (paper Tables 1-3).
Runner RegisterSimulate(CLI::App& app, MakePerception make_perception);
// `moslam-perception`: the front-end on rendered frames as the experiments' perception hook.
ExperimentConfig::Perceive MakeRenderedPerception(const RenderedPerceptionArgs& args);
// `moslam render --scenario chairs25 --out DIR --format yolo|tum`: rendered RGB-D frames.
Runner RegisterRender(CLI::App& app);
// `moslam detect [--model M] (--image F | --data DIR)`: the object detector (src/moslam/detection)
// on one image, or evaluated on a YOLO-layout dataset.
Runner RegisterDetect(CLI::App& app);
// `moslam perceive <sequence dir>`: the front-end on a TUM RGB-D layout sequence.
Runner RegisterPerceive(CLI::App& app);

}  // namespace moslam::cli
