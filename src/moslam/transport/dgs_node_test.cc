// The DGS protocol node (dgs_node.h) over the in-process transport, one thread per robot: the
// result equals the in-process driver's (Jacobi) whatever the timing, and survives a robot
// crashing and restarting from its journal, a cut link, and a robot that leaves for good.
#include "moslam/transport/dgs_node.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/dgs_test_util.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"
#include "moslam/robust/spoil.h"
#include "moslam/solver/initialization.h"
#include "moslam/transport/in_process_transport.h"
#include "moslam/transport/robot_data.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

struct Crash : std::runtime_error {
  Crash() : std::runtime_error("simulated crash") {}
};

struct TeamResult {
  std::map<int, DgsNodeResult> results;
  std::map<int, std::string> errors;
  Values merged() const {
    Values v;
    for (const auto& [r, res] : results) v.insert(res.estimate.begin(), res.estimate.end());
    return v;
  }
};

// Per robot: its options, and (optional) what to do when its node throws Crash: return true to
// restart it from its journal with a fresh transport.
struct RobotSetup {
  DgsNodeOptions options;
  bool restart_after_crash = false;
};

// on_error: called (under the team's lock) after a robot's node threw, with the robot.
TeamResult RunTeam(InProcessNetwork& net, const Dataset& data,
                   const std::function<RobotSetup(int)>& setup,
                   const std::function<void(int)>& on_error = {}) {
  TeamResult team;
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (const RobotSubgraph& part : PartitionByRobot(data.graph)) {
    threads.emplace_back([&, part]() {
      const RobotSetup s = setup(part.robot);
      TransportOptions quiet;
      quiet.log = [](const std::string&) {};
      while (true) {
        try {
          auto transport = net.connect(part.robot, quiet);
          DgsNode node(part.robot, part.graph, data.initial, *transport, s.options);
          DgsNodeResult r = node.run();
          std::lock_guard<std::mutex> lock(mutex);
          team.results[part.robot] = std::move(r);
          return;
        } catch (const Crash&) {
          if (s.restart_after_crash) continue;  // the transport was destroyed: it left
          std::lock_guard<std::mutex> lock(mutex);
          team.errors[part.robot] = "crashed";
          return;
        } catch (const std::exception& e) {
          std::lock_guard<std::mutex> lock(mutex);
          team.errors[part.robot] = e.what();
          if (on_error) on_error(part.robot);
          return;
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();
  return team;
}

fs::path FreshDir(const std::string& name) { return test::ScratchDir(name); }

using RoundTest = std::function<bool(const DgsNodeRound&)>;

// RunTeam with every robot journaling in dir/<robot>: robot `victim` is killed at each of `at` in
// turn, the k-th time right after the first protocol step it computes (not one it replayed) that
// at[k] accepts, and restarts from its journal each time. The kills are counted in *crashes.
TeamResult RunTeamKilling(InProcessNetwork& net, const Dataset& data, const DgsNodeOptions& o,
                          const fs::path& dir, int victim, const std::vector<RoundTest>& at,
                          std::atomic<int>* crashes) {
  return RunTeam(net, data, [&](int robot) {
    RobotSetup s{o, false};
    s.options.state_dir = (dir / std::to_string(robot)).string();
    if (robot == victim) {
      s.restart_after_crash = true;
      s.options.on_round = [at, crashes](const DgsNodeRound& r) {
        const auto k = static_cast<std::size_t>(crashes->load());
        if (!r.replayed && k < at.size() && at[k](r)) {
          ++*crashes;
          throw Crash();
        }
      };
    }
    return s;
  });
}

// Killed once, right after protocol step `round`.
TeamResult RunTeamKillingOnce(InProcessNetwork& net, const Dataset& data, const DgsNodeOptions& o,
                              const fs::path& dir, int victim, std::uint32_t round,
                              std::atomic<int>* crashes) {
  return RunTeamKilling(net, data, o, dir, victim,
                        {[round](const DgsNodeRound& r) { return r.round == round; }}, crashes);
}

// The round test of round `stage_round` of `stage`.
RoundTest AtStageRound(DgsStage stage, int stage_round) {
  return [=](const DgsNodeRound& r) { return r.stage == stage && r.stage_round == stage_round; };
}

DgsNodeOptions Options() {
  DgsNodeOptions o;
  o.join_timeout = std::chrono::seconds(20);
  o.stall_timeout = std::chrono::seconds(60);
  o.finish_timeout = std::chrono::seconds(20);
  return o;
}

TEST(DgsNode, EqualsTheInProcessDriverInJacobiOrder) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  for (bool flagged : {true, false}) {
    SCOPED_TRACE(flagged ? "flagged initialisation" : "initial exchange");
    DgsNodeOptions o = Options();
    o.solver.flagged_initialisation = flagged;
    const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(o));
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{o}; });
    ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
    ASSERT_EQ(team.results.size(), 4u);
    EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
    std::int64_t messages = 0, bytes = 0;
    for (const auto& [r, res] : team.results) {
      EXPECT_EQ(res.rotation_rounds, reference.rotation.iterations);
      EXPECT_EQ(res.pose_rounds, reference.pose.iterations);
      EXPECT_EQ(res.rotation_converged, reference.rotation.status == StageStatus::kConverged);
      EXPECT_EQ(res.team, (std::vector<int>{0, 1, 2, 3}));
      EXPECT_TRUE(res.left.empty());
      messages += res.estimate_messages;
      bytes += res.estimate_binary_bytes;
    }
    // The same messages as the driver sends.
    EXPECT_EQ(messages, reference.messages);
    EXPECT_EQ(bytes, reference.bytes);
  }
}

TEST(DgsNode, ARobotThatCrashesAndRestartsFromItsJournalLosesNothing) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const DgsNodeOptions base = Options();
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base));
  ASSERT_GT(reference.rotation.iterations, 6);
  ASSERT_GT(reference.pose.iterations, 4);
  const fs::path dir = FreshDir("restart");
  std::atomic<int> crashes{0};
  InProcessNetwork net;
  // Robot 2 crashes in the rotation stage at round 5, then in the pose stage at round 3.
  const TeamResult team = RunTeamKilling(
      net, data, base, dir, 2,
      {AtStageRound(DgsStage::kRotation, 5), AtStageRound(DgsStage::kPose, 3)}, &crashes);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_EQ(crashes, 2);
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  const DgsNodeResult& r2 = team.results.at(2);
  EXPECT_EQ(r2.incarnation, 2u);
  EXPECT_EQ(r2.replayed_rounds, reference.rotation.iterations + 3);
  EXPECT_EQ(r2.rotation_rounds, reference.rotation.iterations);
  EXPECT_EQ(r2.pose_rounds, reference.pose.iterations);
  for (int r = 0; r < 4; ++r) {
    // The saved result: the robot's variables (full precision) and its subgraph.
    const Dataset saved = ReadRobotG2o((dir / std::to_string(r) / "result.g2o").string());
    EXPECT_EQ(saved.initial.size(), team.results.at(r).estimate.size());
    EXPECT_LE(MaxPoseDifference(saved.initial, team.results.at(r).estimate), 1e-12);
    EXPECT_TRUE(fs::exists(dir / std::to_string(r) / "estimate.g2o"));
  }
  fs::remove_all(dir);
}

TEST(DgsNode, ACutLinkDelaysButDoesNotChangeTheResult) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const DgsNodeOptions base = Options();
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base));
  InProcessNetwork net;
  std::mutex m;
  std::condition_variable cv;
  bool cut = false, finished = false;
  std::thread restorer([&]() {
    std::unique_lock<std::mutex> lock(m);
    cv.wait(lock, [&]() { return cut || finished; });
    if (finished) return;
    // The outage lasts 300 ms (the robots poll, see each other gone, and wait).
    cv.wait_for(lock, std::chrono::milliseconds(300), [&]() { return finished; });
    net.setLink(0, 1, true);
    net.setLink(0, 2, true);
  });
  const TeamResult team = RunTeam(net, data, [&](int robot) {
    RobotSetup s{base, false};
    if (robot == 0) {
      s.options.on_round = [&](const DgsNodeRound& r) {
        if (r.stage == DgsStage::kRotation && r.stage_round == 3) {
          net.setLink(0, 1, false);
          net.setLink(0, 2, false);
          std::lock_guard<std::mutex> lock(m);
          cut = true;
          cv.notify_all();
        }
      };
    }
    return s;
  });
  {
    std::lock_guard<std::mutex> lock(m);
    finished = true;
    cv.notify_all();
  }
  restorer.join();
  ASSERT_TRUE(cut);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  for (const auto& [r, res] : team.results) EXPECT_TRUE(res.left.empty());
}

TEST(DgsNode, TheOthersFinishWithoutARobotThatLeaves) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsNodeOptions base = Options();
  base.leave_timeout = std::chrono::milliseconds(200);
  // Robot 3 completes round 4 of the rotation stage and dies: for the others it is the driver's
  // robot that stops answering at the start of sweep 5.
  FaultInjection faults;
  faults.silent = {{3, DgsStage::kRotation, 5}};
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base), faults);
  InProcessNetwork net;
  const TeamResult team = RunTeam(net, data, [&](int robot) {
    RobotSetup s{base, false};
    if (robot == 3) {
      s.options.on_round = [](const DgsNodeRound& r) {
        if (r.stage == DgsStage::kRotation && r.stage_round == 4) throw Crash();
      };
    }
    return s;
  });
  ASSERT_EQ(team.errors.size(), 1u);
  EXPECT_EQ(team.errors.at(3), "crashed");
  ASSERT_EQ(team.results.size(), 3u);
  for (const auto& [r, res] : team.results) {
    EXPECT_EQ(res.left, std::vector<int>{3});
    EXPECT_EQ(res.rotation_rounds, reference.rotation.iterations);
    EXPECT_EQ(res.pose_rounds, reference.pose.iterations);
  }
  Values survivors = team.merged();  // the estimates of robots 0-2, against the reference's
  for (auto it = survivors.begin(); it != survivors.end();) {
    it = it->first.robot == 3 ? survivors.erase(it) : std::next(it);
  }
  EXPECT_LE(MaxPoseDifference(reference.values, survivors), 1e-9);
}

// A robot alive but stuck (here: inside its round callback after round 4) is not a robot that
// left: the others wait for it until the stall timeout, then fail naming the step, the robot and
// what they miss of it, rather than continuing without its variables.
TEST(DgsNode, ARobotAliveButStuckFailsTheOthersAfterTheStallTimeoutNamingIt) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsNodeOptions base = Options();
  base.stall_timeout = std::chrono::milliseconds(1000);  // far above a step of this team
  base.leave_timeout = std::chrono::seconds(60);  // alive all along: it never leaves
  std::mutex mutex;
  std::condition_variable others_failed;
  int failed = 0;
  InProcessNetwork net;
  const TeamResult team = RunTeam(
      net, data,
      [&](int robot) {
        RobotSetup s{base, false};
        if (robot == 3) {
          s.options.on_round = [&](const DgsNodeRound& r) {
            if (r.stage != DgsStage::kRotation || r.stage_round != 4) return;
            std::unique_lock<std::mutex> lock(mutex);
            // Bounded, so that a regression fails the test rather than hangs it.
            others_failed.wait_for(lock, std::chrono::seconds(60), [&] { return failed == 3; });
            throw Crash();
          };
        }
        return s;
      },
      [&](int) {
        std::lock_guard<std::mutex> lock(mutex);
        ++failed;
        others_failed.notify_all();
      });
  ASSERT_EQ(team.errors.size(), 4u);
  EXPECT_EQ(team.errors.at(3), "crashed");
  for (int r = 0; r < 3; ++r) {
    EXPECT_NE(team.errors.at(r).find(fmt::format(
                  "robot {}: no progress for 1000 ms at step 5, waiting for robot(s) 3 (", r)),
              std::string::npos)
        << team.errors.at(r);
  }
}

// With the team given (a robot session formed it), the nodes start without waiting for the
// others' statuses and equal the driver; a robot of the team that never takes a step (here: never
// starts) stops the solve of every other at the first step, TeamChangedError naming it, rather
// than leaving them to solve with nothing of its variables (robot 0's absence would leave them
// with no anchor). A team given that lacks the robot or a neighbour is refused.
TEST(DgsNode, WithTheTeamGivenARobotThatNeverStepsStopsTheSolveForEveryRobot) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsNodeOptions base = Options();
  base.team = {0, 1, 2, 3};
  base.leave_timeout = std::chrono::milliseconds(200);
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base));
  {
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{base, false}; });
    ASSERT_TRUE(team.errors.empty());
    EXPECT_LE(MaxPoseDifference(reference.values, team.merged()), 1e-9);
  }
  for (const int absent : {0, 2}) {
    InProcessNetwork net;
    std::map<int, std::vector<int>> named;
    std::mutex mutex;
    std::vector<std::thread> threads;
    for (const RobotSubgraph& part : PartitionByRobot(data.graph)) {
      if (part.robot == absent) continue;
      threads.emplace_back([&, part]() {
        auto transport = net.connect(part.robot, {[](const std::string&) {}});
        DgsNode node(part.robot, part.graph, data.initial, *transport, base);
        try {
          node.run();
        } catch (const TeamChangedError& e) {
          std::lock_guard<std::mutex> lock(mutex);
          named[part.robot] = e.robots();
        }
      });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(named.size(), 3u) << "robot " << absent << " absent";
    for (const auto& [r, robots] : named) EXPECT_EQ(robots, std::vector<int>{absent});
  }
  const auto parts = PartitionByRobot(data.graph);
  InProcessNetwork net;
  auto t = net.connect(1);
  DgsNodeOptions o = Options();
  o.team = {0, 2, 3};  // robot 1 itself is missing
  DgsNode lacking(1, parts[1].graph, data.initial, *t, o);
  EXPECT_THROW(lacking.run(), InvalidInputError);
  o.team = {1, 0};
  EXPECT_THROW(DgsNode(1, parts[1].graph, data.initial, *t, o), InvalidInputError);
}

// Without the team given, a robot forms it from the statuses it hears: alone, it gives up at the
// join timeout naming the robots it never heard; a team without robot 0 (whose first pose fixes
// the gauge) is refused.
TEST(DgsNode, ATeamThatNeverFormsOrLacksRobotZeroIsRefusedNamingWhy) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const auto parts = PartitionByRobot(data.graph);
  InProcessNetwork net;
  auto t = net.connect(1, {[](const std::string&) {}});
  DgsNodeOptions o = Options();
  o.join_timeout = std::chrono::milliseconds(300);
  DgsNode alone(1, parts[1].graph, data.initial, *t, o);
  EXPECT_TRUE(test::ThrowsNaming<Error>(
      [&] { alone.run(); },
      "robot 1: the team did not form within 300 ms: no status from robot(s) 0"));
  o.team = {1, 2, 3};
  DgsNode no_gauge(1, parts[1].graph, data.initial, *t, o);
  EXPECT_TRUE(test::ThrowsNaming<UnderdeterminedError>(
      [&] { no_gauge.run(); },
      "its team 1, 2, 3 has no robot 0, whose first pose fixes the gauge"));
}

// The whole solver: the two-level stages with the error-bound rule, then the refinement.
DgsNodeOptions WholeSolver() {
  DgsNodeOptions o = Options();
  o.solver.coarse_correction = true;
  o.solver.stopping = StageStopping::kErrorBound;
  o.solver.refine = true;
  o.solver.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
  return o;
}

TEST(DgsNode, TheWholeSolverEqualsTheInProcessDriver) {
  for (int robots : {4, 9}) {
    SCOPED_TRACE(std::to_string(robots) + " robots");
    const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(robots));
    const DgsNodeOptions o = WholeSolver();
    const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(o));
    ASSERT_GT(reference.rotation.coarse_corrections, 0);
    ASSERT_GT(reference.refine.iterations, 0);
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{o}; });
    ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
    ASSERT_EQ(team.results.size(), static_cast<std::size_t>(robots));
    EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
    for (const auto& [r, res] : team.results) {
      const RobotProgramResult& p = res.program;
      EXPECT_EQ(p.rotation.iterations, reference.rotation.iterations);
      EXPECT_EQ(p.rotation.coarse_corrections, reference.rotation.coarse_corrections);
      EXPECT_EQ(p.pose.iterations, reference.pose.iterations);
      EXPECT_EQ(p.refine.iterations, reference.refine.iterations);
      EXPECT_EQ(p.refine.sweeps, reference.refine.sweeps);
      EXPECT_NEAR(p.refine.final_cost, reference.refine.final_cost,
                  1e-12 * reference.refine.final_cost);
      EXPECT_GT(res.coarse_messages, 0);
      EXPECT_EQ(res.transport.coarse_sent, res.coarse_messages);
    }
  }
}

TEST(DgsNode, TheLowestRobotKilledInTheRefinementAndRestartedChangesNothing) {
  // No robot coordinates: every robot solves the coarse system and takes the step decisions
  // from the reports of all. Robot 0, the one a coordinator rule would pick, dies twice (in the
  // two-level stage and in the refinement's conjugate gradients) and restarts from its journal.
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const DgsNodeOptions base = WholeSolver();
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base));
  const fs::path dir = FreshDir("restart_refine");
  std::atomic<int> crashes{0};
  InProcessNetwork net;
  const TeamResult team = RunTeamKilling(
      net, data, base, dir, 0,
      {AtStageRound(DgsStage::kRotation, 6), AtStageRound(DgsStage::kRefine, 9)}, &crashes);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_EQ(crashes, 2);
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  const DgsNodeResult& r0 = team.results.at(0);
  EXPECT_EQ(r0.incarnation, 2u);
  EXPECT_GT(r0.replayed_rounds, reference.rotation.iterations);
  EXPECT_NEAR(r0.program.refine.final_cost, reference.refine.final_cost,
              1e-12 * reference.refine.final_cost);
  for (const auto& [r, res] : team.results) EXPECT_TRUE(res.left.empty());
  fs::remove_all(dir);
}

TEST(DgsNode, TheOthersFinishTheRefinementWithoutARobotThatLeaves) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  DgsNodeOptions base = WholeSolver();
  base.leave_timeout = std::chrono::milliseconds(200);
  const DgsResult reference = RunDgs(data.graph, data.initial, DriverOptions(base));
  InProcessNetwork net;
  const TeamResult team = RunTeam(net, data, [&](int robot) {
    RobotSetup s{base, false};
    if (robot == 0) {
      s.options.on_round = [](const DgsNodeRound& r) {
        if (r.stage == DgsStage::kRefine && r.stage_round == 5) throw Crash();
      };
    }
    return s;
  });
  ASSERT_EQ(team.errors.size(), 1u);
  EXPECT_EQ(team.errors.at(0), "crashed");
  ASSERT_EQ(team.results.size(), 3u);
  for (const auto& [r, res] : team.results) {
    EXPECT_EQ(res.left, std::vector<int>{0});
    EXPECT_EQ(res.rotation_rounds, reference.rotation.iterations);
    EXPECT_EQ(res.pose_rounds, reference.pose.iterations);
    // The survivors refine on without robot 0 (its variables fixed) and agree on every decision.
    EXPECT_EQ(res.program.refine.iterations, team.results.begin()->second.program.refine.iterations);
    EXPECT_EQ(res.program.refine.final_cost, team.results.begin()->second.program.refine.final_cost);
    EXPECT_LE(res.program.refine.final_cost, res.program.refine.initial_cost);
    EXPECT_NE(res.program.refine.status, StageStatus::kNotRun);
  }
}

TEST(RobotData, EachRobotFileHoldsItsPartitionOfTheFolder) {
  const Dataset folder = ReadG2oFolder(test::BlocksWorldFolder(4));
  EXPECT_EQ(CountRobotFiles(test::BlocksWorldFolder(4)), 4);
  for (const RobotSubgraph& part : PartitionByRobot(folder.graph)) {
    const Dataset own = ReadRobotG2o(RobotFile(test::BlocksWorldFolder(4), part.robot));
    ASSERT_EQ(own.graph.factors().size(), part.graph.factors().size());
    std::set<std::pair<Key, Key>> a, b;
    for (const auto& f : own.graph.factors()) a.insert({f.a(), f.b()});
    for (const auto& f : part.graph.factors()) b.insert({f.a(), f.b()});
    EXPECT_EQ(a, b);
    for (const auto& [k, x] : own.initial) {
      EXPECT_EQ(k.robot, part.robot);
      EXPECT_EQ(x.translation(), folder.initial.at(k).translation());
    }
  }
  EXPECT_THROW(RobotFile(test::BlocksWorldFolder(4), 4), InvalidInputError);
}

// The weights every robot holds are the reference's for its factors (its subgraph, in graph
// order), and it ran as many GNC rounds.
void ExpectReferenceWeights(const TeamResult& team, const PoseGraph& graph,
                            const RobustDgsResult& reference) {
  for (const RobotSubgraph& part : PartitionByRobot(graph)) {
    const DgsNodeResult& res = team.results.at(part.robot);
    ASSERT_TRUE(res.robust.has_value());
    ASSERT_EQ(res.robust->weights.size(), part.graph.factors().size());
    std::size_t j = 0;
    for (std::size_t i = 0; i < graph.factors().size(); ++i) {
      const RelativePoseFactor& f = graph.factors()[i];
      if (f.a().robot != part.robot && f.b().robot != part.robot) continue;
      EXPECT_EQ(res.robust->weights[j++], reference.weights[i]) << "robot " << part.robot;
    }
    EXPECT_EQ(res.robust->iterations, reference.iterations);
    EXPECT_EQ(res.robust->polished, reference.polished);
  }
}

// The robust solve over the transport (robust_program.h): GNC rounds with the weights in
// WeightsPackets, equal to RunRobustDgs without the separator check, also when a robot dies in a
// GNC round and restarts from its journal.
TEST(DgsNode, TheRobustSolveEqualsTheInProcessRobustDriverAndSurvivesARestart) {
  const Dataset clean = ReadG2oFolder(test::BlocksWorldFolder(4));
  SpoilOptions spoil;
  spoil.fraction = 0.5;
  spoil.seed = 2;
  const SpoiledGraph spoiled = SpoilSeparators(clean.graph, spoil);
  Dataset data = clean;
  data.graph = spoiled.graph;
  DgsNodeOptions base = WholeSolver();
  base.gnc = GncOptions();
  base.gnc->threshold = 1.0;  // blocks_world: see robust/gnc_test.cc
  RobustDgsOptions ro;
  ro.dgs = DriverOptions(base);
  ro.gnc = *base.gnc;
  ro.check_separators = false;
  const RobustDgsResult reference =
      RunRobustDgs(data.graph, data.initial, DefaultRobustFactors(data.graph), ro);
  ASSERT_GT(reference.iterations, 1);
  ASSERT_GT(reference.outliers, 0);
  ASSERT_TRUE(reference.polished);
  auto expectReferenceWeights = [&](const TeamResult& team) {
    ExpectReferenceWeights(team, data.graph, reference);
    for (const auto& [robot, res] : team.results) EXPECT_TRUE(res.robust->polished);
  };
  int steps = 0, ls_steps = 0;
  {
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{base}; });
    ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
    EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
    expectReferenceWeights(team);
    std::int64_t weights = 0;
    for (const auto& [r, res] : team.results) {
      weights += res.weight_messages;
      EXPECT_EQ(res.transport.weights_sent, res.weight_messages);
      EXPECT_GT(res.transport.weights_bytes, 0);
    }
    // Every robot sends each of its neighbours one weight message per GNC round and one after.
    EXPECT_GT(weights, 0);
    steps = team.results.at(1).robust->channel_steps;
    ls_steps = team.results.at(1).robust->solves.front().channel_steps;
  }
  // Robot 1 dies in a GNC round (past the least-squares solve) and restarts from its journal.
  const std::uint32_t crash_at = static_cast<std::uint32_t>((ls_steps + steps) / 2);
  const fs::path dir = FreshDir("robust_restart");
  std::atomic<int> crashes{0};
  InProcessNetwork net;
  const TeamResult team = RunTeamKillingOnce(net, data, base, dir, 1, crash_at, &crashes);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_EQ(crashes, 1);
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  expectReferenceWeights(team);
  EXPECT_EQ(team.results.at(1).incarnation, 1u);
  // The step it died in was journaled before on_round ran.
  EXPECT_EQ(team.results.at(1).replayed_rounds, static_cast<int>(crash_at));
  fs::remove_all(dir);
}

TEST(DgsNode, RefusesTheJournalOfAnotherRun) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(2));
  const auto parts = PartitionByRobot(data.graph);
  const fs::path dir = FreshDir("foreign");
  InProcessNetwork net;
  auto t = net.connect(1);
  DgsNodeOptions o = Options();
  o.state_dir = dir.string();
  { DgsNode node(1, parts[1].graph, data.initial, *t, o); }  // writes the journal header
  o.solver.eta_pose = 0.5;
  EXPECT_THROW(DgsNode(1, parts[1].graph, data.initial, *t, o), InvalidInputError);
  o.solver.eta_pose = Options().solver.eta_pose;
  EXPECT_THROW(DgsNode(0, parts[0].graph, data.initial, *net.connect(0), o), InvalidInputError);
  EXPECT_NO_THROW(DgsNode(1, parts[1].graph, data.initial, *t, o));
  // The robust solve's options are the run's too: each change makes the journal another run's.
  const RobustDgsOptions robust;
  DgsNodeOptions r = Options();
  r.gnc = robust.gnc;
  r.separator_check = robust.consistency;
  const std::vector<std::pair<const char*, std::function<void(DgsNodeOptions&)>>> changes = {
      {"least squares", [](DgsNodeOptions& x) { x.gnc.reset(); }},
      {"GNC threshold", [](DgsNodeOptions& x) { x.gnc->threshold = 9.0; }},
      {"no check", [](DgsNodeOptions& x) { x.separator_check.reset(); }},
      {"check threshold", [](DgsNodeOptions& x) { x.separator_check->threshold = 9.0; }},
      {"one-to-one", [](DgsNodeOptions& x) { x.separator_check->one_to_one_objects = false; }},
      {"no re-test", [](DgsNodeOptions& x) { x.retest_left_out = false; }},
      {"no group re-test", [](DgsNodeOptions& x) { x.retest_groups = false; }},
      {"one-to-one after GNC", [](DgsNodeOptions& x) { x.one_to_one_after_gnc = true; }},
  };
  for (const auto& [what, change] : changes) {
    const fs::path robust_dir = FreshDir("foreign_robust");
    r.state_dir = robust_dir.string();
    { DgsNode node(1, parts[1].graph, data.initial, *t, r); }
    DgsNodeOptions changed = r;
    change(changed);
    EXPECT_THROW(DgsNode(1, parts[1].graph, data.initial, *t, changed), InvalidInputError)
        << what;
    EXPECT_NO_THROW(DgsNode(1, parts[1].graph, data.initial, *t, r)) << what;
  }
  fs::remove_all(dir);
}

// Each refusal of the node's options names what is wrong (DgsNodeOptions::validate and the
// masks checked against the robot's subgraph).
TEST(DgsNode, ValidatesOptions) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(2));
  const auto parts = PartitionByRobot(data.graph);
  InProcessNetwork net;
  auto t = net.connect(1);
  const auto refused = [&](const DgsNodeOptions& o, const std::string& named) {
    return test::ThrowsNaming([&] { DgsNode(1, parts[1].graph, data.initial, *t, o); }, named);
  };
  DgsNodeOptions o = Options();
  o.solver.eta_rotation = 0.0;
  EXPECT_TRUE(refused(o, "eta_rotation"));
  o = Options();
  o.leave_timeout = std::chrono::milliseconds(0);
  EXPECT_TRUE(refused(o, "leave_timeout must be positive"));
  EXPECT_THROW(DgsNode(0, parts[1].graph, data.initial, *t, Options()), InvalidInputError);
  o = Options();
  o.team = {1, 0};
  EXPECT_TRUE(refused(o, "the team's robot ids must be distinct, non-negative and increasing"));
  o = Options();
  o.robust = {true};
  EXPECT_TRUE(refused(o, "a robust mask without gnc options"));
  o.gnc = GncOptions();
  EXPECT_TRUE(refused(o, "the robust mask has 1 entries for"));
  o.robust.clear();
  o.gnc->mu_step = 1.0;
  EXPECT_TRUE(refused(o, "mu_step"));
  o = Options();
  o.separator_check = SeparatorConsistencyOptions();
  EXPECT_TRUE(refused(o, "a separator check without gnc options"));
  o = Options();
  o.gnc = GncOptions();
  o.checked = {true};
  EXPECT_TRUE(refused(o, "a checked mask without a separator check"));
  o.separator_check = SeparatorConsistencyOptions();
  EXPECT_TRUE(refused(o, "the checked mask has 1 entries for"));
}

// The separator check before GNC over the transport (robust_program.h, C1-C4): on spoiled
// blocks_world with the maps taken as exact, and on two drifting robots with their maps'
// covariances in CovariancePackets, also when robot 0 dies right after the step that brought
// robot 1's covariance and restarts from its journal.
// RunRobustDgs with the robust options of the nodes `o` (GNC, the separator check, the re-test).
RobustDgsResult RobustReference(const Dataset& data, const DgsNodeOptions& o) {
  RobustDgsOptions ro;
  ro.dgs = DriverOptions(o);
  ro.gnc = *o.gnc;
  ro.consistency = *o.separator_check;
  ro.retest_left_out = o.retest_left_out;
  ro.retest_groups = o.retest_groups;
  ro.one_to_one_after_gnc = o.one_to_one_after_gnc;
  return RunRobustDgs(data.graph, data.initial, DefaultRobustFactors(data.graph), ro);
}

TEST(DgsNode, TheSeparatorCheckOverTheTransportEqualsRunRobustDgs) {
  {
    SCOPED_TRACE("blocks_world 4, 90 % wrong separators, the maps taken as exact");
    const Dataset clean = ReadG2oFolder(test::BlocksWorldFolder(4));
    SpoilOptions spoil;
    spoil.fraction = 0.9;
    spoil.seed = 1;
    Dataset data = clean;
    data.graph = SpoilSeparators(clean.graph, spoil).graph;
    DgsNodeOptions o = WholeSolver();
    o.gnc = GncOptions();
    o.gnc->threshold = 1.0;
    o.separator_check = SeparatorConsistencyOptions{0.0, 3, 2};
    o.separator_check->map_uncertainty = false;
    const RobustDgsResult reference = RobustReference(data, o);
    ASSERT_GT(reference.consistency_rejected, 0);
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{o}; });
    ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
    EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
    ExpectReferenceWeights(team, data.graph, reference);
    int rejected = 0;
    for (const auto& [r, res] : team.results) {
      rejected += res.robust->check_rejected;
      EXPECT_EQ(res.covariance_messages, 0);
    }
    EXPECT_EQ(rejected, reference.consistency_rejected);
  }
  SCOPED_TRACE("two drifting robots, the maps' covariances");
  Dataset data;
  std::vector<bool> wrong;
  data.graph = test::DriftingPairWithWrongSeparators(&wrong);
  data.initial = ChordalInitialization(data.graph, SE3());
  DgsNodeOptions o = WholeSolver();
  o.gnc = GncOptions();
  o.separator_check = SeparatorConsistencyOptions{0.0, 3, 2};
  const RobustDgsResult reference = RobustReference(data, o);
  ASSERT_EQ(reference.consistency_rejected, 2);
  const fs::path dir = FreshDir("check_restart");
  std::atomic<int> crashes{0};
  InProcessNetwork net;
  const TeamResult team = RunTeamKillingOnce(net, data, o, dir, 0, 1, &crashes);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_EQ(crashes, 1);
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  ExpectReferenceWeights(team, data.graph, reference);
  EXPECT_EQ(team.results.at(0).robust->check_rejected, 2);
  EXPECT_EQ(team.results.at(0).replayed_rounds, 1);
  // Robot 1 sent its covariance once (robot 0's restart replayed it from its journal).
  EXPECT_EQ(team.results.at(1).covariance_messages, 1);
  EXPECT_EQ(team.results.at(1).transport.covariances_sent, 1);
  fs::remove_all(dir);
}

// The one-to-one rule after GNC over the transport (test::TwoChairsSideBySide, whose wrong pair
// the readmission takes back without it; test::ObjectsMappedTwice, whose duplicates' pairs the
// group re-test tries with it): RunRobustDgs's weights and estimate, with and without.
TEST(DgsNode, TheOneToOneRuleAfterGncOverTheTransportEqualsRunRobustDgs) {
  for (const bool twice : {false, true}) {
    Dataset data;
    data.graph = twice ? test::ObjectsMappedTwice() : test::TwoChairsSideBySide();
    data.initial = ChordalInitialization(data.graph, SE3());
    for (const bool one_to_one : {true, false}) {
      SCOPED_TRACE(fmt::format("{}, {}", twice ? "objects mapped twice" : "two chairs",
                               one_to_one ? "with the rule" : "without"));
      DgsNodeOptions o = WholeSolver();
      o.gnc = GncOptions();
      o.separator_check = SeparatorConsistencyOptions{0.0, 3, 2};
      o.one_to_one_after_gnc = one_to_one;
      const RobustDgsResult reference = RobustReference(data, o);
      if (twice) {
        ASSERT_EQ(reference.group_retests, one_to_one ? 1 : 0);
      } else {
        ASSERT_EQ(reference.weights.back(), one_to_one ? 0.0 : 1.0);
      }
      InProcessNetwork net;
      const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{o}; });
      ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
      EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
      ExpectReferenceWeights(team, data.graph, reference);
    }
  }
}

// The re-test of the check's rejects (robust_program.h) over the transport: RunRobustDgs's
// weights and estimate, and robot 0 killed two steps before the end (in the last re-test's solve)
// and restarted from its journal changes nothing.
TEST(DgsNode, TheRetestOfTheChecksRejectsOverTheTransportSurvivesARestart) {
  Dataset data;
  std::vector<bool> wrong;
  data.graph = test::DriftingPairWithANearMiss(&wrong);
  data.initial = ChordalInitialization(data.graph, SE3());
  DgsNodeOptions o = WholeSolver();
  o.gnc = GncOptions();
  o.separator_check = SeparatorConsistencyOptions{12.0, 3, 2};
  o.retest_left_out = true;
  const RobustDgsResult reference = RobustReference(data, o);
  ASSERT_EQ(reference.retests, 2);
  ASSERT_EQ(reference.retest_readmitted, 1);
  std::uint32_t steps = 0;
  {
    InProcessNetwork net;
    const TeamResult team = RunTeam(net, data, [&](int) { return RobotSetup{o}; });
    ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
    EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
    ExpectReferenceWeights(team, data.graph, reference);
    EXPECT_EQ(team.results.at(0).robust->retest_readmitted, 1);
    steps = static_cast<std::uint32_t>(team.results.at(0).robust->channel_steps);
  }
  const fs::path dir = FreshDir("retest_restart");
  std::atomic<int> crashes{0};
  InProcessNetwork net;
  const TeamResult team = RunTeamKillingOnce(net, data, o, dir, 0, steps - 2, &crashes);
  ASSERT_TRUE(team.errors.empty()) << team.errors.begin()->second;
  EXPECT_EQ(crashes, 1);
  EXPECT_LE(MaxPoseDifference(team.merged(), reference.values), 1e-9);
  ExpectReferenceWeights(team, data.graph, reference);
  EXPECT_EQ(team.results.at(0).replayed_rounds, static_cast<int>(steps) - 2);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace moslam
