// Subcommands of the `moslam` tool. Each registers its options on the app and runs when chosen;
// a run returns the process exit code (0 success, 1 bad input or failed solve).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

#include "moslam/io/g2o.h"

namespace moslam::cli {

using Runner = std::function<int()>;

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

// `moslam robot --robot R --data <folder> | --scenario <name>`: one robot process (a simulated
// robot: object SLAM and rendezvous first), DGS over Cyclone DDS.
Runner RegisterRobot(CLI::App& app);
// `moslam team --data <folder> | --scenario <name> --robots N`: N robot processes on loopback,
// results collected and compared with the in-process run.
Runner RegisterTeam(CLI::App& app);
// `moslam simulate --scenario chairs25 --robots 6`: simulated experiments (paper Tables 1-3).
Runner RegisterSimulate(CLI::App& app);
// `moslam render --scenario chairs25 --out DIR --format yolo|tum`: rendered RGB-D frames.
Runner RegisterRender(CLI::App& app);
// `moslam detect --model M (--image F | --data DIR)`: the object detector (src/moslam/detection)
// on one image, or evaluated on a YOLO-layout dataset.
Runner RegisterDetect(CLI::App& app);
// `moslam perceive <sequence dir>`: the front-end on a TUM RGB-D layout sequence.
Runner RegisterPerceive(CLI::App& app);

}  // namespace moslam::cli
