#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/io/g2o.h"
#include "moslam/io/tum.h"
#include "moslam/robust/gnc.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"
#include "robust_flags.h"

namespace moslam::cli {
namespace {

struct SolveArgs {
  std::string input;
  std::string init = "chordal";
  std::string method = "lm";
  int max_iterations = 100;
  double relative_tolerance = 1e-10;
  G2oReadOptions read;  // --objects, --drop-indefinite-coupling
  std::string out;
  std::string tum_dir;
  bool json = false;
  bool verbose = false;
  bool robust = false;
  RobustSolveArgs robust_args;  // --separator-test, --gnc-threshold, --separator-support
};

double Since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

Values InitialEstimate(const Dataset& data, const std::string& how) {
  const Key anchor = GaugeAnchor(data.graph);
  const auto it = data.initial.find(anchor);
  const SE3 anchor_pose = it != data.initial.end() ? it->second : SE3();
  if (how == "chordal") return ChordalInitialization(data.graph, anchor_pose);
  if (how == "odometry") return OdometryInitialization(data.graph, anchor_pose);
  // "file": every variable needs a vertex.
  for (const Key& k : data.graph.keys()) {
    if (!data.initial.count(k)) {
      throw InvalidInputError("--init file: the input has no vertex for " + ToString(k) +
                              " (edge-only file? use --init chordal or --init odometry)");
    }
  }
  return data.initial;
}

// The robust solve (`--robust`): the separator check and GNC of `moslam dgs --robust`, in one
// process, as an OptimizerResult beside GNC's own report.
OptimizerResult SolveRobust(const SolveArgs& a, const Dataset& data, const Values& initial,
                            const std::vector<bool>& robust_mask, const OptimizerOptions& options,
                            GncResult& gnc, SeparatorConsistencyResult& check) {
  RobustDgsOptions robust_options;  // the same check and GNC as `moslam dgs --robust`
  a.robust_args.applyTo(&robust_options);
  // The initialisation of the factors the separator check keeps (--init file: the file's).
  auto initialize = [&](const PoseGraph& kept) {
    if (a.init == "file") return initial;
    Dataset d;
    d.graph = kept;
    d.initial = data.initial;
    return InitialEstimate(d, a.init);
  };
  gnc =
      SolveRobustCentralized(data.graph, initialize, robust_mask, robust_options, options, &check);
  OptimizerResult result;
  result.values = gnc.values;
  result.termination = TerminationStatus::kConverged;
  result.initial_cost = data.graph.cost(initial);
  result.final_cost = data.graph.cost(gnc.values);
  result.iterations = gnc.iterations;
  result.seconds = gnc.seconds;
  return result;
}

// `--out` (one g2o file, or a folder of one per robot) and `--tum`.
void WriteEstimate(const SolveArgs& a, const Dataset& data, const Values& values) {
  if (!a.out.empty()) {
    G2oWriteOptions w;
    w.scheme = a.read.scheme;
    w.plain_keys = data.plain_keys;
    w.planar = data.planar;
    if (std::filesystem::is_directory(a.out) || a.out.back() == '/') {
      WriteG2oFolder(a.out, data.graph, values, w);
    } else {
      const auto parent = std::filesystem::path(a.out).parent_path();
      if (!parent.empty()) CreateFolder(parent, "solve --out");
      WriteG2oFile(a.out, data.graph, values, w);
    }
  }
  if (!a.tum_dir.empty()) WriteTumTrajectories(a.tum_dir, values);
}

struct SolveTimes {
  double load = 0.0, init = 0.0, total = 0.0;  // seconds
};

nlohmann::json SolveJson(const SolveArgs& a, const Dataset& data, const OptimizerResult& result,
                         const std::vector<bool>& robust, const GncResult& gnc,
                         const SeparatorConsistencyResult& check, const SolveTimes& times) {
  nlohmann::json j = {
      {"input", a.input},
      {"variables", data.graph.keys().size()},
      {"factors", data.graph.factors().size()},
      {"robots", data.graph.numRobots()},
      {"repaired_information", data.repaired_information},
      {"init", a.init},
      {"method", a.method},
      {"initial_cost", result.initial_cost},
      {"final_cost", result.final_cost},
      {"iterations", result.iterations},
      {"termination", ToString(result.termination)},
      {"seconds", result.seconds},
      {"init_seconds", times.init},
      {"load_seconds", times.load},
      {"linearize_seconds", result.linearize_seconds},
      {"cholesky_seconds", result.solve_seconds},
      {"total_seconds", times.total},
  };
  if (a.robust) {
    nlohmann::json r = {{"status", ToString(gnc.status)},
                        {"robust_factors", std::count(robust.begin(), robust.end(), true)},
                        {"check_checked", check.separators},  // separators, or loop closures
                        {"check_rejected", check.rejected},
                        {"rounds", gnc.iterations},
                        {"outliers", gnc.outliers},
                        {"least_squares_cost", gnc.least_squares_cost},
                        {"final_mu", gnc.final_mu}};
    nlohmann::json rejected = nlohmann::json::array();
    for (std::size_t i = 0; i < gnc.weights.size(); ++i) {
      if (gnc.weights[i] < 0.5) {
        const RelativePoseFactor& f = data.graph.factors()[i];
        rejected.push_back({ToString(f.a()), ToString(f.b())});
      }
    }
    r["rejected"] = rejected;
    j["robust"] = r;
  }
  return j;
}

int RunSolve(const SolveArgs& a) {
  const auto t_start = std::chrono::steady_clock::now();
  SolveTimes times;
  const Dataset data = ReadG2o(a.input, a.read);
  times.load = Since(t_start);

  const auto t_init = std::chrono::steady_clock::now();
  const Values initial = InitialEstimate(data, a.init);
  times.init = Since(t_init);

  OptimizerOptions options;
  options.method = a.method == "lm" ? Method::kLevenbergMarquardt : Method::kGaussNewton;
  options.max_iterations = a.max_iterations;
  options.relative_cost_tolerance = a.relative_tolerance;
  options.verbose = a.verbose;
  NonlinearOptimizer optimizer(data.graph, initial, options);
  if (!a.json) {
    fmt::print("{}: {} variables, {} factors, {} robot(s); init {} ({:.3f} s), cost {:.6f}\n",
               a.input, data.graph.keys().size(), data.graph.factors().size(),
               data.graph.numRobots(), a.init, times.init, optimizer.cost());
    if (data.repaired_information > 0) {
      fmt::print("note: {} information matrices read without their indefinite coupling\n",
                 data.repaired_information);
    }
  }
  GncResult gnc;
  SeparatorConsistencyResult check;  // --robust: the pairwise check before GNC
  const std::vector<bool> robust_mask =
      a.robust ? DefaultRobustFactors(data.graph) : std::vector<bool>{};
  const OptimizerResult result =
      a.robust ? SolveRobust(a, data, initial, robust_mask, options, gnc, check)
               : optimizer.optimize();
  times.total = Since(t_start);
  WriteEstimate(a, data, result.values);

  if (a.json) {
    fmt::print("{}\n", SolveJson(a, data, result, robust_mask, gnc, check, times).dump());
  } else if (a.robust) {
    fmt::print(
        "robust (GNC-TLS, threshold {:g}): {} after {} weighted solve(s), {} of {} robust "
        "factor(s) rejected ({} of {} checked by the pairwise check before GNC); cost of "
        "all factors {:.10g} (least squares {:.10g}) in {:.3f} s\n",
        GncOptions{a.robust_args.gnc_threshold}.threshold2(), ToString(gnc.status), gnc.iterations,
        gnc.outliers, std::count(robust_mask.begin(), robust_mask.end(), true), check.rejected,
        check.separators, result.final_cost, gnc.least_squares_cost, gnc.seconds);
  } else {
    fmt::print("{} after {} iteration(s): cost {:.6f} -> {:.10g} in {:.3f} s\n",
               ToString(result.termination), result.iterations, result.initial_cost,
               result.final_cost, result.seconds);
  }
  // Not converging within the limits is a result, not an error; a rising GN step is reported
  // but the best estimate is still written.
  return 0;
}

}  // namespace

Runner RegisterSolve(CLI::App& app) {
  auto args = std::make_shared<SolveArgs>();
  CLI::App* sub = app.add_subcommand(
      "solve", "Centralized solve of a g2o file or a multi-robot folder (0.g2o .. N-1.g2o)");
  sub->add_option("input", args->input, "g2o file or distributed-mapper folder")->required();
  sub->add_option("--init", args->init, "initial estimate")
      ->check(CLI::IsMember({"chordal", "odometry", "file"}))
      ->capture_default_str();
  sub->add_option("--method", args->method, "lm (Levenberg-Marquardt, starting almost undamped) or gn (plain Gauss-Newton)")
      ->check(CLI::IsMember({"gn", "lm"}))
      ->capture_default_str();
  sub->add_option("--max-iterations", args->max_iterations)->check(NonNegative())
      ->capture_default_str();
  sub->add_option("--rel-tol", args->relative_tolerance, "stop when the cost drops by less than this fraction")
      ->check(NonNegative())
      ->capture_default_str();
  AddG2oReadFlags(sub, &args->read);
  sub->add_option("--out", args->out, "write the estimate: a .g2o file, or a folder (ends with /)");
  sub->add_option("--tum", args->tum_dir, "write one TUM trajectory per robot into this folder");
  sub->add_flag("--json", args->json, "print one JSON object as the last line");
  sub->add_flag("-v,--verbose", args->verbose, "one line per iteration on stderr");
  sub->add_flag("--robust", args->robust,
                "the inter-robot factors checked for pairwise consistency per robot pair (single "
                "robot: its loop closures, through its odometry), then graduated non-convexity "
                "with a truncated least-squares cost on them; the rest least squares");
  AddRobustSolveFlags(sub, &args->robust_args);
  return [args] { return RunSolve(*args); };
}

}  // namespace moslam::cli
