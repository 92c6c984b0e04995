// moslam_bench_solve: the centralized solver of moslam against Ceres on the 3D benchmark graphs.
//
// For every dataset: read it, compute moslam's chordal initial estimate (anchor = the first pose
// of robot 0 at its file value), then solve from exactly that estimate with
//   - moslam Gauss-Newton and Levenberg-Marquardt (solver/optimizer.h),
//   - Ceres (LM, SPARSE_NORMAL_CHOLESKY + SuiteSparse, tight tolerances) on the same cost written
//     independently (ceres_se3_cost.h), with 1 thread and, optionally, 2 threads.
// Checks: Ceres' initial cost equals moslam's PoseGraph::cost to 1e-9 relative; moslam's cost at
// Ceres' final estimate is compared with moslam's final cost. Each solver runs in a forked child
// (peak memory = the child's ru_maxrss from wait4, including what its parent held at the fork:
// each dataset is benchmarked in a fresh process holding only its graph and initial estimate);
// wall time is the median of --repeats runs.
//
// Prints a Markdown table on stdout; --json FILE writes one JSON object per dataset.
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/product_manifold.h>
#include <ceres/solver.h>
#include <fmt/format.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "ceres_pose_graph.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/io/g2o.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

const std::vector<std::string> kDefaultDatasets = {
    "sphere2500", "torus3D", "parking-garage", "cubicle", "smallGrid3D", "sphere_bignoise_vertex3"};

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double RelDiff(double a, double b) {
  const double scale = std::max(std::abs(a), std::abs(b));
  return scale > 0.0 ? (a - b) / scale : 0.0;
}

// ---------------------------------------------------------------------------------------------
// Running a job in a forked child: the child sends its JSON result through a pipe; the parent
// gets the child's peak resident set from wait4.

struct ChildOutcome {
  json result;
  double peak_mb = 0.0;
};

ChildOutcome RunInChild(const std::function<json()>& job) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  std::cout.flush();
  std::cerr.flush();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    close(fds[0]);
    std::string out;
    int code = 0;
    try {
      out = job().dump();
    } catch (const std::exception& e) {
      out = json{{"error", e.what()}}.dump();
      code = 1;
    }
    std::size_t written = 0;
    while (written < out.size()) {
      const ssize_t n = write(fds[1], out.data() + written, out.size() - written);
      if (n <= 0) {
        if (n < 0 && errno == EINTR) continue;
        _exit(3);
      }
      written += static_cast<std::size_t>(n);
    }
    close(fds[1]);
    _exit(code);
  }
  close(fds[1]);
  std::string data;
  char buf[65536];
  for (;;) {
    const ssize_t n = read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    data.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  struct rusage usage {};
  while (wait4(pid, &status, 0, &usage) < 0) {
    if (errno != EINTR) throw std::runtime_error(std::string("wait4: ") + std::strerror(errno));
  }
  ChildOutcome outcome;
  outcome.peak_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux: kilobytes
  if (!WIFEXITED(status) || data.empty()) {
    throw std::runtime_error(fmt::format("benchmark child died (status {})", status));
  }
  outcome.result = json::parse(data);
  if (outcome.result.contains("error")) {
    throw std::runtime_error(outcome.result["error"].get<std::string>());
  }
  return outcome;
}

// Exact transport of an estimate between processes: [robot, kind, index, R (row-major), t].
json ValuesToJson(const moslam::Values& values) {
  json out = json::array();
  for (const auto& [key, pose] : values) {
    json row = {key.robot, static_cast<int>(key.kind), key.index};
    const moslam::Matrix3& R = pose.rotation().matrix();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) row.push_back(R(i, j));
    }
    for (int i = 0; i < 3; ++i) row.push_back(pose.translation()[i]);
    out.push_back(row);
  }
  return out;
}

moslam::Values ValuesFromJson(const json& in) {
  moslam::Values values;
  for (const json& row : in) {
    const moslam::Key key{row[0].get<int>(), static_cast<moslam::VariableKind>(row[1].get<int>()),
                          row[2].get<std::uint64_t>()};
    moslam::Matrix3 R;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) R(i, j) = row[static_cast<std::size_t>(3 + 3 * i + j)];
    }
    const moslam::Vector3 t(row[12].get<double>(), row[13].get<double>(), row[14].get<double>());
    values[key] = moslam::SE3(moslam::SO3(R), t);
  }
  return values;
}

double CurrentRssMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  return 0.0;
}

double CeresGradientMaxAbs(const moslam::PoseGraph& graph, const moslam::Values& values,
                           const moslam::Key& anchor);

// ---------------------------------------------------------------------------------------------
// moslam

json RunMoslam(const moslam::PoseGraph& graph, const moslam::Values& initial,
               const moslam::Key& anchor, moslam::Method method, int repeats, int warmup,
               double min_seconds) {
  moslam::OptimizerOptions options;
  options.method = method;
  std::vector<double> wall, total, linearize, solve;
  moslam::OptimizerResult result;
  const auto begin = Clock::now();
  for (int i = -warmup; i < repeats || Seconds(begin) < min_seconds; ++i) {
    const auto start = Clock::now();
    result = moslam::Optimize(graph, initial, options);
    if (i < 0) continue;
    wall.push_back(Seconds(start));
    total.push_back(result.seconds);
    linearize.push_back(result.linearize_seconds);
    solve.push_back(result.solve_seconds);
  }
  int linear_solves = 0;
  std::vector<double> iteration_seconds;  // of the last run; the first includes the analysis
  for (const auto& it : result.history) {
    linear_solves += it.linear_solves;
    iteration_seconds.push_back(it.seconds);
  }
  return json{{"initial_cost", result.initial_cost},
              {"final_cost", result.final_cost},
              {"ceres_gradient_max_at_final", CeresGradientMaxAbs(graph, result.values, anchor)},
              {"final_cost_recomputed", graph.cost(result.values)},
              {"iterations", result.iterations},
              {"linear_solves", linear_solves},
              {"iteration_seconds", iteration_seconds},
              {"termination", moslam::ToString(result.termination)},
              {"seconds", Median(wall)},
              {"seconds_all", wall},
              {"seconds_min", *std::min_element(wall.begin(), wall.end())},
              {"optimizer_seconds", Median(total)},
              {"linearize_seconds", Median(linearize)},
              {"solve_seconds", Median(solve)}};
}

// ---------------------------------------------------------------------------------------------
// Ceres

// Largest gradient component of the Ceres problem at `values` (in Ceres' tangent coordinates):
// an independent stationarity test of another solver's optimum.
double CeresGradientMaxAbs(const moslam::PoseGraph& graph, const moslam::Values& values,
                           const moslam::Key& anchor) {
  moslam_bench::CeresPoseGraph cpg(graph, values, anchor);
  double cost = 0.0;
  std::vector<double> gradient;
  ceres::Problem::EvaluateOptions options;
  options.num_threads = 1;
  if (!cpg.problem().Evaluate(options, &cost, nullptr, &gradient, nullptr)) {
    throw std::runtime_error("Ceres could not evaluate the gradient");
  }
  double worst = 0.0;
  for (double g : gradient) worst = std::max(worst, std::abs(g));
  return worst;
}

json RunCeres(const moslam::PoseGraph& graph, const moslam::Values& initial,
              const moslam::Key& anchor, int num_threads, int repeats, int warmup,
              double min_seconds) {
  std::vector<double> wall, solver_total;
  moslam_bench::CeresRun run;
  const auto begin = Clock::now();
  for (int i = -warmup; i < repeats || Seconds(begin) < min_seconds; ++i) {
    const auto start = Clock::now();
    run = moslam_bench::SolveWithCeres(graph, initial, anchor, num_threads, 1e-12);
    if (i < 0) continue;
    wall.push_back(Seconds(start));
    solver_total.push_back(run.summary.total_time_in_seconds);
  }
  const ceres::Solver::Summary& s = run.summary;
  std::vector<double> iteration_seconds;  // of the last run
  for (const auto& it : s.iterations) iteration_seconds.push_back(it.iteration_time_in_seconds);
  return json{{"iteration_seconds", iteration_seconds},
              {"preprocessor_seconds", s.preprocessor_time_in_seconds},
              {"initial_cost", s.initial_cost},
              {"final_cost", s.final_cost},
              {"final_cost_moslam", graph.cost(run.values)},
              {"ceres_gradient_max_at_final", CeresGradientMaxAbs(graph, run.values, anchor)},
              {"iterations", s.num_successful_steps + s.num_unsuccessful_steps},
              {"successful_steps", s.num_successful_steps},
              {"termination", ceres::TerminationTypeToString(s.termination_type)},
              {"converged", s.termination_type == ceres::CONVERGENCE},
              {"message", s.message},
              {"num_threads_used", s.num_threads_used},
              {"seconds", Median(wall)},
              {"seconds_all", wall},
              {"seconds_min", *std::min_element(wall.begin(), wall.end())},
              {"solve_seconds", Median(solver_total)},
              {"linear_solver_seconds", s.linear_solver_time_in_seconds},
              {"jacobian_seconds", s.jacobian_evaluation_time_in_seconds},
              {"residual_seconds", s.residual_evaluation_time_in_seconds}};
}

// Largest |r_bench - r_moslam| over all edges of `graph` at `values`: the bench residual
// (ceres_se3_cost.h, evaluated with doubles) against RelativePoseFactor::residual.
double MaxResidualDifference(const moslam::PoseGraph& graph, const moslam::Values& values) {
  double worst = 0.0;
  for (const auto& f : graph.factors()) {
    const moslam::SE3& a = values.at(f.a());
    const moslam::SE3& b = values.at(f.b());
    const Eigen::Vector4d qa = a.rotation().quaternionWxyz();
    const Eigen::Vector4d qb = b.rotation().quaternionWxyz();
    const Eigen::Vector4d qz = f.measured().rotation().quaternionWxyz();
    double r[6];
    moslam_bench::RelativePoseLog<double>(
        {qa[0], qa[1], qa[2], qa[3]}, {a.translation()[0], a.translation()[1], a.translation()[2]},
        {qb[0], qb[1], qb[2], qb[3]}, {b.translation()[0], b.translation()[1], b.translation()[2]},
        {qz[0], qz[1], qz[2], qz[3]},
        {f.measured().translation()[0], f.measured().translation()[1],
         f.measured().translation()[2]},
        r);
    const moslam::Vector6 expected = f.residual(a, b);
    for (int i = 0; i < 6; ++i) worst = std::max(worst, std::abs(r[i] - expected[i]));
  }
  return worst;
}

// The bench residual against moslam's on relative rotations from 0 to pi (the series branches and
// the antipodal case), random axes and translations: returns the largest difference.
double ResidualSelfCheck() {
  const double kPi = std::acos(-1.0);
  const std::vector<double> angles = {0.0,  1e-14, 1e-9, 1e-7, 1e-6, 1e-5,       1e-3,
                                      0.01, 0.5,   1.0,  2.0,  3.0,  kPi - 1e-5, kPi - 1e-9};
  std::srand(7);
  auto uniform = [] { return 2.0 * std::rand() / RAND_MAX - 1.0; };
  double worst = 0.0;
  for (double angle : angles) {
    for (int trial = 0; trial < 20; ++trial) {
      const moslam::Vector3 axis = moslam::Vector3(uniform(), uniform(), uniform()).normalized();
      const moslam::Vector3 t(uniform() * 5.0, uniform() * 5.0, uniform() * 5.0);
      const moslam::SE3 error(moslam::SO3::Exp(angle * axis), t);
      // a random, b = a * z * error so that z^-1 a^-1 b = error.
      const moslam::SE3 a(moslam::SO3::Exp(moslam::Vector3(uniform(), uniform(), uniform()) * 3.0),
                          moslam::Vector3(uniform(), uniform(), uniform()) * 10.0);
      const moslam::SE3 z(moslam::SO3::Exp(moslam::Vector3(uniform(), uniform(), uniform())),
                          moslam::Vector3(uniform(), uniform(), uniform()));
      const moslam::SE3 b = a * z * error;
      moslam::PoseGraph g;
      g.add(moslam::RelativePoseFactor(moslam::Key::Pose(0, 0), moslam::Key::Pose(0, 1), z,
                                       moslam::Matrix6::Identity()));
      worst = std::max(worst, MaxResidualDifference(
                                  g, {{moslam::Key::Pose(0, 0), a}, {moslam::Key::Pose(0, 1), b}}));
    }
  }
  return worst;
}

// ---------------------------------------------------------------------------------------------

// The chordal initialisation of `graph`, run in a child: CHOLMOD uses OpenMP, and libgomp's
// thread pool does not survive a fork (a child of a process that already used it hangs in its
// first parallel region). The estimate comes back exactly (rotation matrices and translations as
// round-trip decimal doubles).
struct ChordalStart {
  moslam::Values values;
  double seconds = 0.0;
  double peak_mb = 0.0;
};

ChordalStart ChordalInChild(const moslam::PoseGraph& graph, const moslam::SE3& anchor_pose) {
  const ChildOutcome prep = RunInChild([&] {
    const auto start = Clock::now();
    const moslam::Values chordal = moslam::ChordalInitialization(graph, anchor_pose);
    return json{{"seconds", Seconds(start)}, {"values", ValuesToJson(chordal)}};
  });
  return {ValuesFromJson(prep.result["values"]), prep.result["seconds"].get<double>(),
          prep.peak_mb};
}

struct Job {
  std::string key;
  std::function<json()> run;
};

// Every timed run is a fresh child (after `warmup` untimed runs in it), and the solvers take
// turns, so a change of machine load over the benchmark affects them alike. Into row[job.key]: a
// run's result, the median of each timing over the children, every wall time, the fastest, and
// the largest peak memory.
void TimeJobs(const std::string& name, const std::vector<Job>& jobs, int repeats, json& row) {
  const std::vector<std::string> timings = {"seconds", "optimizer_seconds", "linearize_seconds",
                                            "solve_seconds"};
  std::map<std::string, std::map<std::string, std::vector<double>>> samples;
  std::map<std::string, double> peak;
  for (int rep = 0; rep < repeats; ++rep) {
    for (const Job& job : jobs) {
      const std::string& key = job.key;
      const ChildOutcome out = RunInChild(job.run);
      std::cerr << fmt::format("[{}] {} run {}: {:.3f} s\n", name, key, rep + 1,
                               out.result["seconds"].get<double>());
      for (const auto& t : timings) {
        if (out.result.contains(t)) samples[key][t].push_back(out.result[t].get<double>());
      }
      peak[key] = std::max(peak[key], out.peak_mb);
      row[key] = out.result;  // costs and iterations are the same in every run
    }
  }
  for (const Job& job : jobs) {
    const std::string& key = job.key;
    json& r = row[key];
    for (const auto& [t, values] : samples[key]) r[t] = Median(values);
    const std::vector<double>& wall = samples[key]["seconds"];
    r["seconds_all"] = wall;
    r["seconds_min"] = *std::min_element(wall.begin(), wall.end());
    r["peak_mb"] = peak[key];
  }
}

// The solvers against Ceres' final cost and time, into the row.
void CompareWithCeres(double initial_cost, bool with_lm, json& row) {
  const json& gn = row["moslam_gn"];
  const json& ce = row["ceres"];
  const double ceres_final = ce["final_cost_moslam"].get<double>();
  row["init_cost_rel_diff"] = RelDiff(ce["initial_cost"].get<double>(), initial_cost);
  row["ceres_final_cost_rel_diff_evaluators"] =
      RelDiff(ce["final_cost"].get<double>(), ceres_final);
  row["gn_vs_ceres_rel_cost_diff"] = RelDiff(gn["final_cost"].get<double>(), ceres_final);
  row["speedup_gn"] = ce["seconds"].get<double>() / gn["seconds"].get<double>();
  if (with_lm) {
    row["lm_vs_ceres_rel_cost_diff"] =
        RelDiff(row["moslam_lm"]["final_cost"].get<double>(), ceres_final);
    row["speedup_lm"] = ce["seconds"].get<double>() / row["moslam_lm"]["seconds"].get<double>();
  }
}

json BenchDataset(const std::string& name, const std::string& path, int repeats, int warmup,
                  double min_seconds, bool with_lm, bool with_two_threads) {
  // cubicle.g2o holds information matrices that are indefinite through their translation-rotation
  // coupling only; moslam rejects them by default. Both solvers get the same repaired matrices
  // (coupling dropped on exactly those edges), counted in "repaired_information".
  moslam::G2oReadOptions read_options;
  read_options.drop_indefinite_coupling = true;
  const moslam::Dataset dataset = moslam::ReadG2o(path, read_options);
  const moslam::PoseGraph& graph = dataset.graph;
  const moslam::Key anchor = moslam::GaugeAnchor(graph);
  const auto anchor_it = dataset.initial.find(anchor);
  const moslam::SE3 anchor_pose =
      anchor_it != dataset.initial.end() ? anchor_it->second : moslam::SE3();
  const ChordalStart prep = ChordalInChild(graph, anchor_pose);
  const moslam::Values& initial = prep.values;
  const double initial_cost = graph.cost(initial);

  json row{{"dataset", name},
           {"file", path},
           {"poses", graph.keys().size()},
           {"edges", graph.factors().size()},
           {"priors", graph.priors().size()},
           {"repaired_information", dataset.repaired_information},
           {"initial_cost", initial_cost},
           {"chordal_seconds", prep.seconds},
           {"chordal_peak_mb", prep.peak_mb},
           {"repeats", repeats},
           {"warmup", warmup},
           {"min_seconds", min_seconds},
           {"parent_rss_mb", CurrentRssMb()},
           {"max_residual_diff_initial", MaxResidualDifference(graph, initial)},
           {"ceres_gradient_max_at_initial", CeresGradientMaxAbs(graph, initial, anchor)}};

  std::vector<Job> jobs;
  jobs.push_back(Job{"moslam_gn", [&] {
                       return RunMoslam(graph, initial, anchor, moslam::Method::kGaussNewton, 1,
                                        warmup, min_seconds);
                     }});
  if (with_lm) {
    jobs.push_back(Job{"moslam_lm", [&] {
                         return RunMoslam(graph, initial, anchor,
                                          moslam::Method::kLevenbergMarquardt, 1, warmup,
                                          min_seconds);
                       }});
  }
  jobs.push_back(
      Job{"ceres", [&] { return RunCeres(graph, initial, anchor, 1, 1, warmup, min_seconds); }});
  if (with_two_threads) {
    jobs.push_back(Job{
        "ceres_2t", [&] { return RunCeres(graph, initial, anchor, 2, 1, warmup, min_seconds); }});
  }
  TimeJobs(name, jobs, repeats, row);
  CompareWithCeres(initial_cost, with_lm, row);
  return row;
}

std::string Cost(double c) { return fmt::format("{:.9g}", c); }
std::string Sec(double s) { return fmt::format("{:.3f}", s); }
std::string Rel(double r) { return fmt::format("{:+.1e}", r); }
std::string Mb(double m) { return fmt::format("{:.0f}", m); }

void PrintTable(const json& rows, bool with_lm, bool with_two_threads) {
  std::vector<std::string> head = {
      "dataset",        "poses", "edges", "initial cost", "init Δ Ceres/moslam",
      "moslam GN cost", "iters", "time s"};
  if (with_lm) {
    for (const char* h : {"moslam LM cost", "iters", "time s"}) head.emplace_back(h);
  }
  for (const char* h : {"Ceres cost", "iters", "time s"}) head.emplace_back(h);
  if (with_two_threads) head.emplace_back("Ceres 2T time s");
  for (const char* h : {"Ceres converged", "rel. cost diff GN", "speed-up GN"}) {
    head.emplace_back(h);
  }
  if (with_lm) {
    head.emplace_back("rel. cost diff LM");
    head.emplace_back("speed-up LM");
  }
  head.emplace_back("peak MB moslam GN");
  if (with_lm) head.emplace_back("peak MB moslam LM");
  head.emplace_back("peak MB Ceres");

  auto line = [](const std::vector<std::string>& cells) {
    std::string s = "|";
    for (const auto& c : cells) s += " " + c + " |";
    return s;
  };
  std::cout << line(head) << "\n";
  std::vector<std::string> sep;
  for (std::size_t i = 0; i < head.size(); ++i) sep.emplace_back(i == 0 ? "---" : "--:");
  std::cout << line(sep) << "\n";

  for (const json& r : rows) {
    const json& gn = r["moslam_gn"];
    const json& ce = r["ceres"];
    std::vector<std::string> c = {r["dataset"].get<std::string>(),
                                  std::to_string(r["poses"].get<int>()),
                                  std::to_string(r["edges"].get<int>()),
                                  Cost(r["initial_cost"].get<double>()),
                                  Rel(r["init_cost_rel_diff"].get<double>()),
                                  Cost(gn["final_cost"].get<double>()),
                                  std::to_string(gn["iterations"].get<int>()),
                                  Sec(gn["seconds"].get<double>())};
    if (with_lm) {
      const json& lm = r["moslam_lm"];
      c.push_back(Cost(lm["final_cost"].get<double>()));
      c.push_back(std::to_string(lm["iterations"].get<int>()));
      c.push_back(Sec(lm["seconds"].get<double>()));
    }
    c.push_back(Cost(ce["final_cost_moslam"].get<double>()));
    c.push_back(std::to_string(ce["iterations"].get<int>()));
    c.push_back(Sec(ce["seconds"].get<double>()));
    if (with_two_threads) c.push_back(Sec(r["ceres_2t"]["seconds"].get<double>()));
    c.push_back(ce["converged"].get<bool>() ? "yes"
                                            : "no (" + ce["termination"].get<std::string>() + ")");
    c.push_back(Rel(r["gn_vs_ceres_rel_cost_diff"].get<double>()));
    c.push_back(fmt::format("{:.2f}x", r["speedup_gn"].get<double>()));
    if (with_lm) {
      c.push_back(Rel(r["lm_vs_ceres_rel_cost_diff"].get<double>()));
      c.push_back(fmt::format("{:.2f}x", r["speedup_lm"].get<double>()));
    }
    c.push_back(Mb(gn["peak_mb"].get<double>()));
    if (with_lm) c.push_back(Mb(r["moslam_lm"]["peak_mb"].get<double>()));
    c.push_back(Mb(ce["peak_mb"].get<double>()));
    std::cout << line(c) << "\n";
  }
  for (const json& r : rows) {
    const int repaired = r["repaired_information"].get<int>();
    if (repaired > 0) {
      std::cout << fmt::format(
          "\n{}: {} of {} edges have an indefinite information matrix in the file; both solvers "
          "use it with the translation-rotation coupling dropped "
          "(G2oReadOptions::drop_indefinite_coupling).\n",
          r["dataset"].get<std::string>(), repaired, r["edges"].get<int>());
    }
  }
}

// Lines naming every failed check; empty when all pass.
std::vector<std::string> FailedChecks(const json& rows) {
  std::vector<std::string> failures;
  for (const json& r : rows) {
    const std::string name = r["dataset"].get<std::string>();
    const double init = r["init_cost_rel_diff"].get<double>();
    if (!(std::abs(init) <= 1e-9)) {
      failures.push_back(
          fmt::format("{}: Ceres and moslam initial costs differ by {:.2e} "
                      "relative (> 1e-9)",
                      name, init));
    }
    for (const char* m : {"gn", "lm"}) {
      const std::string diff_key = std::string(m) + "_vs_ceres_rel_cost_diff";
      if (!r.contains(diff_key)) continue;
      const double d = r[diff_key].get<double>();
      if (r["ceres"]["converged"].get<bool>() && d > 1e-6) {
        failures.push_back(
            fmt::format("{}: moslam {} final cost is {:.2e} relative above "
                        "Ceres' (> 1e-6)",
                        name, m, d));
      }
      const double speedup = r[std::string("speedup_") + m].get<double>();
      if (speedup < 1.0) {
        failures.push_back(fmt::format(
            "{}: moslam {} is slower than Ceres (Ceres/moslam time {:.2f})", name, m, speedup));
      }
    }
  }
  return failures;
}

// The residual and stationarity cross-checks, printed; the failed checks, FailedChecks' with
// them.
std::vector<std::string> ReportChecks(const json& rows, double self_check) {
  std::vector<std::string> failures = FailedChecks(rows);
  std::cout << fmt::format(
      "\nResidual cross-check: max |r_Ceres - r_moslam| = {:.1e} on synthetic edges with "
      "rotation errors 0 .. pi - 1e-9; per dataset at the initial estimate:",
      self_check);
  for (const json& r : rows) {
    const double d = r["max_residual_diff_initial"].get<double>();
    std::cout << fmt::format(" {} {:.1e}", r["dataset"].get<std::string>(), d);
    if (!(d <= 1e-9)) {
      failures.push_back(
          fmt::format("{}: edge residuals differ by {:.1e}", r["dataset"].get<std::string>(), d));
    }
  }
  if (!(self_check <= 1e-9)) {
    failures.push_back(fmt::format("synthetic residuals differ by {:.1e}", self_check));
  }
  std::cout << ".\nStationarity by Ceres' gradient (max |g| in Ceres' tangent coordinates) at the "
               "initial estimate / moslam GN / moslam LM / Ceres final estimates:";
  for (const json& r : rows) {
    std::cout << fmt::format(
        " {} {:.1e} / {:.1e} / {} / {:.1e};", r["dataset"].get<std::string>(),
        r["ceres_gradient_max_at_initial"].get<double>(),
        r["moslam_gn"]["ceres_gradient_max_at_final"].get<double>(),
        r.contains("moslam_lm")
            ? fmt::format("{:.1e}", r["moslam_lm"]["ceres_gradient_max_at_final"].get<double>())
            : std::string("-"),
        r["ceres"]["ceres_gradient_max_at_final"].get<double>());
  }
  std::cout << "\n\n";
  return failures;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"moslam centralized solver vs Ceres on the 3D pose-graph benchmarks"};
#ifdef MOSLAM_DATASETS_DIR
  std::string datasets_dir = MOSLAM_DATASETS_DIR;
#else
  std::string datasets_dir = "../shared/datasets";
#endif
  std::vector<std::string> names = kDefaultDatasets;
  int repeats = 3;
  int warmup = 1;
  double min_seconds = 0.5;
  std::string json_path;
  bool no_lm = false;
  bool no_two_threads = false;
  bool strict = false;
  app.add_option("--datasets", datasets_dir, "Folder holding pgo/ (default: MOSLAM_DATASETS_DIR)");
  app.add_option("--dataset,-d", names, "Dataset names under pgo/ (default: the six 3D graphs)");
  app.add_option("--repeats,-r", repeats,
                 "Timed runs per solver, each in a fresh process; the median is reported")
      ->check(CLI::PositiveNumber);
  app.add_option("--warmup", warmup, "Untimed runs per solver before the timed ones")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--min-time", min_seconds,
                 "Each timed process repeats its solve until this many seconds have passed and "
                 "reports the median solve (steadier times for small graphs)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--json", json_path, "Also write the results as a JSON array to this file");
  app.add_flag("--no-lm", no_lm, "Skip moslam Levenberg-Marquardt");
  app.add_flag("--no-2t", no_two_threads, "Skip the 2-thread Ceres run");
  app.add_flag("--strict", strict,
               "Exit with status 2 when a check fails (costs differ or moslam is slower)");
  CLI11_PARSE(app, argc, argv);

  try {
    const double self_check = ResidualSelfCheck();
    json rows = json::array();
    for (const auto& name : names) {
      const std::string path = datasets_dir + "/pgo/" + name + ".g2o";
      // One process per dataset, so the memory figures of one dataset do not carry what an
      // earlier one left in the allocator.
      rows.push_back(RunInChild([&] {
                       return BenchDataset(name, path, repeats, warmup, min_seconds, !no_lm,
                                           !no_two_threads);
                     }).result);
    }
    PrintTable(rows, !no_lm, !no_two_threads);
    const std::vector<std::string> failures = ReportChecks(rows, self_check);
    if (failures.empty()) {
      std::cout << "All checks pass: residuals agree to 1e-9, initial costs to 1e-9 relative, "
                   "moslam reaches Ceres' final cost to 1e-6 wherever Ceres converges, and is at "
                   "least as fast.\n";
    } else {
      std::cout << "Failed checks:\n";
      for (const auto& f : failures) std::cout << "- " << f << "\n";
    }
    if (!json_path.empty()) {
      std::ofstream out(json_path);
      if (!out) throw std::runtime_error("cannot write " + json_path);
      out << rows.dump(2) << "\n";
    }
    return strict && !failures.empty() ? 2 : 0;
  } catch (const std::exception& e) {
    std::cerr << "moslam_bench_solve: " << e.what() << "\n";
    return 1;
  }
}
