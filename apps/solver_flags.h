// The solver flags `moslam dgs`, `moslam robot` and `moslam team` share (the stages, their
// stopping rule, the two-level correction, the refinement), what they set in DgsOptions, and
// the same flags again as arguments (`moslam team` passes its own to every robot process).
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "moslam/distributed/dgs_driver.h"

namespace moslam::cli {

struct SolverArgs {
  double eta_rotation = 1e-2;
  double eta_pose = 1e-2;
  std::string stopping = "change";
  int stop_window = 10;
  double gamma = 1.0;
  int max_iterations = 1000;
  bool no_flagged = false;
  bool weighted = false;
  std::string stages = "auto";       // auto: two-level with --refine, one-level without
  bool refine = false;
  std::string pose_solver = "auto";  // auto: cg with --refine, sweeps (DGS.md) without
  std::string refine_solver = "cg";
  std::string refine_preconditioner = "two-level";
  int refine_max_iterations = 100;
  double refine_tolerance = 1e-10;
  int refine_max_sweeps = 1000;
  std::optional<double> refine_linear_tolerance;  // unset: the solver's default
  double refine_gamma = 1.0;
  int refine_max_backtracks = 4;
  std::uint64_t refine_coarse_piece_poses = 0;  // 0: one rigid motion per robot

  // The options these flags give (`order` as given); validated (InvalidInputError).
  DgsOptions options(SweepOrder order) const;
  // The flags that reproduce these arguments.
  std::vector<std::string> args() const;
};

// Adds the flags to `sub`, written into `args` (which must outlive the parse).
void AddSolverFlags(CLI::App* sub, SolverArgs* args);

}  // namespace moslam::cli
