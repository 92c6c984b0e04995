// `moslam team`: starts N robot processes (`moslam robot`) on loopback and collects their
// results.
#include <fmt/core.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "child_processes.h"
#include "cli.h"
#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/io/g2o.h"
#include "moslam/io/tum.h"
#include "moslam/metrics/metrics.h"
#include "moslam/online/online_team.h"
#include "moslam/robust/gnc.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"
#include "moslam/transport/dds_transport.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/robot_data.h"
#include "moslam/transport/robot_session.h"
#include "robot_flags.h"
#include "robot_summaries.h"

namespace moslam::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct TeamArgs {
  std::string data;
  ScenarioFlags scenario;
  int robots = 0;
  int domain = 0;
  std::string out;
  SolveFlags solve;
  double timeout = 600.0;
  bool online = false;
  bool prepare_only = false;
  bool collect_only = false;
  bool json = false;
};

// Starts one process per argv (robot r: argvs[r], log in <out>/robot<r>/log.txt) on loopback
// (LoopbackConfigXml), waits for them all (killing them at the timeout: exit code -1) and returns
// their exit codes. `collect_only`: starts nothing and knows no exit code (ReadTeamSummaries
// then goes by the summaries).
std::map<int, int> RunRobotProcesses(const std::vector<std::vector<std::string>>& argvs, int domain,
                                     const fs::path& out, double timeout, bool collect_only) {
  const int n = static_cast<int>(argvs.size());
  std::map<int, int> exit_codes;
  if (collect_only) return exit_codes;
  const std::string config = LoopbackConfigXml(domain, n);
  ::setenv("CYCLONEDDS_URI", config.c_str(), 1);
  std::map<pid_t, int> children;
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    CreateFolder(dir, "team");
    children[SpawnSelf(argvs[static_cast<std::size_t>(r)], dir / "log.txt")] = r;
  }
  return WaitForChildren(children, Ms(timeout));
}

// What `team` reads back from the robot folders <out>/robot<R>/ after the processes ended.
struct TeamResults {
  bool ok = true;  // every robot exited 0 and wrote its summary
  nlohmann::json per_robot = nlohmann::json::array();  // robot, exit_code, log or the summary
  std::map<int, JsonFields> summaries;                 // robot -> summary, those that finished
  Values merged;  // each finished robot's own variables, from its result.g2o
  std::int64_t binary = 0, cdr = 0, status_bytes = 0, messages = 0;
  std::int64_t coarse_binary = 0, coarse_cdr = 0, coarse_messages = 0;
  int rotation_rounds = 0, pose_rounds = 0, refine_steps = 0, protocol_steps = 0;
  double refine_cost = 0.0;  // the refinement's final cost as the robots summed it
  double seconds = 0.0;  // from starting the processes to the last one ending
};

// Reads every robot's summary.json and result.g2o. Scenario robots also write objects and the
// estimates of their neighbours' variables in result.g2o (only their own are merged) and the
// shared-object pairs in their summary (left out of per_robot).
TeamResults CollectTeam(const fs::path& out, int n, const std::map<int, int>& exit_codes,
                        bool scenario) {
  TeamResults t;
  TeamSummaries read = ReadTeamSummaries(out, n, exit_codes);
  t.ok = read.ok;
  for (int r = 0; r < n; ++r) {
    const auto it = read.summaries.find(r);
    if (it == read.summaries.end()) {
      t.per_robot.push_back(read.failed.at(r));
      continue;
    }
    const JsonFields& s = it->second;
    const fs::path dir = out / fmt::format("robot{}", r);
    nlohmann::json entry = {{"robot", r}, {"exit_code", 0}};
    entry.update(s.json());
    entry.erase("shared");
    t.per_robot.push_back(entry);
    const Dataset result = ReadRobotG2o((dir / "result.g2o").string(),
                                        scenario ? WithObjects() : G2oReadOptions{});
    for (const auto& [k, x] : result.initial) {
      if (!scenario || k.robot == r) t.merged.emplace(k, x);
    }
    t.binary += s.get<std::int64_t>("estimate_binary_bytes");
    t.cdr += s.get<std::int64_t>("dds_estimate_bytes");
    t.status_bytes += s.get<std::int64_t>("dds_status_bytes");
    t.messages += s.get<std::int64_t>("estimate_messages");
    t.coarse_binary += s.get<std::int64_t>("coarse_binary_bytes");
    t.coarse_cdr += s.get<std::int64_t>("dds_coarse_bytes");
    t.coarse_messages += s.get<std::int64_t>("coarse_messages");
    t.refine_steps = std::max(t.refine_steps, s.get<int>("refine_steps"));
    t.protocol_steps = std::max(t.protocol_steps, s.get<int>("protocol_steps"));
    t.refine_cost = s.get<double>("refine_final_cost");
    t.rotation_rounds = std::max(t.rotation_rounds, s.get<int>("rotation_rounds"));
    t.pose_rounds = std::max(t.pose_rounds, s.get<int>("pose_rounds"));
    t.summaries.emplace(r, s);
  }
  return t;
}

// The robot processes' exit codes and the time from starting them to the last one ending.
struct TeamRun {
  std::map<int, int> exit_codes;
  double seconds = 0.0;
};

// Runs `moslam robot` for robots 0 .. n-1 (each with its --robot, --domain and --out
// <out>/robot<R>, then `source`: what the robot solves, and the solve flags).
TeamRun RunTeamRobots(const TeamArgs& a, const fs::path& out, int n,
                      const std::vector<std::string>& source) {
  std::vector<std::vector<std::string>> argvs;
  for (int r = 0; r < n; ++r) {
    std::vector<std::string> argv = {"moslam", "robot", "--robot", std::to_string(r), "--domain",
                                     std::to_string(a.domain), "--out",
                                     (out / fmt::format("robot{}", r)).string()};
    argv.insert(argv.end(), source.begin(), source.end());
    for (const std::string& s : SolveArgs(a.solve)) argv.push_back(s);
    argvs.push_back(argv);
  }
  const auto t0 = Clock::now();
  TeamRun run;
  run.exit_codes = RunRobotProcesses(argvs, a.domain, out, a.timeout, a.collect_only);
  run.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return run;
}

// RunTeamRobots, then the results collected (CollectTeam).
TeamResults RunTeamProcesses(const TeamArgs& a, const fs::path& out, int n,
                             const std::vector<std::string>& source, bool scenario) {
  const TeamRun run = RunTeamRobots(a, out, n, source);
  TeamResults t = CollectTeam(out, n, run.exit_codes, scenario);
  t.seconds = run.seconds;
  return t;
}

// --robust: the robots' separator check, GNC rounds, weights and re-tests (summed or the most of
// their summaries) against the in-process robust solve's; JSON fields and two report lines.
void CompareRobust(const TeamResults& t, const RobustDgsResult& in_process, nlohmann::json& j) {
  std::int64_t messages = 0, binary = 0, dds = 0, check_binary = 0, check_dds = 0;
  int rounds = 0, outliers = 0, check_rejected = 0, retests = 0, retest_readmitted = 0;
  int group_retests = 0, group_readmitted = 0;
  for (const auto& [r, s] : t.summaries) {
    messages += s.get<std::int64_t>("weight_messages");
    binary += s.get<std::int64_t>("weight_binary_bytes");
    dds += s.get<std::int64_t>("dds_weight_bytes");
    check_rejected += s.get<int>("check_rejected");
    check_binary += s.get<std::int64_t>("check_binary_bytes");
    check_dds += s.get<std::int64_t>("dds_covariance_bytes");
    rounds = std::max(rounds, s.get<int>("gnc_rounds"));
    outliers += s.get<int>("outliers");
    retests = std::max(retests, s.get<int>("retests"));
    retest_readmitted += s.get<int>("retest_readmitted");
    group_retests = std::max(group_retests, s.get<int>("group_retests"));
    group_readmitted += s.get<int>("group_readmitted");
  }
  j["gnc_rounds"] = rounds;
  j["in_process_gnc_rounds"] = in_process.iterations;
  j["in_process_outliers"] = in_process.outliers;
  j["robots_outliers"] = outliers;  // per robot, its subgraph's: a separator counts twice
  j["weight_messages"] = messages;
  j["weight_binary_bytes"] = binary;
  j["dds_weight_bytes"] = dds;
  j["in_process_weight_messages"] = in_process.weight_messages;
  j["in_process_weight_bytes"] = in_process.weight_bytes;
  j["check_rejected"] = check_rejected;
  j["in_process_check_rejected"] = in_process.consistency_rejected;
  j["check_binary_bytes"] = check_binary;
  j["in_process_check_bytes"] = in_process.consistency_bytes;
  j["dds_covariance_bytes"] = check_dds;
  j["retests"] = retests;
  j["retest_readmitted"] = retest_readmitted;
  j["in_process_retests"] = in_process.retests;
  j["in_process_retest_readmitted"] = in_process.retest_readmitted;
  j["group_retests"] = group_retests;
  j["group_readmitted"] = group_readmitted;
  j["in_process_group_retests"] = in_process.group_retests;
  j["in_process_group_readmitted"] = in_process.group_readmitted;
  fmt::print(
      "separator check: {} left out before GNC (in-process {}); {} B binary for it "
      "(in-process {} B), {} B CDR payload of covariances\n",
      check_rejected, in_process.consistency_rejected, check_binary, in_process.consistency_bytes,
      check_dds);
  fmt::print(
      "robust: {} GNC rounds (in-process {}), {} outliers in-process; {} weight "
      "messages, {} B binary, {} B CDR payload (in-process {}, {} B)\n",
      rounds, in_process.iterations, in_process.outliers, messages, binary, dds,
      in_process.weight_messages, in_process.weight_bytes);
}

// With the refinement: the team's cost against the centralized optimum in the same gauge (the
// anchor at its initial value); JSON fields (j["cost"] already set) and a report line.
void CompareWithCentralized(const TeamResults& t, const PoseGraph& graph,
                            const DgsResult& reference, nlohmann::json& j) {
  // The centralized optimum in the same gauge (the anchor at its initial value).
  const Key anchor = GaugeAnchor(graph);
  const auto it = reference.values.find(anchor);
  const SE3 anchor_pose = it != reference.values.end() ? it->second : SE3();
  const OptimizerResult central = Optimize(graph, ChordalInitialization(graph, anchor_pose));
  j["refine_final_cost"] = t.refine_cost;
  j["in_process_refine_final_cost"] = reference.refine.final_cost;
  j["cost_centralized"] = central.final_cost;
  const std::optional<double> ratio = CostRatio(j["cost"].get<double>(), central.final_cost);
  j["cost_relative_to_centralized"] = ratio ? nlohmann::json(*ratio - 1.0) : nullptr;
  fmt::print(
      "refinement: {} steps (in-process {}), cost F = {:.12g} (in-process {:.12g}, "
      "centralized optimum {:.12g}: {})\n",
      t.refine_steps, reference.refine.iterations, j["cost"].get<double>(),
      reference.refine.final_cost, central.final_cost,
      ratio ? fmt::format("{:+.2e} relative", *ratio - 1.0) : "at rounding level");
}

// The team's estimate against the in-process driver's on the same graph (and, with the
// refinement, against the centralized optimum): JSON fields and the DGS lines of the report.
// Writes the merged map into `out`: merged.g2o (every variable and factor) and robot_<r>.tum.
// With `robust` (the team ran --robust): the estimate is compared with it, the rounds, messages
// and refinement of `reference` are those of its least-squares solve.
void CompareWithInProcess(const TeamResults& t, const PoseGraph& graph, const DgsResult& reference,
                          const fs::path& out, const G2oWriteOptions& write, nlohmann::json& j,
                          const RobustDgsResult* robust = nullptr) {
  const Values& expected = robust ? robust->values : reference.values;
  WriteG2oFile((out / "merged.g2o").string(), graph, t.merged, write);
  WriteTumTrajectories(out.string(), t.merged);
  j["merged_map"] = (out / "merged.g2o").string();
  j["cost"] = graph.cost(t.merged);
  j["cost_in_process"] = graph.cost(expected);
  j["max_difference"] = MaxPoseDifference(t.merged, expected);
  j["variables"] = t.merged.size();
  j["in_process_variables"] = expected.size();
  if (robust) CompareRobust(t, *robust, j);
  j["rotation_rounds"] = t.rotation_rounds;
  j["pose_rounds"] = t.pose_rounds;
  j["in_process_rotation_iterations"] = reference.rotation.iterations;
  j["in_process_pose_iterations"] = reference.pose.iterations;
  j["estimate_messages"] = t.messages;
  j["in_process_messages"] = reference.messages;
  j["estimate_binary_bytes"] = t.binary;
  j["in_process_bytes"] = reference.bytes;
  j["dds_estimate_bytes"] = t.cdr;
  j["dds_status_bytes"] = t.status_bytes;
  j["coarse_messages"] = t.coarse_messages;
  j["coarse_binary_bytes"] = t.coarse_binary;
  j["dds_coarse_bytes"] = t.coarse_cdr;
  j["in_process_coarse_bytes"] = reference.refine.coarse_bytes;
  j["protocol_steps"] = t.protocol_steps;
  j["refine_steps"] = t.refine_steps;
  j["in_process_refine_steps"] = reference.refine.iterations;
  const int rounds = t.rotation_rounds + t.pose_rounds;
  j["dds_payload_bytes_per_round"] =
      rounds ? static_cast<double>(t.cdr + t.status_bytes) / rounds : 0.0;
  j["dds_payload_bytes"] = t.cdr + t.status_bytes + t.coarse_cdr;
  if (reference.refine.status != StageStatus::kNotRun && !robust) {
    CompareWithCentralized(t, graph, reference, j);
  }
  if (robust) {
    j["in_process_solve_bytes"] = robust->solve_bytes;
    fmt::print("DGS, least-squares solve: rotation {} rounds, pose {} rounds (in-process {}, {}); "
               "every solve: {} messages, {} B binary estimates and {} B coarse (in-process {} B "
               "with the control messages), {} B CDR payload, status {} B\n",
               t.rotation_rounds, t.pose_rounds, reference.rotation.iterations,
               reference.pose.iterations, t.messages, t.binary, t.coarse_binary,
               robust->solve_bytes, t.cdr, t.status_bytes);
  } else {
    fmt::print("DGS: rotation {} rounds, pose {} rounds (in-process {}, {}); {} messages, {} B "
               "binary (in-process {}, {} B), {} B CDR payload, status {} B\n",
               t.rotation_rounds, t.pose_rounds, reference.rotation.iterations,
               reference.pose.iterations, t.messages, t.binary, reference.messages,
               reference.bytes, t.cdr, t.status_bytes);
  }
  if (t.coarse_messages > 0) {
    fmt::print("coarse shares: {} published, {} B binary, {} B CDR payload; {} protocol steps\n",
               t.coarse_messages, t.coarse_binary, t.coarse_cdr, t.protocol_steps);
  }
  fmt::print("cost F = {:.9g} (in-process {:.9g}), largest difference {:.3g}\n",
             j["cost"].get<double>(), j["cost_in_process"].get<double>(),
             j["max_difference"].get<double>());
}

// The robots ReadTeamSummaries found failed: why, and their log when they wrote one.
void ReportFailedRobots(const nlohmann::json& per_robot) {
  for (const auto& r : per_robot) {
    if (!r.contains("reason")) continue;
    const std::string log = r.value("log", std::string());
    fmt::print(stderr, "moslam: robot {} failed: {}{}\n", r["robot"].get<int>(),
               r["reason"].get<std::string>(), log.empty() ? "" : "; its log: " + log);
  }
}

// The online robots' summaries: whether every robot exited 0 and wrote one, and per robot its
// exit code and log (failed) or its number of group solves.
struct OnlineSummaries {
  bool ok = true;
  nlohmann::json per_robot = nlohmann::json::array();
  std::map<int, JsonFields> summaries;  // robot -> summary, those that finished
};

OnlineSummaries ReadOnlineSummaries(const fs::path& out, int n,
                                    const std::map<int, int>& exit_codes) {
  TeamSummaries read = ReadTeamSummaries(out, n, exit_codes);
  OnlineSummaries o;
  o.ok = read.ok;
  for (int r = 0; r < n; ++r) {
    const auto it = read.summaries.find(r);
    if (it == read.summaries.end()) {
      o.per_robot.push_back(read.failed.at(r));
      continue;
    }
    o.per_robot.push_back(
        {{"robot", r}, {"exit_code", 0}, {"solves", it->second.items("solves").size()}});
  }
  o.summaries = std::move(read.summaries);
  return o;
}

// The processes' online mission against the in-process twin's: every map each robot saved, the
// group solves each took part in, the pairs set aside at the end (--robust), and the bytes.
struct OnlineComparison {
  bool same_solves = true;       // every robot in the twin's group solves
  int maps = 0, mismatched = 0;  // maps compared; of another size than the twin's
  double largest = 0.0;          // largest pose difference over them
  std::int64_t objects_bytes = 0, solve_bytes = 0;  // DDS payload: rendezvous, group solves
  int events = 0;                                   // rendezvous (counted once, by alpha)
  std::set<std::pair<Key, Key>> set_aside, twin_set_aside;
  int unlinked = 0;  // twin's group solves the separator check left unlinked
};

OnlineComparison CompareWithTwin(const fs::path& out, const std::map<int, JsonFields>& summaries,
                                 const OnlineRun& twin) {
  OnlineComparison c;
  const auto pair_of = [](const JsonFields& p) {
    const auto v = p.as<std::vector<std::uint64_t>>();
    const auto robots = static_cast<std::uint64_t>(kMaxRobotsWithObjects);
    if (v.size() != 4 || v[0] >= robots || v[2] >= robots) {
      throw InvalidInputError(p.where() + ": not a pair of objects [robot, index, robot, index]");
    }
    return UnorderedPair(Key::Object(static_cast<int>(v[0]), v[1]),
                         Key::Object(static_cast<int>(v[2]), v[3]));
  };
  for (const SharedObject& o : twin.set_aside) {
    c.twin_set_aside.insert(UnorderedPair(o.alpha_object, o.beta_object));
  }
  for (const GroupSolveRecord& g : twin.solves) c.unlinked += g.unlinked ? 1 : 0;
  const auto compare = [&](const fs::path& file, const Values& reference) {
    const Dataset saved = ReadRobotG2o(file.string(), WithObjects());
    ++c.maps;
    if (saved.initial.size() != reference.size()) ++c.mismatched;
    c.largest = std::max(c.largest, MaxPoseDifference(saved.initial, reference));
  };
  for (const auto& [r, s] : summaries) {
    const fs::path dir = out / fmt::format("robot{}", r);
    std::vector<std::pair<int, std::vector<int>>> expected;
    for (const GroupSolveRecord& g : twin.solves) {
      if (std::find(g.robots.begin(), g.robots.end(), r) != g.robots.end()) {
        expected.emplace_back(g.step, g.robots);
      }
    }
    std::vector<std::pair<int, std::vector<int>>> got;
    for (const JsonFields& g : s.items("solves")) {
      got.emplace_back(g.get<int>("step"), g.get<std::vector<int>>("robots"));
      c.solve_bytes += g.get<std::int64_t>("dds_sent_bytes");
      compare(dir / "maps" / fmt::format("step_{:04d}", got.back().first) / "map.g2o",
              twin.maps.at({got.back().first, r}));
    }
    if (got != expected) {
      c.same_solves = false;
      fmt::print(stderr, "moslam: robot {} took part in {} group solves, the in-process twin's "
                 "robot in {} (or in other groups)\n", r, got.size(), expected.size());
    }
    compare(dir / "maps" / "final" / "map.g2o",
            twin.slam.robots[static_cast<std::size_t>(r)].estimate());
    c.objects_bytes += s.get<std::int64_t>("rendezvous_dds_bytes");
    for (const JsonFields& e : s.items("rendezvous")) c.events += e.get<int>("alpha") == r ? 1 : 0;
    for (const JsonFields& p : s.items("set_aside", /*optional=*/true)) {
      c.set_aside.insert(pair_of(p));
    }
  }
  return c;
}

// The in-process twin of the processes' online mission (online/online_team.h, RunOnline with
// the processes' solver).
OnlineRun RunOnlineTwin(const DgsNodeOptions& node, const ScenarioSpec& spec) {
  OnlineOptions options;
  options.solver = DriverOptions(node);
  if (node.gnc) options.robust = ReferenceRobustOptions(node);  // its dgs: the solver
  const MultiRobotSlamConfig config = ScenarioSlamConfig(spec);
  options.lambda = config.rendezvous.lambda();
  return RunOnline(SimulateScenario(spec), config, options);
}

void PrintOnlineReport(const ScenarioSpec& spec, double seconds, std::size_t solves, bool robust,
                       const OnlineComparison& c, const nlohmann::json& j) {
  fmt::print(
      "{} with {} robots (seed {}, {} poses each), online, as processes on loopback: "
      "{:.2f} s\n",
      spec.scenario, spec.robots, spec.seed, spec.poses_per_robot, seconds);
  fmt::print(
      "{} rendezvous, {} group solves; {} saved maps against the in-process twin: largest "
      "difference {:.3g}{}\n",
      c.events, solves, c.maps, c.largest,
      c.mismatched ? fmt::format(" ({} of other sizes)", c.mismatched) : "");
  if (robust) {
    fmt::print(
        "robust: {} pairs set aside at the end (in-process twin {}), {} group solves left "
        "unlinked by the separator check\n",
        c.set_aside.size(), c.twin_set_aside.size(), c.unlinked);
  }
  fmt::print(
      "DDS payload: objects {} B, group solves {} B; {:.1f} kB per group solve (point "
      "clouds, one frame per robot: {:.0f} kB)\n",
      c.objects_bytes, c.solve_bytes, j["dds_bytes_per_solve"].get<double>() / 1e3,
      j["point_cloud_bytes_per_solve"].get<double>() / 1e3);
}

// `moslam team --scenario ... --online`: the robots map online as processes; compared with the
// in-process twin (online/online_team.h, RunOnline with the processes' solver): the same group
// solves, and every map each robot saved (after each solve, and at the end) equal to the twin's.
int RunOnlineTeam(const TeamArgs& a, const ScenarioSpec& spec, const ScenarioFlags& flags,
                  const fs::path& out) {
  const int n = spec.robots;
  std::vector<std::string> source = ScenarioArgs(flags);
  source.push_back("--online");
  const TeamRun run = RunTeamRobots(a, out, n, source);

  nlohmann::json j = ScenarioJson(spec);
  j["robots"] = n;
  j["poses_per_robot"] = spec.poses_per_robot;
  j["online"] = true;
  j["out"] = out.string();
  j["seconds"] = run.seconds;
  const OnlineSummaries robots = ReadOnlineSummaries(out, n, run.exit_codes);
  if (!robots.ok) {
    ReportFailedRobots(robots.per_robot);
    j["ok"] = false;
    j["per_robot"] = robots.per_robot;
    if (a.json) fmt::print("{}\n", j.dump());
    return 1;
  }
  const DgsNodeOptions node = NodeOptions(OnlineSolveFlags(a.solve));
  const bool robust = node.gnc.has_value();
  const OnlineRun twin = RunOnlineTwin(node, spec);
  const OnlineComparison c = CompareWithTwin(out, robots.summaries, twin);
  bool ok = c.same_solves;
  if (c.set_aside != c.twin_set_aside) {
    ok = false;
    fmt::print(stderr,
               "moslam: the robots set aside {} pairs, the in-process twin {} (or others)\n",
               c.set_aside.size(), c.twin_set_aside.size());
  }
  std::int64_t cloud_bytes = 0;  // the paper's alternative: one 640 x 480 x 32 B frame per robot
  for (const GroupSolveRecord& g : twin.solves) {
    cloud_bytes += static_cast<std::int64_t>(g.robots.size()) * 640 * 480 * 32;
  }
  const double solves = std::max<double>(1.0, static_cast<double>(twin.solves.size()));
  ok = ok && c.mismatched == 0;
  j["rendezvous_events"] = c.events;
  j["group_solves"] = twin.solves.size();
  j["robust"] = robust;
  j["set_aside"] = c.set_aside.size();  // pairs set aside at the end (--robust)
  j["in_process_set_aside"] = c.twin_set_aside.size();
  j["unlinked_solves"] = c.unlinked;  // group solves the check left unlinked (--robust)
  j["maps_compared"] = c.maps;
  j["max_difference"] = c.largest;
  j["rendezvous_dds_bytes"] = c.objects_bytes;
  j["solve_dds_bytes"] = c.solve_bytes;
  j["dds_bytes_per_solve"] = static_cast<double>(c.objects_bytes + c.solve_bytes) / solves;
  j["point_cloud_bytes_per_solve"] = static_cast<double>(cloud_bytes) / solves;
  PrintOnlineReport(spec, run.seconds, twin.solves.size(), robust, c, j);
  j["ok"] = ok;
  j["per_robot"] = robots.per_robot;
  fmt::print("maps in {}/robot<R>/maps\n", out.string());
  if (a.json) fmt::print("{}\n", j.dump());
  return ok ? 0 : 1;
}

// The rendezvous as the robots' summaries report them: the shared pairs (beta robot, beta
// landmark, alpha robot, alpha landmark), the bytes and samples, the events (counted once, by
// alpha).
struct RendezvousTotals {
  std::set<std::vector<std::uint64_t>> shared;
  std::int64_t binary = 0, dds = 0, samples = 0;
  int events = 0;
};

RendezvousTotals SumRendezvous(const std::map<int, JsonFields>& summaries) {
  RendezvousTotals t;
  for (const auto& [r, s] : summaries) {
    for (const JsonFields& p : s.items("shared")) {
      t.shared.insert(p.as<std::vector<std::uint64_t>>());
    }
    t.binary += s.get<std::int64_t>("rendezvous_binary_bytes");
    t.dds += s.get<std::int64_t>("rendezvous_dds_bytes");
    t.samples += s.get<std::int64_t>("rendezvous_dds_samples");
    for (const JsonFields& e : s.items("rendezvous")) t.events += e.get<int>("alpha") == r ? 1 : 0;
  }
  return t;
}

// The in-process pipeline on the processes' scenario (RunMultiRobotObjectSlam,
// AssembleJointProblem, RunDgs in Jacobi order, or the robust solve), against the processes'
// rendezvous and results; whether they agree.
bool CompareScenarioWithInProcess(const TeamArgs& a, const ScenarioSpec& spec, const TeamResults& t,
                                  const fs::path& out, nlohmann::json& j) {
  const RendezvousTotals rdv = SumRendezvous(t.summaries);
  const SimulationData data = SimulateScenario(spec);
  const MultiRobotSlamConfig config = ScenarioSlamConfig(spec);
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, config);
  const JointProblem joint =
      AssembleJointProblem(slam.robots, slam.shared, config.rendezvous.lambda());
  std::set<std::vector<std::uint64_t>> reference_shared;
  for (const SharedObject& o : slam.shared) {
    reference_shared.insert({static_cast<std::uint64_t>(o.beta_object.robot), o.beta_object.index,
                             static_cast<std::uint64_t>(o.alpha_object.robot),
                             o.alpha_object.index});
  }
  j["rendezvous_events"] = rdv.events;
  j["in_process_rendezvous_events"] = slam.rendezvous.size();
  j["shared_objects"] = rdv.shared.size();
  j["in_process_shared_objects"] = slam.shared.size();
  j["shared_objects_equal"] = rdv.shared == reference_shared;
  j["rendezvous_binary_bytes"] = rdv.binary;
  j["in_process_rendezvous_bytes"] = slam.bytes;
  j["rendezvous_dds_samples"] = rdv.samples;
  j["rendezvous_dds_bytes"] = rdv.dds;
  if (!joint.unanchored_robots.empty()) {
    fmt::print(stderr, "moslam: in-process reference: robot {} is not linked to robot 0\n",
               joint.unanchored_robots.front());
    return false;
  }
  fmt::print(
      "{} with {} robots (seed {}, {} poses each) as processes on loopback (domain {}): "
      "{:.2f} s\n",
      spec.scenario, spec.robots, spec.seed, spec.poses_per_robot, a.domain, t.seconds);
  fmt::print(
      "rendezvous: {} events, {} shared objects (in-process {}, {}), {} B in-process "
      "encoding (in-process run {} B), {} B DDS payload in {} samples\n",
      rdv.events, rdv.shared.size(), slam.shared.size(),
      rdv.shared == reference_shared ? "the same pairs" : "DIFFERENT pairs", rdv.binary, slam.bytes,
      rdv.dds, rdv.samples);
  const DgsNodeOptions node = NodeOptions(a.solve);
  const DgsResult reference = RunDgs(joint.graph, joint.initial, DriverOptions(node));
  std::optional<RobustDgsResult> robust;
  if (node.gnc) {  // as the robot sessions
    robust = RunRobustDgs(joint.graph, joint.initial, ObjectFactors(joint.graph),
                          ReferenceRobustOptions(node));
  }
  G2oWriteOptions write;
  write.scheme = KeyScheme::kWithObjects;
  CompareWithInProcess(t, joint.graph, reference, out, write, j, robust ? &*robust : nullptr);
  return true;
}

// `moslam team --scenario ...` in batch mode: the robots map, meet and solve once at the end.
int RunBatchScenarioTeam(const TeamArgs& a, const ScenarioSpec& spec, const ScenarioFlags& flags,
                         const fs::path& out) {
  const int n = spec.robots;
  const TeamResults t = RunTeamProcesses(a, out, n, ScenarioArgs(flags), true);
  bool ok = t.ok;
  nlohmann::json j = ScenarioJson(spec);
  j["robots"] = n;
  j["poses_per_robot"] = spec.poses_per_robot;
  j["domain"] = a.domain;
  j["out"] = out.string();
  j["seconds"] = t.seconds;
  if (ok) {
    ok = CompareScenarioWithInProcess(a, spec, t, out, j);
  } else {
    ReportFailedRobots(t.per_robot);
  }
  j["ok"] = ok;
  j["per_robot"] = t.per_robot;
  fmt::print("results in {}\n", out.string());
  if (a.json) fmt::print("{}\n", j.dump());
  return ok ? 0 : 1;
}

// `moslam team --scenario ...`: the robots of a simulated scenario as processes, compared with
// the in-process pipeline (RunMultiRobotObjectSlam, AssembleJointProblem, RunDgs in Jacobi order).
int RunScenarioTeam(const TeamArgs& a) {
  ScenarioFlags flags = a.scenario;
  if (a.robots > 0) flags.spec.robots = a.robots;
  const ScenarioSpec spec = flags.get();
  spec.validate();
  if (spec.robots > kMaxRobotsWithObjects) {
    throw InvalidInputError(
        fmt::format("team: at most {} robots (results are g2o files with "
                    "objects), got --robots {}",
                    kMaxRobotsWithObjects, spec.robots));
  }
  const fs::path out = a.out.empty()
                           ? fs::temp_directory_path() / fmt::format("moslam_team_{}", ::getpid())
                           : fs::path(a.out);
  CheckScenarioFlags("team", a.online, spec);
  CreateFolder(out, "team --out");
  if (a.online) return RunOnlineTeam(a, spec, flags, out);
  return RunBatchScenarioTeam(a, spec, flags, out);
}

int RunTeam(const TeamArgs& args) {
  if (!args.scenario.name.empty()) return RunScenarioTeam(args);
  if (args.data.empty()) throw InvalidInputError("team: give --data <folder | file> or --scenario <name>");
  if (args.online) throw InvalidInputError("team: --online needs --scenario (the robots map as they go)");
  TeamArgs a = args;
  const fs::path out = a.out.empty() ? fs::temp_directory_path() /
                                           fmt::format("moslam_team_{}", ::getpid())
                                     : fs::path(a.out);
  CreateFolder(out, "team --out");
  if (fs::is_regular_file(a.data)) {
    // A single-robot file: split into --robots contiguous blocks of poses, one file each.
    if (a.robots < 1) throw InvalidInputError("team: a single g2o file needs --robots N");
    const Dataset single = ReadG2oFile(a.data);
    const SplitGraph split = SplitIntoRobots(single.graph, single.initial, a.robots);
    const fs::path folder = out / "data";
    WriteG2oFolder(folder.string(), split.graph, split.initial);
    fmt::print("{} split into {} robots: {}\n", a.data, a.robots, folder.string());
    a.data = folder.string();
    // Robust: the file's loop closures, as `moslam dgs <file> --robots N --robust`.
    a.solve.robust_loop_closures = a.solve.robust;
  }
  if (a.prepare_only) return 0;
  const int files = CountRobotFiles(a.data);
  if (files == 0) throw InvalidInputError("team: " + a.data + " holds no 0.g2o");
  const int n = a.robots > 0 ? a.robots : files;
  if (n != files) {
    throw InvalidInputError(fmt::format("team: --robots {} but {} holds {} robot files (0.g2o .. "
                                        "{}.g2o): every robot of the folder takes part",
                                        n, a.data, files, files - 1));
  }
  const TeamResults t = RunTeamProcesses(a, out, n, {"--data", a.data}, false);

  nlohmann::json j;
  j["robots"] = n;
  j["domain"] = a.domain;
  j["out"] = out.string();
  j["seconds"] = t.seconds;
  j["ok"] = t.ok;
  j["per_robot"] = t.per_robot;
  if (t.ok) {
    const Dataset full = ReadG2oFolder(a.data);
    fmt::print("team of {} on loopback (domain {}): {:.2f} s\n", n, a.domain, t.seconds);
    const DgsNodeOptions node = NodeOptions(a.solve);
    const DgsResult reference = RunDgs(full.graph, full.initial, DriverOptions(node));
    std::optional<RobustDgsResult> robust;
    if (node.gnc) {  // as the nodes
      robust = RunRobustDgs(full.graph, full.initial,
                            a.solve.robust_loop_closures ? LoopClosureFactors(full.graph)
                                                         : SeparatorFactors(full.graph),
                            ReferenceRobustOptions(node));
    }
    CompareWithInProcess(t, full.graph, reference, out, G2oWriteOptions{}, j,
                         robust ? &*robust : nullptr);
  } else {
    ReportFailedRobots(t.per_robot);
  }
  fmt::print("results in {}\n", out.string());
  if (a.json) fmt::print("{}\n", j.dump());
  return t.ok ? 0 : 1;
}

}  // namespace

Runner RegisterTeam(CLI::App& app) {
  auto args = std::make_shared<TeamArgs>();
  CLI::App* sub = app.add_subcommand("team", kTeamDescription);
  auto* data = sub->add_option("--data", args->data,
                               "Distributed-mapper folder (0.g2o .. N-1.g2o), or one single-robot "
                               "g2o file split into --robots contiguous blocks of poses (written "
                               "to <out>/data)")
                   ->check(CLI::ExistingPath);
  AddScenarioFlags(sub, args->scenario, false);
  data->excludes(sub->get_option("--scenario"));
  sub->add_option("--robots", args->robots, "Number of robots (default: every file)")
      ->check(Positive());
  sub->add_flag("--prepare", args->prepare_only,
                "Only write the split data folder (single-file --data) and exit");
  sub->add_flag("--collect", args->collect_only,
                "Start nothing: collect the results already in <out>/robot<R>/ (robots started "
                "elsewhere, e.g. in network namespaces) and compare");
  sub->add_option("--domain", args->domain, "DDS domain id (0..232)")->check(CLI::Range(0, 232));
  sub->add_option("--out", args->out, "Directory for robot<R>/ state and results");
  AddSolveFlags(sub, args->solve);
  sub->add_option("--timeout", args->timeout, "Seconds before the robots are killed")
      ->check(Positive());
  sub->add_flag("--online", args->online,
                "With --scenario: the robots solve with the robots in range at every rendezvous "
                "(moslam robot --online) and save their maps; compared with the in-process twin");
  sub->add_flag("--json", args->json, "Last line: one JSON object with the summary");
  return [args]() { return RunTeam(*args); };
}

}  // namespace moslam::cli
