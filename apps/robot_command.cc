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
#include <nlohmann/json.hpp>
#include <thread>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/partition.h"
#include "moslam/io/g2o.h"
#include "moslam/transport/dds_transport.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/robot_data.h"

namespace moslam::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct SolveFlags {
  double eta_rotation = 1e-2;
  double eta_pose = 1e-2;
  int max_iterations = 1000;
  bool no_flagged = false;
  double leave_timeout = 15.0;  // seconds
  double join_timeout = 60.0;
  double stall_timeout = 300.0;
};

void AddSolveFlags(CLI::App* sub, SolveFlags& f) {
  sub->add_option("--eta-rot", f.eta_rotation, "Stage 1 stops when every change is <= this")
      ->check(CLI::PositiveNumber);
  sub->add_option("--eta-pose", f.eta_pose, "Stage 2 stops when every change is <= this")
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-iter", f.max_iterations, "Rounds (Jacobi sweeps) per stage")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--no-flagged", f.no_flagged,
                "Exchange initial estimates instead of flagged initialisation");
  sub->add_option("--leave-timeout", f.leave_timeout,
                  "Seconds a waited-for robot may be unreachable before it counts as gone")
      ->check(CLI::PositiveNumber);
  sub->add_option("--join-timeout", f.join_timeout, "Seconds to wait for the team to form")
      ->check(CLI::PositiveNumber);
  sub->add_option("--stall-timeout", f.stall_timeout, "Seconds without progress before failing")
      ->check(CLI::PositiveNumber);
}

std::chrono::milliseconds Ms(double seconds) {
  return std::chrono::milliseconds(static_cast<std::int64_t>(seconds * 1000.0));
}

DgsNodeOptions NodeOptions(const SolveFlags& f) {
  DgsNodeOptions o;
  o.eta_rotation = f.eta_rotation;
  o.eta_pose = f.eta_pose;
  o.max_iterations = f.max_iterations;
  o.flagged_initialisation = !f.no_flagged;
  o.leave_timeout = Ms(f.leave_timeout);
  o.join_timeout = Ms(f.join_timeout);
  o.stall_timeout = Ms(f.stall_timeout);
  o.finish_timeout = Ms(std::max(10.0, f.leave_timeout + 5.0));
  return o;
}

std::vector<std::string> SolveArgs(const SolveFlags& f) {
  std::vector<std::string> a = {"--eta-rot", fmt::format("{}", f.eta_rotation), "--eta-pose",
                                fmt::format("{}", f.eta_pose), "--max-iter",
                                std::to_string(f.max_iterations), "--leave-timeout",
                                fmt::format("{}", f.leave_timeout), "--join-timeout",
                                fmt::format("{}", f.join_timeout), "--stall-timeout",
                                fmt::format("{}", f.stall_timeout)};
  if (f.no_flagged) a.push_back("--no-flagged");
  return a;
}

// ---- moslam robot ------------------------------------------------------------------------

struct RobotArgs {
  int robot = 0;
  std::string data;
  int domain = 0;
  std::string out;
  SolveFlags solve;
  bool progress = false;
  bool json = false;
};

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
  j["dds_estimate_bytes"] = r.transport.estimates_bytes;
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

int RunRobot(const RobotArgs& a) {
  const std::string file = RobotFile(a.data, a.robot);
  const Dataset data = ReadRobotG2o(file);
  DgsNodeOptions options = NodeOptions(a.solve);
  options.state_dir = a.out;
  if (a.progress) {
    options.on_round = [](const DgsNodeRound& r) {
      fmt::print("progress: {} {} {}{}\n", ToString(r.stage), r.round, r.sent ? "sent" : "-",
                 r.replayed ? " replayed" : "");
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
  int robots = 0;
  int domain = 0;
  std::string out;
  SolveFlags solve;
  double timeout = 600.0;
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

double MaxDifference(const Values& a, const Values& b) {
  double worst = 0.0;
  for (const auto& [k, x] : b) {
    const auto it = a.find(k);
    if (it == a.end()) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, (x.translation() - it->second.translation()).norm());
    worst = std::max(worst, (x.rotation().matrix() - it->second.rotation().matrix()).norm());
  }
  return worst;
}

int RunTeam(const TeamArgs& args) {
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
  const std::string config = LoopbackConfigXml(a.domain, n);
  ::setenv("CYCLONEDDS_URI", config.c_str(), 1);

  const auto t0 = Clock::now();
  std::map<pid_t, int> children;
  std::map<int, int> exit_codes;
  for (int r = 0; r < n && a.collect_only; ++r) {
    exit_codes[r] = fs::exists(out / fmt::format("robot{}", r) / "summary.json") ? 0 : 1;
  }
  for (int r = 0; r < n && !a.collect_only; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    fs::create_directories(dir);
    std::vector<std::string> argv = {"moslam", "robot", "--robot", std::to_string(r), "--data",
                                     a.data, "--domain", std::to_string(a.domain), "--out",
                                     dir.string()};
    for (const std::string& s : SolveArgs(a.solve)) argv.push_back(s);
    children[Spawn(argv, dir / "log.txt")] = r;
  }
  const auto deadline = t0 + Ms(a.timeout);
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
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  // Collect.
  Values merged;
  nlohmann::json robots = nlohmann::json::array();
  bool ok = true;
  std::int64_t binary = 0, cdr = 0, status_bytes = 0, messages = 0;
  int rotation_rounds = 0, pose_rounds = 0;
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    nlohmann::json j;
    j["robot"] = r;
    j["exit_code"] = exit_codes[r];
    if (exit_codes[r] != 0 || !fs::exists(dir / "summary.json")) {
      ok = false;
      j["log"] = (dir / "log.txt").string();
      robots.push_back(j);
      continue;
    }
    std::ifstream in(dir / "summary.json");
    const nlohmann::json s = nlohmann::json::parse(in);
    j.update(s);
    robots.push_back(j);
    const Dataset result = ReadRobotG2o((dir / "result.g2o").string());
    merged.insert(result.initial.begin(), result.initial.end());
    binary += s["estimate_binary_bytes"].get<std::int64_t>();
    cdr += s["dds_estimate_bytes"].get<std::int64_t>();
    status_bytes += s["dds_status_bytes"].get<std::int64_t>();
    messages += s["estimate_messages"].get<std::int64_t>();
    rotation_rounds = std::max(rotation_rounds, s["rotation_rounds"].get<int>());
    pose_rounds = std::max(pose_rounds, s["pose_rounds"].get<int>());
  }

  nlohmann::json j;
  j["robots"] = n;
  j["domain"] = a.domain;
  j["out"] = out.string();
  j["seconds"] = seconds;
  j["ok"] = ok;
  j["per_robot"] = robots;
  if (ok) {
    const Dataset full = ReadG2oFolder(a.data);
    const DgsResult reference = RunDgs(full.graph, full.initial, DriverOptions(NodeOptions(a.solve)));
    j["cost"] = full.graph.cost(merged);
    j["cost_in_process"] = full.graph.cost(reference.values);
    j["max_difference"] = MaxDifference(merged, reference.values);
    j["rotation_rounds"] = rotation_rounds;
    j["pose_rounds"] = pose_rounds;
    j["in_process_rotation_iterations"] = reference.rotation.iterations;
    j["in_process_pose_iterations"] = reference.pose.iterations;
    j["estimate_messages"] = messages;
    j["in_process_messages"] = reference.messages;
    j["estimate_binary_bytes"] = binary;
    j["in_process_bytes"] = reference.bytes;
    j["dds_estimate_bytes"] = cdr;
    j["dds_status_bytes"] = status_bytes;
    const int rounds = rotation_rounds + pose_rounds;
    j["dds_payload_bytes_per_round"] = rounds ? static_cast<double>(cdr + status_bytes) / rounds : 0.0;
    fmt::print("team of {} on loopback (domain {}): {:.2f} s, rotation {} rounds, pose {} rounds "
               "(in-process driver: {}, {})\n",
               n, a.domain, seconds, rotation_rounds, pose_rounds, reference.rotation.iterations,
               reference.pose.iterations);
    fmt::print("cost F = {:.9g} (in-process {:.9g}), largest difference {:.3g}\n",
               j["cost"].get<double>(), j["cost_in_process"].get<double>(),
               j["max_difference"].get<double>());
    fmt::print("DGS estimates: {} messages, {} B binary (in-process {} messages, {} B), {} B CDR "
               "payload; status {} B\n",
               messages, binary, reference.messages, reference.bytes, cdr, status_bytes);
  } else {
    for (const auto& r : robots) {
      if (r["exit_code"] != 0) {
        fmt::print(stderr, "moslam: robot {} failed (exit {}), see {}\n", r["robot"].get<int>(),
                   r["exit_code"].get<int>(), r.value("log", std::string()));
      }
    }
  }
  fmt::print("results in {}\n", out.string());
  if (a.json) fmt::print("{}\n", j.dump());
  return ok ? 0 : 1;
}

}  // namespace

Runner RegisterRobot(CLI::App& app) {
  auto args = std::make_shared<RobotArgs>();
  CLI::App* sub = app.add_subcommand(
      "robot", "One robot as a process: its g2o file, DGS with the others over Cyclone DDS");
  sub->add_option("--robot", args->robot, "Robot id: reads <data>/<id>.g2o")
      ->required()
      ->check(CLI::Range(0, kMaxRobots - 1));
  sub->add_option("--data", args->data, "Distributed-mapper folder (0.g2o .. N-1.g2o)")
      ->required()
      ->check(CLI::ExistingDirectory);
  sub->add_option("--domain", args->domain, "DDS domain id (0..232)")->check(CLI::Range(0, 232));
  sub->add_option("--out", args->out,
                  "State directory: journal, estimate.g2o, result.g2o, summary.json (a restart "
                  "with the same --out resumes)");
  AddSolveFlags(sub, args->solve);
  sub->add_flag("--progress", args->progress, "Print a line per round");
  sub->add_flag("--json", args->json, "Last line: one JSON object with the summary");
  return [args]() { return RunRobot(*args); };
}

Runner RegisterTeam(CLI::App& app) {
  auto args = std::make_shared<TeamArgs>();
  CLI::App* sub = app.add_subcommand(
      "team", "Start one `moslam robot` process per robot on loopback and collect the results");
  sub->add_option("--data", args->data,
                  "Distributed-mapper folder (0.g2o .. N-1.g2o), or one single-robot g2o file "
                  "split into --robots contiguous blocks of poses (written to <out>/data)")
      ->required()
      ->check(CLI::ExistingPath);
  sub->add_option("--robots", args->robots, "Number of robots (default: every file)")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--prepare", args->prepare_only,
                "Only write the split data folder (single-file --data) and exit");
  sub->add_flag("--collect", args->collect_only,
                "Start nothing: collect the results already in <out>/robot<R>/ (robots started "
                "elsewhere, e.g. in network namespaces) and compare");
  sub->add_option("--domain", args->domain, "DDS domain id (0..232)")->check(CLI::Range(0, 232));
  sub->add_option("--out", args->out, "Directory for robot<R>/ state and results");
  AddSolveFlags(sub, args->solve);
  sub->add_option("--timeout", args->timeout, "Seconds before the robots are killed")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--json", args->json, "Last line: one JSON object with the summary");
  return [args]() { return RunTeam(*args); };
}

}  // namespace moslam::cli
