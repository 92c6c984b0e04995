// `moslam robot`: one robot as its own process, talking to the others over Cyclone DDS.
// `moslam team`: starts N such processes on loopback and collects their results.
#include <fcntl.h>
#include <fmt/core.h>
#include <fmt/ranges.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "commands.h"
#include "moslam/common/errors.h"
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
#include "robust_flags.h"
#include "solver_flags.h"

namespace moslam::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct SolveFlags {
  SolverArgs solver;  // the same solver flags as `moslam dgs` (the robots solve in Jacobi order)
  double leave_timeout = 15.0;  // seconds
  double join_timeout = 60.0;
  double stall_timeout = 300.0;
  bool robust = false;
  RobustSolveArgs robust_args;  // --separator-test, --gnc-threshold, --separator-support
};

void AddSolveFlags(CLI::App* sub, SolveFlags& f) {
  AddSolverFlags(sub, &f.solver);
  sub->add_flag("--robust", f.robust,
                "GNC-TLS around the solver, run by the robots (weights on the wire), after the "
                "pairwise check of the separators (map covariances on the wire), as `moslam dgs "
                "--robust`: the separators robust, and with --scenario the object measurements "
                "too (the refinement is forced on); with --online at every group solve, as "
                "`moslam simulate --online --robust` (pairs rejected set aside until their robots "
                "meet again)");
  AddRobustSolveFlags(sub, &f.robust_args);
  sub->add_option("--leave-timeout", f.leave_timeout,
                  "Seconds a waited-for robot may be unreachable before it counts as gone (one "
                  "never heard from too: start every robot within this of its first rendezvous)")
      ->check(Positive());
  sub->add_option("--join-timeout", f.join_timeout, "Seconds to wait for the team to form")
      ->check(Positive());
  sub->add_option("--stall-timeout", f.stall_timeout, "Seconds without progress before failing")
      ->check(Positive());
}

std::chrono::milliseconds Ms(double seconds) {
  return std::chrono::milliseconds(static_cast<std::int64_t>(seconds * 1000.0));
}

DgsNodeOptions NodeOptions(const SolveFlags& f) {
  DgsNodeOptions o;
  o.solver = f.solver.options(SweepOrder::kJacobi);
  o.leave_timeout = Ms(f.leave_timeout);
  o.join_timeout = Ms(f.join_timeout);
  o.stall_timeout = Ms(f.stall_timeout);
  o.finish_timeout = Ms(std::max(10.0, f.leave_timeout + 5.0));
  if (f.robust) {
    RobustDgsOptions r;
    f.robust_args.applyTo(&r);
    o.gnc = r.gnc;
    if (r.check_separators) o.separator_check = r.consistency;
    o.retest_left_out = r.retest_left_out;
    o.retest_groups = r.retest_groups;
    o.solver.refine = true;
  }
  return o;
}

// The in-process reference of a robust team: RunRobustDgs with the processes' solver, GNC
// options and separator check.
RobustDgsOptions ReferenceRobustOptions(const DgsNodeOptions& o) {
  RobustDgsOptions r;
  r.dgs = DriverOptions(o);
  r.gnc = *o.gnc;
  r.check_separators = o.separator_check.has_value();
  if (o.separator_check) r.consistency = *o.separator_check;
  r.retest_left_out = o.retest_left_out;
  r.retest_groups = o.retest_groups;
  return r;
}

std::vector<std::string> SolveArgs(const SolveFlags& f) {
  std::vector<std::string> a = f.solver.args();
  for (const std::string& s :
       {std::string("--leave-timeout"), fmt::format("{}", f.leave_timeout),
        std::string("--join-timeout"), fmt::format("{}", f.join_timeout),
        std::string("--stall-timeout"), fmt::format("{}", f.stall_timeout)}) {
    a.push_back(s);
  }
  if (f.robust) {
    a.push_back("--robust");
    for (const std::string& s : f.robust_args.args()) a.push_back(s);
  }
  return a;
}

// ---- moslam robot ------------------------------------------------------------------------

// The simulated scenario of `moslam robot --scenario` and `moslam team --scenario`.
struct ScenarioFlags {
  std::string name;  // --scenario; empty: not a scenario run
  ScenarioSpec spec;
  double rendezvous_timeout = 60.0;  // seconds
  std::string initial_poses = "known";
  ScenarioSpec get() const {
    ScenarioSpec s = spec;
    s.scenario = name;
    s.known_initial_poses = initial_poses == "known";
    return s;
  }
};

// `with_robots`: also --robots (moslam team has its own). Every flag but --scenario needs it:
// given with --data (a g2o folder has none of them) it is an error, not ignored.
void AddScenarioFlags(CLI::App* sub, ScenarioFlags& f, bool with_robots) {
  const std::size_t before = sub->get_options().size();
  CLI::Option* scenario = sub->add_option("--scenario", f.name,
                  "Simulated scenario (chairs25 | house | generated): every process simulates it "
                  "and keeps its own robot's measurements")
      ->check(CLI::IsMember({"chairs25", "house", "generated"}));
  if (with_robots) {
    sub->add_option("--robots", f.spec.robots, "Robots of the scenario")->check(Positive());
  }
  sub->add_option("--seed", f.spec.seed, "Seed of the world, trajectories and noise");
  sub->add_option("--sigma-rot", f.spec.sigma_rotation_deg, "Noise: rotation sigma (deg)")
      ->check(NonNegative());
  sub->add_option("--sigma-trans", f.spec.sigma_translation, "Noise: translation sigma (m)")
      ->check(NonNegative());
  sub->add_option("--poses", f.spec.poses_per_robot, "Poses per robot")->check(CLI::Range(2, 100000));
  sub->add_option("--rendezvous-timeout", f.rendezvous_timeout,
                  "Seconds to wait for the peer of a rendezvous")
      ->check(Positive());
  sub->add_option("--initial-poses", f.initial_poses,
                  "known: the robots know one another's initial poses (the paper); unknown: a "
                  "rendezvous aligns the two object maps from the objects alone, and no process "
                  "is given the initial poses")
      ->check(CLI::IsMember({"known", "unknown"}));
  sub->add_option("--exclusion-radius", f.spec.exclusion_radius,
                  "A robot's landmark exclusion radius (m, 0: off): a detection that joins no "
                  "landmark but lies this close to one of its label is discarded (as simulate)")
      ->check(NonNegative());
  sub->add_flag("--leave-one-out-check", f.spec.leave_one_out_check,
                "A robot re-tests each match of a pose at the pose localised on its other "
                "matches, and refuses the ones that disagree (as simulate)");
  sub->add_flag("--loop-closure", f.spec.loop_closure,
                "A robot aligns its recent landmarks with its older ones and joins the objects it "
                "mapped twice (as simulate; not with --online)");
  sub->add_flag("--rendezvous-constellation", f.spec.rendezvous_constellation,
                "Known initial poses: a rendezvous also aligns the two object maps by their "
                "constellation and takes that transform when more of its matches agree pairwise "
                "(as simulate; not with --online)");
  const std::vector<CLI::Option*> options = sub->get_options();
  for (std::size_t i = before; i < options.size(); ++i) {
    if (options[i] != scenario) options[i]->needs(scenario);
  }
}

// Refuses what the online mission does not run, and a refinement of initial poses the robots do
// not know (`who`: robot or team).
void CheckScenarioFlags(const char* who, bool online, const ScenarioSpec& spec) {
  if (online && (spec.loop_closure || spec.rendezvous_constellation)) {
    throw InvalidInputError(fmt::format("{}: --loop-closure and --rendezvous-constellation are not "
                                        "part of the online mission (--online)",
                                        who));
  }
  if (spec.rendezvous_constellation && !spec.known_initial_poses) {
    throw InvalidInputError(fmt::format("{}: {}", who, kConstellationNeedsKnownPoses));
  }
}

std::vector<std::string> ScenarioArgs(const ScenarioFlags& f) {
  std::vector<std::string> a = {
      "--scenario", f.name, "--robots", std::to_string(f.spec.robots), "--seed",
      std::to_string(f.spec.seed), "--sigma-rot", fmt::format("{}", f.spec.sigma_rotation_deg),
      "--sigma-trans", fmt::format("{}", f.spec.sigma_translation), "--poses",
      std::to_string(f.spec.poses_per_robot), "--rendezvous-timeout",
      fmt::format("{}", f.rendezvous_timeout), "--initial-poses", f.initial_poses,
      "--exclusion-radius", fmt::format("{}", f.spec.exclusion_radius)};
  if (f.spec.leave_one_out_check) a.push_back("--leave-one-out-check");
  if (f.spec.loop_closure) a.push_back("--loop-closure");
  if (f.spec.rendezvous_constellation) a.push_back("--rendezvous-constellation");
  return a;
}

G2oReadOptions WithObjects() {
  G2oReadOptions o;
  o.scheme = KeyScheme::kWithObjects;
  return o;
}

struct RobotArgs {
  int robot = 0;
  std::string data;
  ScenarioFlags scenario;
  int domain = 0;
  std::string out;
  SolveFlags solve;
  bool online = false;
  bool progress = false;
  bool json = false;
};

// --online: the whole solver at every rendezvous (two-level, error-bound rule, refinement), as
// `moslam simulate --online` (OnlineOptions::DefaultSolver); the other solver flags still apply.
SolveFlags OnlineSolveFlags(SolveFlags f) {
  f.solver.refine = true;
  f.solver.stopping = "error-bound";
  return f;
}

nlohmann::json SolveJson(const SessionSolve& s) {
  return {{"step", s.step},
          {"robots", s.robots},
          {"object_object", s.object_object},
          {"team_factors", s.team_factors},
          {"rotation_rounds", s.rotation_rounds},
          {"pose_rounds", s.pose_rounds},
          {"refine_steps", s.refine_steps},
          {"protocol_steps", s.protocol_steps},
          {"refine_status", ToString(s.refine_status)},
          {"dds_estimate_bytes", s.sent.estimates_bytes},
          {"dds_status_bytes", s.sent.status_bytes},
          {"dds_coarse_bytes", s.sent.coarse_bytes},
          {"dds_sent_bytes", s.sent.sent_bytes},
          {"replayed", s.replayed},
          {"unlinked", s.unlinked},  // --robust: the check left the group unlinked: not solved
          {"set_aside", s.set_aside},  // --robust: its pairs set aside after it
          {"observation_outliers", s.observation_outliers},  // its own factors rejected
          {"seconds", s.seconds}};
}

nlohmann::json Summary(const RobotArgs& a, const DgsNodeResult& r) {
  nlohmann::json j;
  j["robot"] = a.robot;
  j["team"] = r.team;
  j["left"] = r.left;
  j["rotation_rounds"] = r.rotation_rounds;
  j["pose_rounds"] = r.pose_rounds;
  j["rotation_converged"] = r.rotation_converged;
  j["pose_converged"] = r.pose_converged;
  j["incarnation"] = r.incarnation;
  j["replayed_rounds"] = r.replayed_rounds;
  j["estimate_messages"] = r.estimate_messages;
  j["estimate_binary_bytes"] = r.estimate_binary_bytes;
  j["coarse_messages"] = r.coarse_messages;
  j["coarse_binary_bytes"] = r.coarse_binary_bytes;
  j["rotation_coarse_corrections"] = r.program.rotation.coarse_corrections;
  j["pose_coarse_corrections"] = r.program.pose.coarse_corrections;
  j["refine_steps"] = r.program.refine.iterations;
  j["refine_sweeps"] = r.program.refine.sweeps;
  j["refine_status"] = ToString(r.program.refine.status);
  j["refine_final_cost"] = r.program.refine.final_cost;
  j["protocol_steps"] = r.robust ? r.robust->channel_steps : r.program.channel_steps;
  if (r.robust) {
    j["gnc_status"] = ToString(r.robust->status);
    j["gnc_rounds"] = r.robust->iterations;
    j["outliers"] = r.robust->outliers;  // robust factors of its subgraph with weight < 0.5
    j["readmitted"] = r.robust->readmitted;
    j["retests"] = r.robust->retests;  // --retest-left-out: the team's
    j["retest_readmitted"] = r.robust->retest_readmitted;  // of those, its own back
    j["group_retests"] = r.robust->group_retests;          // the team's groups re-tested
    j["group_readmitted"] = r.robust->group_readmitted;    // of those, its own back
    j["polished"] = r.robust->polished;
    j["polish_refused"] = r.robust->polish_refused;  // it raised the inliers' cost: not kept
    j["weight_messages"] = r.weight_messages;
    j["weight_binary_bytes"] = r.weight_binary_bytes;
    j["dds_weight_bytes"] = r.transport.weights_bytes;
    // The separator check: separators to higher robots it left out, and the messages it sent
    // for it (map estimates, covariances, estimates for the readmission).
    j["check_rejected"] = r.robust->check_rejected;
    j["check_deferred"] = r.robust->check_deferred;
    j["check_messages"] = r.robust->check_messages;
    j["check_binary_bytes"] = r.robust->check_bytes;
    j["dds_covariance_bytes"] = r.transport.covariances_bytes;
  }
  j["dds_estimate_bytes"] = r.transport.estimates_bytes;
  j["dds_coarse_bytes"] = r.transport.coarse_bytes;
  j["dds_status_samples"] = r.transport.status_sent;
  j["dds_status_bytes"] = r.transport.status_bytes;
  j["dds_sent_samples"] = r.transport.sent_samples;
  j["dds_sent_bytes"] = r.transport.sent_bytes;
  j["dds_received_bytes"] = r.transport.received_bytes;
  j["rejected_samples"] = r.transport.rejected + r.rejected_estimates;
  j["variables"] = r.estimate.size();
  j["seconds"] = r.seconds;
  j["out"] = a.out;
  return j;
}

nlohmann::json SharedJson(const std::vector<SharedObject>& shared) {
  nlohmann::json j = nlohmann::json::array();
  for (const SharedObject& o : shared) {
    j.push_back({o.beta_object.robot, o.beta_object.index, o.alpha_object.robot,
                 o.alpha_object.index});
  }
  return j;
}

nlohmann::json RendezvousJson(const RobotSessionResult& r) {
  nlohmann::json events = nlohmann::json::array();
  for (const SessionRendezvous& e : r.rendezvous) {
    events.push_back({{"step", e.event.step}, {"alpha", e.event.alpha}, {"beta", e.event.beta},
                      {"objects_sent", e.objects_sent}, {"new_shared", e.new_shared},
                      {"removed_shared", e.removed_shared},
                      {"binary_bytes", e.binary_bytes}, {"replayed", e.replayed},
                      {"skipped", e.skipped}, {"seconds", e.seconds}});
  }
  return events;
}

// What a scenario robot's summary says in both modes: its map and its rendezvous.
void AddSessionSummary(const ScenarioSpec& spec, const RobotSessionResult& r, nlohmann::json& j) {
  j["scenario"] = spec.scenario;
  j["seed"] = spec.seed;
  j["initial_poses"] = spec.known_initial_poses ? "known" : "unknown";
  j["exclusion_radius"] = spec.exclusion_radius;
  j["leave_one_out_check"] = spec.leave_one_out_check;
  j["loop_closure"] = spec.loop_closure;
  j["rendezvous_constellation"] = spec.rendezvous_constellation;
  j["poses"] = r.poses;
  j["landmarks"] = r.landmarks;
  j["shared"] = SharedJson(r.shared);
  j["rendezvous"] = RendezvousJson(r);
  j["left_team"] = r.left_team;  // the team had found it gone: it mapped alone from then on
  j["rendezvous_binary_bytes"] = r.rendezvous_binary_bytes;
  j["rendezvous_dds_samples"] = r.rendezvous_transport.objects_sent;
  j["rendezvous_dds_bytes"] = r.rendezvous_transport.objects_bytes;
}

// `moslam robot --scenario ... --online`: its summary (the group solves) and the last line.
int ReportOnlineRobot(const RobotArgs& a, const ScenarioSpec& spec, const RobotSessionResult& r) {
  nlohmann::json j;
  j["robot"] = a.robot;
  j["online"] = true;
  AddSessionSummary(spec, r, j);
  nlohmann::json solves = nlohmann::json::array();
  std::int64_t dgs_bytes = 0;
  for (const SessionSolve& s : r.solves) {
    solves.push_back(SolveJson(s));
    dgs_bytes += s.sent.sent_bytes;
  }
  j["solves"] = solves;
  j["solve_dds_bytes"] = dgs_bytes;
  j["set_aside"] = SharedJson(r.set_aside);  // --robust: its pairs set aside at the end
  j["seconds"] = r.seconds;
  j["out"] = a.out;
  if (!a.out.empty()) std::ofstream(fs::path(a.out) / "summary.json") << j.dump(2) << "\n";
  fmt::print("robot {}: {} rendezvous, {} shared objects ({} B DDS payload sent), {} group solves "
             "({} B DDS payload sent), {:.3f} s{}\n",
             a.robot, r.rendezvous.size(), r.shared.size(), r.rendezvous_transport.objects_bytes,
             r.solves.size(), dgs_bytes, r.seconds,
             a.out.empty() ? "" : fmt::format("; maps in {}/maps", a.out));
  if (a.json) fmt::print("{}\n", j.dump());
  return 0;
}

// `moslam robot --scenario ...`: SLAM, rendezvous over DDS, DGS (transport/robot_session.h).
int RunScenarioRobot(const RobotArgs& a) {
  const ScenarioSpec spec = a.scenario.get();
  if (a.robot >= spec.robots) {
    throw InvalidInputError(fmt::format("robot: --robot {} but the scenario has {} robots (--robots)",
                                        a.robot, spec.robots));
  }
  if (!a.out.empty() && spec.robots > kMaxRobotsWithObjects) {
    throw InvalidInputError(fmt::format("robot: --out writes g2o files with objects, which hold "
                                        "at most {} robots (--robots {})",
                                        kMaxRobotsWithObjects, spec.robots));
  }
  CheckScenarioFlags("robot", a.online, spec);
  RobotSessionOptions options;
  options.slam = ScenarioSlamConfig(spec);
  options.dgs = NodeOptions(a.online ? OnlineSolveFlags(a.solve) : a.solve);
  options.dgs.state_dir = a.out;
  options.online = a.online;
  options.rendezvous_timeout = Ms(a.scenario.rendezvous_timeout);
  if (a.progress) {
    options.dgs.on_round = [](const DgsNodeRound& r) {
      fmt::print("progress: {} {} step {} {}{}\n", ToString(r.stage), r.stage_round, r.round,
                 r.sent ? "sent" : "-", r.replayed ? " replayed" : "");
      std::fflush(stdout);
    };
    options.on_rendezvous = [](const SessionRendezvous& r) {
      fmt::print("rendezvous: step {} alpha {} beta {} shared {}{}\n", r.event.step, r.event.alpha,
                 r.event.beta, r.new_shared,
                 r.replayed ? " replayed" : (r.skipped ? " skipped (peer left)" : ""));
      std::fflush(stdout);
    };
  }
  if (a.online) {
    options.on_solve = [&a](const SessionSolve& s) {
      fmt::print("group solve: step {} robots {} rounds {} + {}, {} refinement steps, {} B sent, "
                 "{:.3f} s{}{}\n",
                 s.step, fmt::join(s.robots, ","), s.rotation_rounds, s.pose_rounds,
                 s.refine_steps, s.sent.sent_bytes, s.seconds,
                 a.out.empty() ? "" : fmt::format(", map in {}/maps/step_{:04d}", a.out, s.step),
                 s.replayed ? " replayed" : "");
      std::fflush(stdout);
    };
  }
  DdsTransportOptions transport_options;
  transport_options.domain = a.domain;
  DdsTransport transport(a.robot, transport_options);
  // Every process simulates the same scenario and keeps only its own slice.
  RobotSession session(SliceForRobot(SimulateScenario(spec), a.robot, spec.known_initial_poses),
                       transport, options);
  const RobotSessionResult r = session.run();
  if (a.online) return ReportOnlineRobot(a, spec, r);
  nlohmann::json j = Summary(a, r.dgs);
  AddSessionSummary(spec, r, j);
  j["slam_seconds"] = r.slam_seconds;
  j["seconds"] = r.seconds;
  if (!a.out.empty()) std::ofstream(fs::path(a.out) / "summary.json") << j.dump(2) << "\n";
  fmt::print("robot {}: {} rendezvous, {} shared objects ({} B in-process encoding, {} B DDS "
             "payload sent); DGS team {}, rotation {} rounds, pose {} rounds, {:.3f} s{}\n",
             a.robot, r.rendezvous.size(), r.shared.size(), r.rendezvous_binary_bytes,
             r.rendezvous_transport.objects_bytes, fmt::join(r.dgs.team, ","),
             r.dgs.rotation_rounds, r.dgs.pose_rounds, r.seconds,
             r.dgs.incarnation ? fmt::format(" (restart {})", r.dgs.incarnation) : "");
  if (a.json) fmt::print("{}\n", j.dump());
  return 0;
}

int RunRobot(const RobotArgs& a) {
  if (!a.scenario.name.empty()) return RunScenarioRobot(a);
  if (a.online) throw InvalidInputError("robot: --online needs --scenario (it maps as it goes)");
  if (a.data.empty()) throw InvalidInputError("robot: give --data <folder> or --scenario <name>");
  const std::string file = RobotFile(a.data, a.robot);
  const Dataset data = ReadRobotG2o(file);
  DgsNodeOptions options = NodeOptions(a.solve);
  options.state_dir = a.out;
  if (a.progress) {
    options.on_round = [](const DgsNodeRound& r) {
      fmt::print("progress: {} {} step {} {}{}\n", ToString(r.stage), r.stage_round, r.round,
                 r.sent ? "sent" : "-", r.replayed ? " replayed" : "");
      std::fflush(stdout);
    };
  }
  DdsTransportOptions transport_options;
  transport_options.domain = a.domain;
  DdsTransport transport(a.robot, transport_options);
  DgsNode node(a.robot, data.graph, data.initial, transport, options);
  const DgsNodeResult r = node.run();
  const nlohmann::json j = Summary(a, r);
  if (!a.out.empty()) std::ofstream(fs::path(a.out) / "summary.json") << j.dump(2) << "\n";
  fmt::print("robot {}: team {}, rotation {} rounds, pose {} rounds{}, {} estimates sent "
             "({} B binary, {} B CDR), {:.3f} s{}\n",
             a.robot, fmt::join(r.team, ","), r.rotation_rounds, r.pose_rounds,
             r.left.empty() ? "" : fmt::format(", left: {}", fmt::join(r.left, ",")),
             r.estimate_messages, r.estimate_binary_bytes, r.transport.estimates_bytes,
             r.seconds, r.incarnation ? fmt::format(" (restart {})", r.incarnation) : "");
  if (!a.out.empty()) fmt::print("robot {}: result in {}\n", a.robot, (fs::path(a.out) / "result.g2o").string());
  if (a.json) fmt::print("{}\n", j.dump());
  return 0;
}

// ---- moslam team -------------------------------------------------------------------------

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

pid_t Spawn(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid < 0) throw Error("team: fork failed");
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::close(fd);
    }
    std::vector<char*> argv;
    for (const std::string& s : args) argv.push_back(const_cast<char*>(s.c_str()));
    argv.push_back(nullptr);
    ::execv("/proc/self/exe", argv.data());
    ::_exit(127);
  }
  return pid;
}

// Starts one process per argv (robot r: argvs[r], log in <out>/robot<r>/log.txt) on loopback
// (LoopbackConfigXml), waits for them all (killing them at the timeout: exit code -1) and returns
// their exit codes. `collect_only`: starts nothing, robot r counts as successful when
// <out>/robot<r>/summary.json exists.
std::map<int, int> RunRobotProcesses(const std::vector<std::vector<std::string>>& argvs, int domain,
                                     const fs::path& out, double timeout, bool collect_only) {
  const int n = static_cast<int>(argvs.size());
  std::map<int, int> exit_codes;
  if (collect_only) {
    for (int r = 0; r < n; ++r) {
      exit_codes[r] = fs::exists(out / fmt::format("robot{}", r) / "summary.json") ? 0 : 1;
    }
    return exit_codes;
  }
  const std::string config = LoopbackConfigXml(domain, n);
  ::setenv("CYCLONEDDS_URI", config.c_str(), 1);
  const auto t0 = Clock::now();
  std::map<pid_t, int> children;
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    fs::create_directories(dir);
    children[Spawn(argvs[static_cast<std::size_t>(r)], dir / "log.txt")] = r;
  }
  const auto deadline = t0 + Ms(timeout);
  while (exit_codes.size() < children.size()) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, WNOHANG);
    if (pid > 0 && children.count(pid)) {
      exit_codes[children[pid]] = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      continue;
    }
    if (Clock::now() > deadline) {
      for (const auto& [p, r] : children) {
        if (!exit_codes.count(r)) ::kill(p, SIGKILL);
      }
      for (const auto& [p, r] : children) {
        if (!exit_codes.count(r)) {
          ::waitpid(p, &status, 0);
          exit_codes[r] = -1;
        }
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return exit_codes;
}

// What `team` reads back from the robot folders <out>/robot<R>/ after the processes ended.
struct TeamResults {
  bool ok = true;  // every robot exited 0 and wrote its summary
  nlohmann::json per_robot = nlohmann::json::array();  // robot, exit_code, log or the summary
  std::map<int, nlohmann::json> summaries;             // robot -> summary, those that finished
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
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    const auto code = exit_codes.find(r);
    const int exit_code = code == exit_codes.end() ? 0 : code->second;
    nlohmann::json entry = {{"robot", r}, {"exit_code", exit_code}};
    if (exit_code != 0 || !fs::exists(dir / "summary.json")) {
      t.ok = false;
      entry["log"] = (dir / "log.txt").string();
      t.per_robot.push_back(entry);
      continue;
    }
    std::ifstream in(dir / "summary.json");
    const nlohmann::json s = nlohmann::json::parse(in);
    entry.update(s);
    entry.erase("shared");
    t.per_robot.push_back(entry);
    const Dataset result = ReadRobotG2o((dir / "result.g2o").string(),
                                        scenario ? WithObjects() : G2oReadOptions{});
    for (const auto& [k, x] : result.initial) {
      if (!scenario || k.robot == r) t.merged.emplace(k, x);
    }
    t.binary += s["estimate_binary_bytes"].get<std::int64_t>();
    t.cdr += s["dds_estimate_bytes"].get<std::int64_t>();
    t.status_bytes += s["dds_status_bytes"].get<std::int64_t>();
    t.messages += s["estimate_messages"].get<std::int64_t>();
    t.coarse_binary += s["coarse_binary_bytes"].get<std::int64_t>();
    t.coarse_cdr += s["dds_coarse_bytes"].get<std::int64_t>();
    t.coarse_messages += s["coarse_messages"].get<std::int64_t>();
    t.refine_steps = std::max(t.refine_steps, s["refine_steps"].get<int>());
    t.protocol_steps = std::max(t.protocol_steps, s["protocol_steps"].get<int>());
    t.refine_cost = s["refine_final_cost"].get<double>();
    t.rotation_rounds = std::max(t.rotation_rounds, s["rotation_rounds"].get<int>());
    t.pose_rounds = std::max(t.pose_rounds, s["pose_rounds"].get<int>());
    t.summaries[r] = s;
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
  if (robust) {
    std::int64_t messages = 0, binary = 0, dds = 0, check_binary = 0, check_dds = 0;
    int rounds = 0, outliers = 0, check_rejected = 0, retests = 0, retest_readmitted = 0;
    int group_retests = 0, group_readmitted = 0;
    for (const auto& [r, s] : t.summaries) {
      messages += s["weight_messages"].get<std::int64_t>();
      binary += s["weight_binary_bytes"].get<std::int64_t>();
      dds += s["dds_weight_bytes"].get<std::int64_t>();
      check_rejected += s["check_rejected"].get<int>();
      check_binary += s["check_binary_bytes"].get<std::int64_t>();
      check_dds += s["dds_covariance_bytes"].get<std::int64_t>();
      rounds = std::max(rounds, s["gnc_rounds"].get<int>());
      outliers += s["outliers"].get<int>();
      retests = std::max(retests, s["retests"].get<int>());
      retest_readmitted += s["retest_readmitted"].get<int>();
      group_retests = std::max(group_retests, s["group_retests"].get<int>());
      group_readmitted += s["group_readmitted"].get<int>();
    }
    j["gnc_rounds"] = rounds;
    j["in_process_gnc_rounds"] = robust->iterations;
    j["in_process_outliers"] = robust->outliers;
    j["robots_outliers"] = outliers;  // per robot, its subgraph's: a separator counts twice
    j["weight_messages"] = messages;
    j["weight_binary_bytes"] = binary;
    j["dds_weight_bytes"] = dds;
    j["in_process_weight_messages"] = robust->weight_messages;
    j["in_process_weight_bytes"] = robust->weight_bytes;
    j["check_rejected"] = check_rejected;
    j["in_process_check_rejected"] = robust->consistency_rejected;
    j["check_binary_bytes"] = check_binary;
    j["in_process_check_bytes"] = robust->consistency_bytes;
    j["dds_covariance_bytes"] = check_dds;
    j["retests"] = retests;
    j["retest_readmitted"] = retest_readmitted;
    j["in_process_retests"] = robust->retests;
    j["in_process_retest_readmitted"] = robust->retest_readmitted;
    j["group_retests"] = group_retests;
    j["group_readmitted"] = group_readmitted;
    j["in_process_group_retests"] = robust->group_retests;
    j["in_process_group_readmitted"] = robust->group_readmitted;
    fmt::print("separator check: {} separators left out (in-process {}); {} B binary for it "
               "(in-process {} B), {} B CDR payload of covariances\n",
               check_rejected, robust->consistency_rejected, check_binary,
               robust->consistency_bytes, check_dds);
    fmt::print("robust: {} GNC rounds (in-process {}), {} outliers in-process; {} weight "
               "messages, {} B binary, {} B CDR payload (in-process {}, {} B)\n",
               rounds, robust->iterations, robust->outliers, messages, binary, dds,
               robust->weight_messages, robust->weight_bytes);
  }
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
    // The centralized optimum in the same gauge (the anchor at its initial value).
    const Key anchor = GaugeAnchor(graph);
    const auto it = reference.values.find(anchor);
    const SE3 anchor_pose = it != reference.values.end() ? it->second : SE3();
    const OptimizerResult central = Optimize(graph, ChordalInitialization(graph, anchor_pose));
    j["refine_final_cost"] = t.refine_cost;
    j["in_process_refine_final_cost"] = reference.refine.final_cost;
    j["cost_centralized"] = central.final_cost;
    j["cost_relative_to_centralized"] = (j["cost"].get<double>() - central.final_cost) /
                                        central.final_cost;
    fmt::print("refinement: {} steps (in-process {}), cost F = {:.12g} (in-process {:.12g}, "
               "centralized optimum {:.12g}: {:+.2e} relative)\n",
               t.refine_steps, reference.refine.iterations, j["cost"].get<double>(),
               reference.refine.final_cost, central.final_cost,
               j["cost_relative_to_centralized"].get<double>());
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

void ReportFailedRobots(const nlohmann::json& per_robot) {
  for (const auto& r : per_robot) {
    if (r["exit_code"] != 0) {
      fmt::print(stderr, "moslam: robot {} failed (exit {}), see {}\n", r["robot"].get<int>(),
                 r["exit_code"].get<int>(), r.value("log", std::string()));
    }
  }
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
  const std::map<int, int>& exit_codes = run.exit_codes;
  const double seconds = run.seconds;

  nlohmann::json j;
  j["scenario"] = spec.scenario;
  j["robots"] = n;
  j["seed"] = spec.seed;
  j["initial_poses"] = spec.known_initial_poses ? "known" : "unknown";
  j["exclusion_radius"] = spec.exclusion_radius;
  j["leave_one_out_check"] = spec.leave_one_out_check;
  j["poses_per_robot"] = spec.poses_per_robot;
  j["online"] = true;
  j["out"] = out.string();
  j["seconds"] = seconds;
  bool ok = true;
  std::map<int, nlohmann::json> summaries;
  nlohmann::json per_robot = nlohmann::json::array();
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    const int code = exit_codes.count(r) ? exit_codes.at(r) : 0;
    if (code != 0 || !fs::exists(dir / "summary.json")) {
      ok = false;
      per_robot.push_back({{"robot", r}, {"exit_code", code}, {"log", (dir / "log.txt").string()}});
      continue;
    }
    std::ifstream in(dir / "summary.json");
    summaries[r] = nlohmann::json::parse(in);
    per_robot.push_back({{"robot", r}, {"exit_code", 0}, {"solves", summaries[r]["solves"].size()}});
  }
  if (!ok) {
    ReportFailedRobots(per_robot);
    j["ok"] = false;
    j["per_robot"] = per_robot;
    if (a.json) fmt::print("{}\n", j.dump());
    return 1;
  }
  OnlineOptions twin_options;
  const DgsNodeOptions node = NodeOptions(OnlineSolveFlags(a.solve));
  twin_options.solver = DriverOptions(node);
  if (node.gnc) twin_options.robust = ReferenceRobustOptions(node);  // its dgs: the solver
  const MultiRobotSlamConfig config = ScenarioSlamConfig(spec);
  twin_options.lambda = config.rendezvous.lambda();
  const OnlineRun twin = RunOnline(SimulateScenario(spec), config, twin_options);

  // Every map a robot saved against the twin's map of the same robot at the same time.
  double largest = 0.0;
  int maps = 0, mismatched = 0;
  std::int64_t objects_bytes = 0, solve_bytes = 0;
  int events = 0;
  // --robust: the pairs set aside at the end, by the robots (each holds its own) and the twin.
  const auto pair_of = [](const nlohmann::json& p) {
    return UnorderedPair(Key::Object(p[0].get<int>(), p[1].get<std::uint64_t>()),
                         Key::Object(p[2].get<int>(), p[3].get<std::uint64_t>()));
  };
  std::set<std::pair<Key, Key>> set_aside, twin_set_aside;
  for (const SharedObject& o : twin.set_aside) {
    twin_set_aside.insert(UnorderedPair(o.alpha_object, o.beta_object));
  }
  int unlinked = 0;
  for (const GroupSolveRecord& g : twin.solves) unlinked += g.unlinked ? 1 : 0;
  const auto compare = [&](const fs::path& file, const Values& reference) {
    const Dataset saved = ReadRobotG2o(file.string(), WithObjects());
    ++maps;
    if (saved.initial.size() != reference.size()) ++mismatched;
    largest = std::max(largest, MaxPoseDifference(saved.initial, reference));
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
    for (const auto& g : s["solves"]) {
      got.emplace_back(g["step"].get<int>(), g["robots"].get<std::vector<int>>());
      solve_bytes += g["dds_sent_bytes"].get<std::int64_t>();
      compare(dir / "maps" / fmt::format("step_{:04d}", got.back().first) / "map.g2o",
              twin.maps.at({got.back().first, r}));
    }
    if (got != expected) {
      ok = false;
      fmt::print(stderr, "moslam: robot {} took part in {} group solves, the in-process twin's "
                 "robot in {} (or in other groups)\n", r, got.size(), expected.size());
    }
    compare(dir / "maps" / "final" / "map.g2o",
            twin.slam.robots[static_cast<std::size_t>(r)].estimate());
    objects_bytes += s["rendezvous_dds_bytes"].get<std::int64_t>();
    for (const auto& e : s["rendezvous"]) events += e["alpha"].get<int>() == r ? 1 : 0;
    for (const auto& p : s.value("set_aside", nlohmann::json::array())) {
      set_aside.insert(pair_of(p));
    }
  }
  if (set_aside != twin_set_aside) {
    ok = false;
    fmt::print(stderr,
               "moslam: the robots set aside {} pairs, the in-process twin {} (or others)\n",
               set_aside.size(), twin_set_aside.size());
  }
  std::int64_t cloud_bytes = 0;  // the paper's alternative: one 640 x 480 x 32 B frame per robot
  for (const GroupSolveRecord& g : twin.solves) {
    cloud_bytes += static_cast<std::int64_t>(g.robots.size()) * 640 * 480 * 32;
  }
  const double solves = std::max<double>(1.0, static_cast<double>(twin.solves.size()));
  ok = ok && mismatched == 0;
  j["rendezvous_events"] = events;
  j["group_solves"] = twin.solves.size();
  j["robust"] = twin_options.robust.has_value();
  j["set_aside"] = set_aside.size();  // pairs set aside at the end (--robust)
  j["in_process_set_aside"] = twin_set_aside.size();
  j["unlinked_solves"] = unlinked;  // group solves the check left unlinked (--robust)
  j["maps_compared"] = maps;
  j["max_difference"] = largest;
  j["rendezvous_dds_bytes"] = objects_bytes;
  j["solve_dds_bytes"] = solve_bytes;
  j["dds_bytes_per_solve"] = static_cast<double>(objects_bytes + solve_bytes) / solves;
  j["point_cloud_bytes_per_solve"] = static_cast<double>(cloud_bytes) / solves;
  fmt::print("{} with {} robots (seed {}, {} poses each), online, as processes on loopback: "
             "{:.2f} s\n",
             spec.scenario, n, spec.seed, spec.poses_per_robot, seconds);
  fmt::print("{} rendezvous, {} group solves; {} saved maps against the in-process twin: largest "
             "difference {:.3g}{}\n",
             events, twin.solves.size(), maps, largest,
             mismatched ? fmt::format(" ({} of other sizes)", mismatched) : "");
  if (twin_options.robust) {
    fmt::print("robust: {} pairs set aside at the end (in-process twin {}), {} group solves left "
               "unlinked by the separator check\n",
               set_aside.size(), twin_set_aside.size(), unlinked);
  }
  fmt::print("DDS payload: objects {} B, group solves {} B; {:.1f} kB per group solve (point "
             "clouds, one frame per robot: {:.0f} kB)\n",
             objects_bytes, solve_bytes, j["dds_bytes_per_solve"].get<double>() / 1e3,
             j["point_cloud_bytes_per_solve"].get<double>() / 1e3);
  j["ok"] = ok;
  j["per_robot"] = per_robot;
  fmt::print("maps in {}/robot<R>/maps\n", out.string());
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
    throw InvalidInputError(fmt::format("team: at most {} robots (results are g2o files with "
                                        "objects), got --robots {}",
                                        kMaxRobotsWithObjects, spec.robots));
  }
  const int n = spec.robots;
  const fs::path out = a.out.empty() ? fs::temp_directory_path() /
                                           fmt::format("moslam_team_{}", ::getpid())
                                     : fs::path(a.out);
  CheckScenarioFlags("team", a.online, spec);
  fs::create_directories(out);
  if (a.online) return RunOnlineTeam(a, spec, flags, out);
  const TeamResults t = RunTeamProcesses(a, out, n, ScenarioArgs(flags), true);
  bool ok = t.ok;
  std::set<std::vector<std::uint64_t>> shared;
  std::int64_t rdv_binary = 0, rdv_dds = 0, rdv_samples = 0;
  int events = 0;
  for (const auto& [r, s] : t.summaries) {
    for (const auto& p : s["shared"]) shared.insert(p.get<std::vector<std::uint64_t>>());
    rdv_binary += s["rendezvous_binary_bytes"].get<std::int64_t>();
    rdv_dds += s["rendezvous_dds_bytes"].get<std::int64_t>();
    rdv_samples += s["rendezvous_dds_samples"].get<std::int64_t>();
    for (const auto& e : s["rendezvous"]) events += e["alpha"].get<int>() == r ? 1 : 0;
  }

  nlohmann::json j;
  j["scenario"] = spec.scenario;
  j["robots"] = n;
  j["seed"] = spec.seed;
  j["initial_poses"] = spec.known_initial_poses ? "known" : "unknown";
  j["exclusion_radius"] = spec.exclusion_radius;
  j["leave_one_out_check"] = spec.leave_one_out_check;
  j["loop_closure"] = spec.loop_closure;
  j["rendezvous_constellation"] = spec.rendezvous_constellation;
  j["poses_per_robot"] = spec.poses_per_robot;
  j["domain"] = a.domain;
  j["out"] = out.string();
  j["seconds"] = t.seconds;
  if (ok) {
    // The in-process pipeline on the same scenario.
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
    j["rendezvous_events"] = events;
    j["in_process_rendezvous_events"] = slam.rendezvous.size();
    j["shared_objects"] = shared.size();
    j["in_process_shared_objects"] = slam.shared.size();
    j["shared_objects_equal"] = shared == reference_shared;
    j["rendezvous_binary_bytes"] = rdv_binary;
    j["in_process_rendezvous_bytes"] = slam.bytes;
    j["rendezvous_dds_samples"] = rdv_samples;
    j["rendezvous_dds_bytes"] = rdv_dds;
    if (!joint.unanchored_robots.empty()) {
      ok = false;
      fmt::print(stderr, "moslam: in-process reference: robot {} is not linked to robot 0\n",
                 joint.unanchored_robots.front());
    } else {
      fmt::print("{} with {} robots (seed {}, {} poses each) as processes on loopback (domain {}): "
                 "{:.2f} s\n",
                 spec.scenario, n, spec.seed, spec.poses_per_robot, a.domain, t.seconds);
      fmt::print("rendezvous: {} events, {} shared objects (in-process {}, {}), {} B in-process "
                 "encoding (in-process run {} B), {} B DDS payload in {} samples\n",
                 events, shared.size(), slam.shared.size(),
                 shared == reference_shared ? "the same pairs" : "DIFFERENT pairs", rdv_binary,
                 slam.bytes, rdv_dds, rdv_samples);
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
    }
  } else {
    ReportFailedRobots(t.per_robot);
  }
  j["ok"] = ok;
  j["per_robot"] = t.per_robot;
  fmt::print("results in {}\n", out.string());
  if (a.json) fmt::print("{}\n", j.dump());
  return ok ? 0 : 1;
}

int RunTeam(const TeamArgs& args) {
  if (!args.scenario.name.empty()) return RunScenarioTeam(args);
  if (args.data.empty()) throw InvalidInputError("team: give --data <folder | file> or --scenario <name>");
  if (args.online) throw InvalidInputError("team: --online needs --scenario (the robots map as they go)");
  TeamArgs a = args;
  const fs::path out = a.out.empty() ? fs::temp_directory_path() /
                                           fmt::format("moslam_team_{}", ::getpid())
                                     : fs::path(a.out);
  fs::create_directories(out);
  if (fs::is_regular_file(a.data)) {
    // A single-robot file: split into --robots contiguous blocks of poses, one file each.
    if (a.robots < 1) throw InvalidInputError("team: a single g2o file needs --robots N");
    const Dataset single = ReadG2oFile(a.data);
    const SplitGraph split = SplitIntoRobots(single.graph, single.initial, a.robots);
    const fs::path folder = out / "data";
    WriteG2oFolder(folder.string(), split.graph, split.initial);
    fmt::print("{} split into {} robots: {}\n", a.data, a.robots, folder.string());
    a.data = folder.string();
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
      robust = RunRobustDgs(full.graph, full.initial, SeparatorFactors(full.graph),
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

Runner RegisterRobot(CLI::App& app) {
  auto args = std::make_shared<RobotArgs>();
  CLI::App* sub = app.add_subcommand("robot", kRobotDescription);
  sub->add_option("--robot", args->robot, "Robot id: reads <data>/<id>.g2o")
      ->required()
      ->check(CLI::Range(0, kMaxRobots - 1));
  auto* data = sub->add_option("--data", args->data, "Distributed-mapper folder (0.g2o .. N-1.g2o)")
                   ->check(CLI::ExistingDirectory);
  AddScenarioFlags(sub, args->scenario, true);
  data->excludes(sub->get_option("--scenario"));
  sub->add_option("--domain", args->domain, "DDS domain id (0..232)")->check(CLI::Range(0, 232));
  sub->add_option("--out", args->out,
                  "State directory: journal, estimate.g2o, result.g2o, summary.json (a restart "
                  "with the same --out resumes)");
  AddSolveFlags(sub, args->solve);
  sub->add_flag("--online", args->online,
                "With --scenario: solve with the robots in range at every rendezvous (the whole "
                "solver: --refine --stop error-bound implied) and save the map after each in "
                "<out>/maps/; no solve after the mission, no restart");
  sub->add_flag("--progress", args->progress, "Print a line per round");
  sub->add_flag("--json", args->json, "Last line: one JSON object with the summary");
  return [args]() { return RunRobot(*args); };
}

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
