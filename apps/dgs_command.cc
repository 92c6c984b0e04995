// `moslam dgs <folder | file [--robots N]>`: the distributed Gauss-Seidel solver
// (distributed/dgs_driver.h) run in-process, compared with the centralized Gauss-Newton optimum
// (from the chordal initialisation, same gauge: no alignment).
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "cli.h"
#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/io/g2o.h"
#include "moslam/io/tum.h"
#include "moslam/metrics/metrics.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"
#include "robust_flags.h"
#include "solver_flags.h"

namespace moslam::cli {
namespace {

struct DgsArgs {
  std::string input;
  int robots = 0;  // 0: the robots the keys name
  std::string order = "gs";
  SolverArgs solver;    // the stages, their stopping rule, two-level, the refinement
  G2oReadOptions read;  // --objects, --drop-indefinite-coupling
  bool json = false;
  bool robust = false;
  RobustSolveArgs robust_args;  // --separator-test, --gnc-threshold, --separator-support
  std::string out;             // folder: one g2o and one TUM file per robot
};

double Since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// JSON has no infinity: a stage that never finished a sweep reports null.
nlohmann::json Number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json Number(std::optional<double> v) { return v ? Number(*v) : nlohmann::json(nullptr); }

double StageSeconds(const DgsResult& r, DgsStage stage) {
  double s = 0.0;
  for (const DgsIterationStats& it : r.history) {
    if (it.stage == stage) s += it.seconds;
  }
  return s;
}

void WriteEstimate(const std::string& dir, const PoseGraph& graph, const Values& values,
                   const G2oReadOptions& read, bool planar) {
  if (dir.empty()) return;
  G2oWriteOptions w;
  w.scheme = read.scheme;
  w.planar = planar;
  WriteG2oFolder(dir, graph, values, w);
  WriteTumTrajectories(dir, values);
}

// The robots' robust solve against the centralized one of the same options.
struct RobustComparison {
  long robust_factors = 0;
  int disagree = 0;                                   // factors whose verdicts differ
  nlohmann::json rejected = nlohmann::json::array();  // the robots' rejects, as key pairs
  double cost = 0.0, central_cost = 0.0;              // of the factors each solve kept
  TrajectoryErrors errors;                            // the robots' vs the centralized
};

RobustComparison CompareRobust(const PoseGraph& graph, const std::vector<bool>& robust,
                               const RobustDgsResult& r, const GncResult& central) {
  // The cost of the factors each solve kept (weight >= 0.5).
  auto keptCost = [&](const Values& values, const std::vector<double>& weights) {
    const std::vector<double> r2 = SquaredResiduals(graph, values);
    double c = 0.0;
    for (std::size_t i = 0; i < r2.size(); ++i) c += weights[i] >= 0.5 ? 0.5 * r2[i] : 0.0;
    return c;
  };
  RobustComparison out;
  out.robust_factors = static_cast<long>(std::count(robust.begin(), robust.end(), true));
  for (std::size_t i = 0; i < r.weights.size(); ++i) {
    out.disagree += (r.weights[i] < 0.5) != (central.weights[i] < 0.5) ? 1 : 0;
    if (r.weights[i] < 0.5) {
      out.rejected.push_back({ToString(graph.factors()[i].a()), ToString(graph.factors()[i].b())});
    }
  }
  out.cost = keptCost(r.values, r.weights);
  out.central_cost = keptCost(central.values, central.weights);
  out.errors = CompareEstimates(r.values, central.values);
  return out;
}

nlohmann::json RobustDgsJson(const DgsArgs& a, const PoseGraph& graph,
                             const RobustDgsOptions& options, const RobustDgsResult& r,
                             const GncResult& central, const RobustComparison& c,
                             double total_seconds) {
  nlohmann::json j = {
      {"input", a.input},
      {"robust", true},
      {"variables", graph.keys().size()},
      {"factors", graph.factors().size()},
      {"robust_factors", c.robust_factors},
      {"gnc_threshold", options.gnc.threshold2()},
      {"status", ToString(r.status)},
      {"rounds", r.iterations},
      {"outliers", r.outliers},
      {"polished", r.polished},
      {"polish_refused", r.polish_refused},
      {"rejected", c.rejected},
      {"centralized_status", ToString(central.status)},
      {"centralized_rounds", central.iterations},
      {"centralized_outliers", central.outliers},
      {"weights_disagreeing", c.disagree},
      {"kept_cost", c.cost},
      {"centralized_kept_cost", c.central_cost},
      {"ate_poses", c.errors.poses.ate},
      {"are_poses_deg", c.errors.poses.are_deg},
      {"bytes", r.bytes()},
      {"bytes_solves", r.solve_bytes},
      {"bytes_weights", r.weight_bytes},
      {"weight_messages", r.weight_messages},
      {"bytes_control", r.control_bytes},
      {"bytes_consistency", r.consistency_bytes},
      {"consistency_rejected", r.consistency_rejected},
      {"retests", r.retests},
      {"retest_readmitted", r.retest_readmitted},
      {"group_retests", r.group_retests},
      {"group_readmitted", r.group_readmitted},
      {"consistency_deferred", r.consistency_deferred},
      {"sweeps", r.sweeps},
      {"seconds", r.seconds},
      {"total_seconds", total_seconds},
  };
  nlohmann::json rounds = nlohmann::json::array();
  for (const RobustDgsRound& k : r.rounds) {
    rounds.push_back({{"round", k.round},
                      {"mu", k.mu},
                      {"undecided", k.undecided},
                      {"outliers", k.outliers},
                      {"bytes", k.solve_bytes},
                      {"cost", k.cost}});
  }
  j["round_history"] = rounds;
  return j;
}

void PrintRobustDgs(const DgsArgs& a, const PoseGraph& graph, const RobustDgsOptions& options,
                    const RobustDgsResult& r, const GncResult& central, const RobustComparison& c) {
  fmt::print("{}: {} variables, {} factors ({} robust), GNC-TLS threshold {:g}\n", a.input,
             graph.keys().size(), graph.factors().size(), c.robust_factors,
             options.gnc.threshold2());
  fmt::print(
      "centralized GNC: {} after {} round(s); {} rejected in all (the separator check's and "
      "GNC's), cost of the kept factors {:.10g}\n",
      ToString(central.status), central.iterations, central.outliers, c.central_cost);
  const std::optional<double> ratio = CostRatio(c.cost, c.central_cost);
  fmt::print(
      "robots' GNC:     {} after {} round(s); {} rejected in all ({} weight(s) differ from "
      "the centralized), cost of the kept factors {:.10g} ({})\n",
      ToString(r.status), r.iterations, r.outliers, c.disagree, c.cost,
      ratio ? fmt::format("{:.3e} relative", *ratio - 1.0) : "the centralized's at rounding level");
  fmt::print("vs centralized GNC (no alignment): ATE* {:.3e} m, ARE* {:.3e} deg over {} poses\n",
             c.errors.poses.ate, c.errors.poses.are_deg, c.errors.poses.count);
  fmt::print(
      "separator check: {} rejected before GNC, {} left to it (too few to confirm "
      "themselves, their robots linked otherwise)\n",
      r.consistency_rejected, r.consistency_deferred);
  if (options.retest_left_out && options.check_separators) {
    fmt::print(
        "re-tested against the joint estimate: {} left-out separator(s), {} back; "
        "{} robot pair group(s), {} separator(s) back\n",
        r.retests, r.retest_readmitted, r.group_retests, r.group_readmitted);
  }
  fmt::print(
      "traffic: {} bytes (solves {}, weights {} in {} messages, control {}, separator "
      "check {}); {} sweeps; {:.3f} s\n",
      r.bytes(), r.solve_bytes, r.weight_bytes, r.weight_messages, r.control_bytes,
      r.consistency_bytes, r.sweeps, r.seconds);
}

// --robust: GNC-TLS by the robots (distributed/robust_dgs.h) beside the centralized GNC.
int RunRobustDgsCommand(const DgsArgs& a, const PoseGraph& graph, const Values& initial,
                        const std::vector<bool>& robust, bool planar, const DgsOptions& dgs,
                        std::chrono::steady_clock::time_point t_start) {
  RobustDgsOptions options;
  options.dgs = dgs;
  a.robust_args.applyTo(&options);
  options.validate();
  const Key anchor = GaugeAnchor(graph);
  const auto anchor_it = initial.find(anchor);
  const SE3 anchor_pose = anchor_it != initial.end() ? anchor_it->second : SE3();
  const GncResult central = SolveRobustCentralized(
      graph, [&](const PoseGraph& g) { return ChordalInitialization(g, anchor_pose); }, robust,
      options);
  const RobustDgsResult r = RunRobustDgs(graph, initial, robust, options);
  WriteEstimate(a.out, graph, r.values, a.read, planar);
  const RobustComparison c = CompareRobust(graph, robust, r, central);
  const double total_seconds = Since(t_start);
  if (a.json) {
    fmt::print("{}\n", RobustDgsJson(a, graph, options, r, central, c, total_seconds).dump());
  } else {
    PrintRobustDgs(a, graph, options, r, central, c);
  }
  return 0;
}

// The graph `moslam dgs` solves: the file or folder read, a single-robot file split with --robots.
struct DgsInput {
  Dataset data;  // as read (planar, repaired information)
  PoseGraph graph;
  Values initial;
  // The factors --robust makes robust: DefaultRobustFactors of the graph read, for a split file
  // its loop closures, in a block (each robot checks its own through its odometry) or between two
  // (separators, which the separator check tests); the odometry stays least squares, from one
  // block to the next too.
  std::vector<bool> robust;
};

DgsInput ReadDgsInput(const DgsArgs& a) {
  DgsInput in;
  in.data = ReadG2o(a.input, a.read);
  in.graph = in.data.graph;
  in.initial = in.data.initial;
  in.robust = DefaultRobustFactors(in.graph);  // the same factors in the same order once split
  if (a.robots == 0) return in;
  if (std::filesystem::is_directory(a.input)) {
    throw InvalidInputError("--robots " + std::to_string(a.robots) +
                            " splits a single-robot file; the folder " + a.input +
                            " is already split by robot (drop --robots)");
  }
  if (in.graph.numRobots() > 1) {
    throw InvalidInputError("--robots " + std::to_string(a.robots) +
                            " splits a single-robot file; " + a.input + " already has " +
                            std::to_string(in.graph.numRobots()) + " robots (drop --robots)");
  }
  SplitGraph split = SplitIntoRobots(in.graph, in.initial, a.robots);
  in.graph = std::move(split.graph);
  in.initial = std::move(split.initial);
  return in;
}

// The text progress: a line per sweep (bytes so far) and per refinement step.
DgsProgress PrintedProgress() {
  DgsProgress progress;
  progress.on_sweep = [bytes_so_far = std::int64_t{0}](const DgsIterationStats& s) mutable {
    bytes_so_far += s.bytes;
    std::string extra;
    if (s.stage == DgsStage::kRefine) {
      extra = s.residual > 0.0
                  ? fmt::format("  step {:3d}  cg residual {:.3e}", s.refine_step, s.residual)
                  : fmt::format("  step {:3d}", s.refine_step);
    } else if (s.residual > 0.0) {  // the pose stage by conjugate gradients
      extra = fmt::format("  cg residual {:.3e}", s.residual);
    }
    fmt::print("{:<8} iteration {:5d}  max change {:.3e}  bytes {}{}\n", ToString(s.stage),
               s.iteration, s.max_change, bytes_so_far, extra);
  };
  progress.on_refine_step = [](const RefineStepSummary& s) {
    // The gain ratio: the decrease of F over the model's (conjugate gradients only), of the
    // whole step; a halved one says how often it was halved instead.
    std::string gain;
    if (s.backtracks > 0) {
      gain = fmt::format(", step halved {} times", s.backtracks);
    } else if (s.predicted_decrease > 0.0) {
      gain = fmt::format(", gain ratio {:.3g}",
                         (s.cost_before - s.cost_candidate) / s.predicted_decrease);
    }
    fmt::print("refine   step {:3d}: {} sweeps{}, lambda {:g}, cost {:.10g} -> {:.10g}{} ({})\n",
               s.iteration, s.sweeps, s.linear_converged ? "" : " (max sweeps)", s.lambda,
               s.cost_before, s.cost_candidate, gain, s.accepted ? "accepted" : "rejected");
  };
  return progress;
}

// What one solve measured, against the centralized references.
struct DgsRun {
  int robots = 0;
  DgsResult result;
  OptimizerResult central;  // Gauss-Newton from chordal, in the solve's gauge
  double central_seconds = 0.0;
  double two_stage_cost = 0.0, final_cost = 0.0, central_two_stage_cost = 0.0;
  TrajectoryErrors errors, two_stage_errors;  // against central
  TrajectoryErrors to_fixed_point;  // the two stages against their fixed point solved centrally
  int iterations_total = 0;
  double total_seconds = 0.0;
};

nlohmann::json DgsJson(const DgsArgs& a, const DgsOptions& options, const DgsInput& in,
                       const DgsRun& run) {
  const DgsResult& r = run.result;
  const OptimizerResult& central = run.central;
  const int iterations_refine = r.refine.sweeps;
  nlohmann::json j = {
      {"input", a.input},
      {"robots", run.robots},
      {"variables", in.graph.keys().size()},
      {"factors", in.graph.factors().size()},
      {"repaired_information", in.data.repaired_information},
      {"eta_rotation", a.solver.eta_rotation},
      {"eta_pose", a.solver.eta_pose},
      {"gamma", a.solver.gamma},
      {"order", a.order},
      {"flagged_initialisation", !a.solver.no_flagged},
      {"weighted", a.solver.weighted},
      {"coarse", options.coarse_correction},
      {"coarse_corrections", r.rotation.coarse_corrections + r.pose.coarse_corrections},
      {"refine", a.solver.refine},
      {"two_stage_cost", run.two_stage_cost},
      {"final_cost", run.final_cost},
      {"centralized_cost", central.final_cost},
      {"centralized_init", "chordal"},
      {"centralized_iterations", central.iterations},
      {"centralized_termination", ToString(central.termination)},
      {"centralized_seconds", run.central_seconds},
      {"two_stage_cost_ratio", Number(CostRatio(run.two_stage_cost, central.final_cost))},
      {"final_cost_ratio", Number(CostRatio(run.final_cost, central.final_cost))},
      {"iterations_rotation", r.rotation.iterations},
      {"iterations_pose", r.pose.iterations},
      {"iterations_refine", iterations_refine},
      {"iterations_total", run.iterations_total},
      {"termination_rotation", ToString(r.rotation.status)},
      {"termination_pose", ToString(r.pose.status)},
      {"termination_refine", ToString(r.refine.status)},
      {"final_change_rotation", Number(r.rotation.final_change)},
      {"final_change_pose", Number(r.pose.final_change)},
      {"ate_poses", run.errors.poses.ate},
      {"are_poses_deg", run.errors.poses.are_deg},
      {"two_stage_ate_poses", run.two_stage_errors.poses.ate},
      {"two_stage_are_poses_deg", run.two_stage_errors.poses.are_deg},
      {"stopping", a.solver.stopping},
      {"final_error_bound_rotation", Number(r.rotation.final_error_bound)},
      {"final_error_bound_pose", Number(r.pose.final_error_bound)},
      {"centralized_two_stage_cost", run.central_two_stage_cost},
      {"fixed_point_ate_poses", run.to_fixed_point.poses.ate},
      {"fixed_point_are_poses_deg", run.to_fixed_point.poses.are_deg},
      {"messages", r.messages},
      {"bytes", r.bytes},
      {"messages_rotation", r.rotation.messages},
      {"bytes_rotation", r.rotation.bytes},
      {"messages_pose", r.pose.messages},
      {"bytes_pose", r.pose.bytes},
      {"messages_refine", r.refine.messages},
      {"bytes_refine", r.refine.bytes},
      {"seconds", r.seconds},
      {"seconds_rotation", StageSeconds(r, DgsStage::kRotation)},
      {"seconds_pose", StageSeconds(r, DgsStage::kPose)},
      {"seconds_refine", r.refine.seconds},
      {"seconds_per_iteration", run.iterations_total > 0 ? r.seconds / run.iterations_total : 0.0},
      {"total_seconds", run.total_seconds},
  };
  if (a.solver.refine) {
    // Per Gauss-Newton step: the accepted cost and the bytes so far (two stages included), the
    // step's own numbers (damping, linear solve, the cost it led to, the model's decrease), and
    // the bytes when the estimate first came within 1e-6 relative of the centralized optimum.
    const std::int64_t two_stage_bytes = r.rotation.bytes + r.pose.bytes;
    const double within = central.final_cost * (1.0 + 1e-6);
    nlohmann::json history = nlohmann::json::array();
    nlohmann::json bytes_to_optimum =
        run.two_stage_cost <= within ? nlohmann::json(two_stage_bytes) : nlohmann::json(nullptr);
    double cost = r.refine.initial_cost;
    for (const RefineStepSummary& step : r.refine.steps) {
      if (step.accepted) cost = step.cost_candidate;
      history.push_back({{"step", step.iteration},
                         {"sweeps", step.sweeps},
                         {"linear_converged", step.linear_converged},
                         {"lambda", step.lambda},
                         {"accepted", step.accepted},
                         {"cost_candidate", step.cost_candidate},
                         {"predicted_decrease", step.predicted_decrease},
                         {"backtracks", step.backtracks},
                         {"step_scale", step.step_scale},
                         {"cost", cost},
                         {"bytes", two_stage_bytes + step.bytes}});
      if (bytes_to_optimum.is_null() && cost <= within) {
        bytes_to_optimum = two_stage_bytes + step.bytes;
      }
    }
    j["refine_history"] = history;
    j["bytes_to_optimum_1e-6"] = bytes_to_optimum;
    j["refine_preconditioner"] = ToString(options.refinement.preconditioner);
    j["refine_coarse_corrections"] = r.refine.coarse_corrections;
    j["refine_solver"] = ToString(options.refinement.solver);
    j["refine_steps"] = r.refine.iterations;
    j["refine_rejected_steps"] = r.refine.rejected;
    j["refine_backtracks"] = r.refine.backtracks;
    j["refine_initial_cost"] = r.refine.initial_cost;  // as the robots' shares sum it
    j["control_messages_refine"] = r.refine.control_messages;
    j["control_bytes_refine"] = r.refine.control_bytes;
  }
  if (run.errors.objects.count > 0) {
    j["ate_objects"] = run.errors.objects.ate;
    j["are_objects_deg"] = run.errors.objects.are_deg;
    j["objects"] = run.errors.objects.count;
  }
  return j;
}

// What to try when the refinement stopped at its step limit after rejected steps, or when half
// or more of its linear solves stopped at the sweep cap with one rigid motion per robot as the
// coarse space; else empty.
std::string RefineHint(const RefineReport& refine, const DgsOptions& options) {
  std::string hint;
  if (refine.status == StageStatus::kMaxIterations && refine.rejected > 0) {
    hint = fmt::format(
        "refine: stopped at its step limit (--refine-max-iter) with {} of {} steps rejected. On "
        "long 2D chains, where the damped steps crawl, a tighter linear solve avoids them "
        "(--refine-linear-tol 1e-3), and so may more halvings of a step before it is rejected "
        "(--refine-backtracks; README, \"The 2D benchmark graphs\")",
        refine.rejected, refine.iterations);
  }
  const DgsOptions::Refinement& o = options.refinement;
  int capped = 0;
  for (const RefineStepSummary& s : refine.steps) capped += s.linear_converged ? 0 : 1;
  if (o.solver == RefineSolver::kConjugateGradient &&
      o.preconditioner == RefinePreconditioner::kTwoLevel && o.coarse_piece_poses == 0 &&
      !refine.steps.empty() && 2 * capped >= static_cast<int>(refine.steps.size())) {
    hint += fmt::format(
        "{}refine: {} of {} linear solves stopped at the sweep cap (--refine-max-sweeps). On long "
        "chains a coarse space of pieces instead of whole robots converges in far fewer sweeps "
        "(--refine-coarse-piece-poses 30; README, \"The refinement's coarse space by "
        "pieces\")",
        hint.empty() ? "" : "\n", capped, refine.steps.size());
  }
  return hint;
}

void PrintDgsSummary(const DgsArgs& a, const DgsOptions& options, const DgsRun& run) {
  const DgsResult& r = run.result;
  const double central_cost = run.central.final_cost;
  fmt::print("rotation: {} after {} sweep(s); pose: {} after {} sweep(s)",
             ToString(r.rotation.status), r.rotation.iterations, ToString(r.pose.status),
             r.pose.iterations);
  if (a.solver.refine) {
    fmt::print("; refine: {} after {} step(s) ({} rejected, {} halving(s)), {} sweep(s)",
               ToString(r.refine.status), r.refine.iterations, r.refine.rejected,
               r.refine.backtracks, r.refine.sweeps);
  }
  fmt::print("\n");
  if (CostRatio(0.0, central_cost)) {
    fmt::print(
        "cost: two-stage {:.10g} ({:.6f} x centralized), final {:.10g} ({:.6f} x), "
        "centralized GN {:.10g}\n",
        run.two_stage_cost, run.two_stage_cost / central_cost, run.final_cost,
        run.final_cost / central_cost, central_cost);
  } else {  // the measurements agree exactly: no ratio
    fmt::print("cost: two-stage {:.10g}, final {:.10g}, centralized GN {:.10g}\n",
               run.two_stage_cost, run.final_cost, central_cost);
  }
  fmt::print("vs centralized GN (no alignment): ATE* {:.3e} m, ARE* {:.3e} deg over {} poses",
             run.errors.poses.ate, run.errors.poses.are_deg, run.errors.poses.count);
  if (run.errors.objects.count > 0) {
    fmt::print("; objects ATE* {:.3e} m, ARE* {:.3e} deg over {}", run.errors.objects.ate,
               run.errors.objects.are_deg, run.errors.objects.count);
  }
  fmt::print("\ntraffic: {} messages, {} bytes; {:.3f} s ({:.3g} ms per sweep)\n", r.messages,
             r.bytes, r.seconds,
             run.iterations_total > 0 ? 1e3 * r.seconds / run.iterations_total : 0.0);
  if (a.solver.refine) {
    const std::string hint = RefineHint(r.refine, options);
    if (!hint.empty()) fmt::print("{}\n", hint);
  }
}

int RunDgsCommand(const DgsArgs& a_in) {
  DgsArgs a = a_in;
  if (a.robust) a.solver.refine = true;  // every robust round solves to the optimum
  const auto t_start = std::chrono::steady_clock::now();
  const DgsInput in = ReadDgsInput(a);
  const PoseGraph& graph = in.graph;
  const DgsOptions options =
      a.solver.options(a.order == "jacobi" ? SweepOrder::kJacobi : SweepOrder::kGaussSeidel);
  if (a.robust) {
    return RunRobustDgsCommand(a, graph, in.initial, in.robust, in.data.planar, options, t_start);
  }

  // The reference: centralized Gauss-Newton from the chordal initialisation, in the same gauge
  // (the anchor at its initial value, as the distributed solve holds it).
  DgsRun run;
  const auto t_central = std::chrono::steady_clock::now();
  const Key anchor = GaugeAnchor(graph);
  const auto anchor_it = in.initial.find(anchor);
  const SE3 anchor_pose = anchor_it != in.initial.end() ? anchor_it->second : SE3();
  run.central = Optimize(graph, ChordalInitialization(graph, anchor_pose));
  run.central_seconds = Since(t_central);

  DgsDriver driver(graph, in.initial, options);
  run.robots = driver.numAgents();
  if (!a.json) {
    fmt::print(
        "{}: {} variables, {} factors, {} robots (order {}); centralized GN {} after {} "
        "iteration(s): cost {:.10g} ({:.3f} s)\n",
        a.input, graph.keys().size(), graph.factors().size(), run.robots, ToString(options.order),
        ToString(run.central.termination), run.central.iterations, run.central.final_cost,
        run.central_seconds);
    if (in.data.repaired_information > 0) {
      fmt::print("note: {} information matrices read without their indefinite coupling\n",
                 in.data.repaired_information);
    }
    driver.setProgress(PrintedProgress());
  }
  driver.runRotationStage();
  driver.runPoseStage();
  const Values two_stage = driver.result().values;
  // The fixed point of the two stages, solved centrally: what DGS converges to (DGS.md).
  TwoStageOptions two_stage_options;
  two_stage_options.weight_by_information = a.solver.weighted;
  const Values central_two_stage = CentralizedTwoStage(graph, in.initial, two_stage_options).values;
  run.to_fixed_point = CompareEstimates(two_stage, central_two_stage);
  run.two_stage_cost = graph.cost(two_stage);
  if (a.solver.refine) driver.runRefineStage();
  run.result = driver.result();
  const DgsResult& r = run.result;
  WriteEstimate(a.out, graph, r.values, a.read, in.data.planar);
  run.final_cost = graph.cost(r.values);
  run.errors = CompareEstimates(r.values, run.central.values);
  run.two_stage_errors = CompareEstimates(two_stage, run.central.values);
  run.iterations_total = r.rotation.iterations + r.pose.iterations + r.refine.sweeps;
  run.central_two_stage_cost = graph.cost(central_two_stage);
  run.total_seconds = Since(t_start);

  if (a.json) {
    fmt::print("{}\n", DgsJson(a, options, in, run).dump());
  } else {
    PrintDgsSummary(a, options, run);
  }
  return 0;
}

}  // namespace

Runner RegisterDgs(CLI::App& app) {
  auto args = std::make_shared<DgsArgs>();
  CLI::App* sub = app.add_subcommand(
      "dgs",
      "Distributed Gauss-Seidel (two-stage DGS, optional distributed refinement) over the robots "
      "of a folder (0.g2o .. N-1.g2o) or of a file split into --robots N blocks");
  sub->add_option("input", args->input, "g2o file or distributed-mapper folder")->required();
  sub->add_option("--robots", args->robots,
                  "split a single-robot file into N robots of contiguous pose blocks")
      ->check(CLI::Range(1, kMaxMessageRobot + 1));
  sub->add_option("--order", args->order, "gs (Gauss-Seidel) or jacobi")
      ->check(CLI::IsMember({"gs", "jacobi"}))
      ->capture_default_str();
  AddSolverFlags(sub, &args->solver);
  AddG2oReadFlags(sub, &args->read);
  sub->add_flag("--robust", args->robust,
                "outlier-robust: graduated non-convexity with a truncated least-squares cost on "
                "the inter-robot factors (one robot's file: its loop closures, each robot "
                "checking its own through its odometry), run by the robots (implies --refine)");
  AddRobustSolveFlags(sub, &args->robust_args);
  sub->add_option("--out", args->out,
                  "write the distributed estimate into this folder: 0.g2o .. N-1.g2o (each "
                  "robot's vertices and edges) and robot_<r>.tum");
  sub->add_flag("--json", args->json, "print one JSON object as the last line (no progress)");
  return [args] { return RunDgsCommand(*args); };
}

}  // namespace moslam::cli
