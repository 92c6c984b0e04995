#include "solver_flags.h"

#include <fmt/core.h>

namespace moslam::cli {

DgsOptions SolverArgs::options(SweepOrder order) const {
  DgsOptions o;
  o.eta_rotation = eta_rotation;
  o.eta_pose = eta_pose;
  o.stopping = StageStoppingFromString(stopping);
  o.error_bound_window = stop_window;
  o.gamma = gamma;
  o.order = order;
  o.max_iterations = max_iterations;
  o.flagged_initialisation = !no_flagged;
  o.weight_by_information = weighted;
  o.coarse_correction = stages == "two-level" || (stages == "auto" && refine);
  o.refine = refine;
  o.pose_solver = pose_solver == "cg" || (pose_solver == "auto" && refine)
                      ? DgsOptions::PoseSolver::kConjugateGradient
                      : DgsOptions::PoseSolver::kSweeps;
  o.refinement.solver =
      refine_solver == "sweeps" ? RefineSolver::kSweeps : RefineSolver::kConjugateGradient;
  o.refinement.preconditioner = RefinePreconditionerFromString(refine_preconditioner);
  o.refinement.max_iterations = refine_max_iterations;
  o.refinement.relative_cost_tolerance = refine_tolerance;
  o.refinement.max_sweeps = refine_max_sweeps;
  if (refine_linear_tolerance) {  // validate() refuses a negative or non-finite one
    o.refinement.sweep_tolerance = *refine_linear_tolerance;
    o.refinement.cg_tolerance = *refine_linear_tolerance;
  }
  o.refinement.gamma = refine_gamma;
  o.refinement.max_backtracks = refine_max_backtracks;
  o.refinement.coarse_piece_poses = refine_coarse_piece_poses;
  o.validate();
  return o;
}

std::vector<std::string> SolverArgs::args() const {
  // {} prints the shortest text that reads back as the same double.
  // clang-format off
  std::vector<std::string> a = {
      "--eta-rot", fmt::format("{}", eta_rotation), "--eta-pose", fmt::format("{}", eta_pose),
      "--stop", stopping, "--stop-window", std::to_string(stop_window), "--gamma",
      fmt::format("{}", gamma), "--max-iter", std::to_string(max_iterations), "--stages", stages,
      "--pose-solver", pose_solver, "--refine-solver", refine_solver,
      "--refine-preconditioner", refine_preconditioner, "--refine-max-iter",
      std::to_string(refine_max_iterations), "--refine-tol", fmt::format("{}", refine_tolerance),
      "--refine-max-sweeps", std::to_string(refine_max_sweeps), "--refine-gamma",
      fmt::format("{}", refine_gamma), "--refine-backtracks",
      std::to_string(refine_max_backtracks), "--refine-coarse-piece-poses",
      std::to_string(refine_coarse_piece_poses)};
  // clang-format on
  if (refine_linear_tolerance) {
    a.push_back("--refine-linear-tol");
    a.push_back(fmt::format("{}", *refine_linear_tolerance));
  }
  if (no_flagged) a.push_back("--no-flagged");
  if (weighted) a.push_back("--weighted");
  if (refine) a.push_back("--refine");
  return a;
}

void AddSolverFlags(CLI::App* sub, SolverArgs* args) {
  // Values are checked by DgsOptions::validate(), whose messages name the field.
  sub->add_option("--eta-rot", args->eta_rotation, "stage 1 stops when every change <= this")
      ->capture_default_str();
  sub->add_option("--eta-pose", args->eta_pose, "stage 2 stops when every change <= this")
      ->capture_default_str();
  sub->add_option("--stop", args->stopping,
                  "what eta bounds: change (each robot's change per sweep, DGS.md) or "
                  "error-bound (each robot's estimated distance to the fixed point, "
                  "change * rho / (1 - rho))")
      ->check(CLI::IsMember({"change", "error-bound"}))
      ->capture_default_str();
  sub->add_option("--stop-window", args->stop_window,
                  "error-bound: rho is the largest ratio of successive changes over this many "
                  "solves")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  sub->add_option("--gamma", args->gamma, "over-relaxation of the two stages, in (0, 2)")
      ->capture_default_str();
  sub->add_option("--max-iter", args->max_iterations, "maximum sweeps per stage")
      ->capture_default_str();
  sub->add_flag("--no-flagged", args->no_flagged, "without flagged initialisation");
  sub->add_flag("--weighted", args->weighted,
                "weight the two stages by the information matrices (the reference: unit)");
  sub->add_option("--stages", args->stages,
                  "the two stages: one-level (DGS.md, the paper's), two-level (after each sweep "
                  "a coarse correction of every robot's motion as a whole), or auto: two-level "
                  "with --refine (the stages then only start the refinement), one-level without")
      ->check(CLI::IsMember({"auto", "one-level", "two-level"}))
      ->capture_default_str();
  sub->add_flag_callback(
      "--coarse", [args] { args->stages = "two-level"; }, "the same as --stages two-level");
  sub->add_flag("--refine", args->refine,
                "after the two stages, distributed Gauss-Newton on the SE(3) cost");
  sub->add_option("--refine-solver", args->refine_solver,
                  "linear steps by cg (conjugate gradients preconditioned by the sweeps) or "
                  "sweeps (plain block Gauss-Seidel / Jacobi)")
      ->check(CLI::IsMember({"cg", "sweeps"}))
      ->capture_default_str();
  sub->add_option("--pose-solver", args->pose_solver,
                  "the pose stage: sweeps (DGS.md), cg (conjugate gradients on the same system, "
                  "preconditioned as the refinement's), or auto: cg with --refine, sweeps without")
      ->check(CLI::IsMember({"auto", "sweeps", "cg"}))
      ->capture_default_str();
  sub->add_option("--refine-preconditioner", args->refine_preconditioner,
                  "preconditioner of the refinement's conjugate gradients: two-level (the "
                  "sweeps around a coarse correction over the robots' rigid motions) or sweeps")
      ->check(CLI::IsMember({"two-level", "sweeps"}))
      ->capture_default_str();
  sub->add_option("--refine-max-iter", args->refine_max_iterations,
                  "maximum Gauss-Newton steps")
      ->capture_default_str();
  sub->add_option("--refine-tol", args->refine_tolerance,
                  "stop when a step lowers the cost by at most this fraction")
      ->capture_default_str();
  sub->add_option("--refine-max-sweeps", args->refine_max_sweeps,
                  "maximum sweeps per Gauss-Newton step")
      ->capture_default_str();
  sub->add_option("--refine-linear-tol", args->refine_linear_tolerance,
                  "linear-step tolerance (cg: relative residual, default 1e-2; sweeps: change "
                  "relative to the increment, default 1e-3)");
  sub->add_option("--refine-gamma", args->refine_gamma,
                  "over-relaxation of the refinement sweeps, in (0, 2)")
      ->capture_default_str();
  sub->add_option("--refine-backtracks", args->refine_max_backtracks,
                  "halvings of a Gauss-Newton step that raised the cost before it is rejected "
                  "and damped, in [0, 30] (0: none)")
      ->capture_default_str();
  sub->add_option("--refine-coarse-piece-poses", args->refine_coarse_piece_poses,
                  "the two-level preconditioner's coarse space in refinement steps: 0, one "
                  "rigid motion per robot; L, one per run of L pose indices of a robot (long "
                  "chains: README, \"The refinement's coarse space by pieces\")")
      ->capture_default_str();
}

}  // namespace moslam::cli
