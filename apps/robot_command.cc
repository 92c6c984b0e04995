// `moslam robot`: one robot as its own process, talking to the others over Cyclone DDS.
#include <fmt/core.h>
#include <fmt/ranges.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/io/g2o.h"
#include "moslam/online/online_team.h"
#include "moslam/robust/gnc.h"
#include "moslam/transport/dds_transport.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/robot_data.h"
#include "moslam/transport/robot_session.h"
#include "robot_flags.h"

namespace moslam::cli {
namespace {

namespace fs = std::filesystem;

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

// <out>/summary.json (with --out), which `moslam team` reads back: written whole, or an error
// naming it (never half a file, never a silent failure).
void WriteSummary(const RobotArgs& a, const nlohmann::json& j) {
  if (a.out.empty()) return;
  WriteWholeFile((fs::path(a.out) / "summary.json").string(), j.dump(2) + "\n",
                 fmt::format("robot {}: its summary", a.robot));
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
          {"dds_weights_bytes", s.sent.weights_bytes},
          {"dds_covariances_bytes", s.sent.covariances_bytes},
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
    // The separator check: separators to higher robots it left out (and its own loop closures,
    // robust_program.h C5), and the messages it sent
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
  j.update(ScenarioJson(spec));
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
  WriteSummary(a, j);
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
  WriteSummary(a, j);
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
  if (a.solve.robust_loop_closures) options.robust = LoopClosureFactors(data.graph);
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
  WriteSummary(a, j);
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

}  // namespace moslam::cli
