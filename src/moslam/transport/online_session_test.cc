// Online mapping between robot sessions (robot_session.h with online = true) as threads over the
// in-process transport: every group solve, and every robot's map after it and at the end, equal
// the in-process twin (online/online_team.h on RunMultiRobotObjectSlam). Between processes over
// DDS: apps/team_test.cc.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/metrics/metrics.h"
#include "moslam/online/online_team.h"
#include "moslam/transport/group_transport.h"
#include "moslam/transport/in_process_transport.h"
#include "moslam/transport/robot_session.h"

namespace moslam {
namespace {

using std::chrono::milliseconds;

RobotSessionOptions OnlineSessionOptions(const ScenarioSpec& spec) {
  RobotSessionOptions o;
  o.slam = ScenarioSlamConfig(spec);
  o.online = true;
  o.dgs.solver = OnlineOptions::DefaultSolver();
  o.dgs.join_timeout = milliseconds(20000);
  o.dgs.stall_timeout = milliseconds(20000);
  o.dgs.finish_timeout = milliseconds(5000);
  o.rendezvous_timeout = milliseconds(20000);
  o.log = [](const std::string&) {};
  return o;
}

// chairs25, 6 robots of 40 poses, seed 2: held landmarks, borrowed copies and a group of three.
ScenarioSpec SixRobots() {
  ScenarioSpec spec;
  spec.scenario = "chairs25";
  spec.robots = 6;
  spec.poses_per_robot = 40;
  spec.seed = 2;
  return spec;
}

OnlineRun RunTwin(const SimulationData& data, const RobotSessionOptions& session) {
  OnlineOptions options;
  options.solver = DriverOptions(session.dgs);
  options.lambda = session.slam.rendezvous.lambda();
  return RunOnline(data, session.slam, options);
}

struct Crash : std::runtime_error {
  Crash() : std::runtime_error("simulated crash") {}
};

// One session per robot, each on its thread over one in-process network, with the options
// `options(robot)` gives; a session that throws Crash is restarted (a fresh transport, as a new
// process) with the same options. Every other failure fails the test.
std::vector<RobotSessionResult> RunSessions(
    const SimulationData& data, int robots,
    const std::function<RobotSessionOptions(int)>& options) {
  InProcessNetwork net;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < robots; ++r) transports.push_back(net.connect(r, {[](const std::string&) {}}));
  std::vector<RobotSessionResult> results(static_cast<std::size_t>(robots));
  std::vector<std::string> errors(results.size());
  std::vector<std::thread> threads;
  for (int r = 0; r < robots; ++r) {
    threads.emplace_back([&, r]() {
      const auto ri = static_cast<std::size_t>(r);
      const RobotSessionOptions o = options(r);
      while (true) {
        try {
          RobotSession session(SliceForRobot(data, r), *transports[ri], o);
          results[ri] = session.run();
          return;
        } catch (const Crash&) {
          transports[ri].reset();  // the process is gone; restarted, it receives the history
          transports[ri] = net.connect(r, {[](const std::string&) {}});
        } catch (const std::exception& e) {
          errors[ri] = e.what();
          return;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& e : errors) EXPECT_EQ(e, "");
  return results;
}

// Every group solve of every robot and its final map against the twin: the same steps, robots
// and sweeps; returns the largest difference of a map (m or rad), counts the solves compared.
double CompareWithTwin(const std::vector<RobotSessionResult>& results, const OnlineRun& twin,
                       std::size_t* solves) {
  double largest_difference = 0.0;
  for (int r = 0; r < static_cast<int>(results.size()); ++r) {
    const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
    std::vector<const GroupSolveRecord*> expected;
    for (const GroupSolveRecord& s : twin.solves) {
      if (std::find(s.robots.begin(), s.robots.end(), r) != s.robots.end()) expected.push_back(&s);
    }
    EXPECT_EQ(got.solves.size(), expected.size()) << "robot " << r;
    for (std::size_t i = 0; i < std::min(expected.size(), got.solves.size()); ++i) {
      const SessionSolve& s = got.solves[i];
      EXPECT_EQ(s.step, expected[i]->step);
      EXPECT_EQ(s.robots, expected[i]->robots);
      EXPECT_EQ(s.refine_steps, expected[i]->refine_steps);
      EXPECT_EQ(s.rotation_rounds, expected[i]->rotation_sweeps);
      if (!s.replayed) {
        EXPECT_GT(s.sent.estimates_bytes + s.sent.status_bytes, 0);
      }
      const Values& map = twin.maps.at({s.step, r});
      largest_difference = std::max(largest_difference, MaxPoseDifference(s.estimate, map));
      EXPECT_EQ(s.estimate.size(), map.size());
      ++*solves;
    }
    const Values& final_map = twin.slam.robots[static_cast<std::size_t>(r)].estimate();
    EXPECT_EQ(got.final_estimate.size(), final_map.size());
    largest_difference = std::max(largest_difference, MaxPoseDifference(got.final_estimate, final_map));
  }
  return largest_difference;
}

TEST(OnlineSession, OverTheInProcessTransportEqualsTheInProcessTwin) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  const RobotSessionOptions options = OnlineSessionOptions(spec);
  const OnlineRun twin = RunTwin(data, options);
  ASSERT_GE(twin.solves.size(), 3u);
  int team_factors = 0, borrowed = 0;
  std::size_t largest = 0;
  for (const GroupSolveRecord& s : twin.solves) {
    team_factors += s.team_factors;
    borrowed += s.borrowed;
    largest = std::max(largest, s.robots.size());
  }
  // The schedule exercises held partner landmarks (robots out of range), copies held by another
  // robot of the group (the joining statuses' team pairs), and a group of three.
  EXPECT_GT(team_factors, 0);
  EXPECT_GT(borrowed, 0);
  EXPECT_GE(largest, 3u);

  const std::vector<RobotSessionResult> results =
      RunSessions(data, spec.robots, [&](int) { return options; });
  std::size_t solves = 0;
  const double largest_difference = CompareWithTwin(results, twin, &solves);
  EXPECT_GT(solves, twin.solves.size());  // each solve counted once per robot of it
  EXPECT_LE(largest_difference, 1e-9);
  std::printf("online twin vs sessions: %zu group solves (largest %zu robots, %d team factors), "
              "largest difference %.2e\n",
              twin.solves.size(), largest, team_factors, largest_difference);
}

// A robot killed in the DGS of a group solve, and again between two solves, and restarted each
// time from its state directory: every robot's maps are still the twin's (the finished solves
// taken from the journal, the interrupted one resumed from its node's journal).
TEST(OnlineSession, ARobotKilledInAndBetweenGroupSolvesResumesFromItsJournal) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  const RobotSessionOptions base = OnlineSessionOptions(spec);
  const OnlineRun twin = RunTwin(data, base);
  std::map<int, int> solves_of;
  for (const GroupSolveRecord& s : twin.solves) {
    for (int r : s.robots) ++solves_of[r];
  }
  ASSERT_FALSE(solves_of.empty());
  const int victim = std::max_element(solves_of.begin(), solves_of.end(), [](const auto& a,
                                      const auto& b) { return a.second < b.second; })->first;
  ASSERT_GE(solves_of[victim], 4);

  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("moslam_online_restart_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::atomic<int> crashes{0};
  std::atomic<int> solves_seen{0};  // group solves of the running incarnation, replayed included
  std::vector<std::string> log;
  std::mutex log_mutex;
  const std::vector<RobotSessionResult> results = RunSessions(data, spec.robots, [&](int r) {
    RobotSessionOptions o = base;
    o.dgs.state_dir = (dir / std::to_string(r)).string();
    if (r != victim) return o;
    o.log = [&](const std::string& text) {
      std::lock_guard<std::mutex> lock(log_mutex);
      log.push_back(text);
    };
    // First death: in round 6 of its second group solve. Second: right after its third.
    o.dgs.on_round = [&](const DgsNodeRound& round) {
      if (round.round == 0) return;
      if (!round.replayed && round.round == 6 && solves_seen == 1 && crashes == 0) {
        ++crashes;
        solves_seen = 0;
        throw Crash();
      }
    };
    o.on_solve = [&](const SessionSolve& s) {
      ++solves_seen;
      if (!s.replayed && solves_seen == 3 && crashes == 1) {
        ++crashes;
        solves_seen = 0;
        throw Crash();
      }
    };
    return o;
  });
  EXPECT_EQ(crashes, 2);
  std::size_t solves = 0;
  EXPECT_LE(CompareWithTwin(results, twin, &solves), 1e-9);
  const std::vector<SessionSolve>& got = results[static_cast<std::size_t>(victim)].solves;
  ASSERT_EQ(got.size(), static_cast<std::size_t>(solves_of[victim]));
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].replayed, i < 3) << "solve " << i;
  const auto said = [&](const std::string& what) {
    return std::any_of(log.begin(), log.end(),
                       [&](const std::string& l) { return l.find(what) != std::string::npos; });
  };
  EXPECT_TRUE(said("restart: 1 group solves taken from"));
  EXPECT_TRUE(said("restart: 3 group solves taken from"));
  // Each finished solve's node journal is gone (the solve record replaces it); every map saved.
  EXPECT_FALSE(std::filesystem::exists(dir / std::to_string(victim) / "solves" /
                                       fmt::format("step_{:04d}", got[1].step)));
  for (const SessionSolve& s : got) {
    EXPECT_TRUE(std::filesystem::exists(dir / std::to_string(victim) / "maps" /
                                        fmt::format("step_{:04d}", s.step) / "map.g2o"));
  }
  std::filesystem::remove_all(dir);
}

TEST(GroupTransport, MapsTheGroupsRobotsAndRoutesEverythingElse) {
  InProcessNetwork net;
  auto t2 = net.connect(2), t5 = net.connect(5), t7 = net.connect(7);
  std::vector<Received> elsewhere;
  GroupTransport g5(*t5, {2, 5}, 9, [&](Received r) { elsewhere.push_back(std::move(r)); });
  EXPECT_EQ(g5.self(), 1);
  StatusPacket st;
  st.robot = 1;
  st.neighbours = {0};
  g5.publish(st);
  // Robot 2 receives robot 5's status of solve 9 with real ids.
  std::vector<Received> at2;
  for (int i = 0; i < 20 && at2.empty(); ++i) at2 = t2->poll(milliseconds(50));
  ASSERT_EQ(at2.size(), 1u);
  const auto& real = std::get<StatusPacket>(at2[0].packet);
  EXPECT_EQ(real.robot, 5);
  EXPECT_EQ(real.solve, 9u);
  EXPECT_EQ(real.neighbours, std::vector<int>{2});

  // Robot 2's estimates of solve 9 arrive re-labelled; its solve-10 status, robot 7's status
  // and an object list go elsewhere.
  EstimatesPacket e;
  e.receiver = 5;
  e.solve = 9;
  e.round = 1;
  e.message.sender = 2;
  e.message.stage = DgsStage::kRotation;
  e.message.keys = {Key::Pose(2, 3)};
  e.message.values.assign(9, 0.0);
  t2->send(e);
  StatusPacket later;
  later.robot = 2;
  later.solve = 10;
  t2->publish(later);
  StatusPacket other;
  other.robot = 7;
  other.solve = 9;
  t7->publish(other);
  ObjectListPacket list;
  list.robot = 2;
  list.objects.push_back({0, "chair", SE3()});
  t2->publish(list);
  std::vector<Received> got;
  for (int i = 0; i < 40 && (got.empty() || elsewhere.size() < 3); ++i) {
    for (Received& r : g5.poll(milliseconds(50))) got.push_back(std::move(r));
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].sender, 0);
  const auto& mapped = std::get<EstimatesPacket>(got[0].packet);
  EXPECT_EQ(mapped.receiver, 1);
  EXPECT_EQ(mapped.message.sender, 0);
  EXPECT_EQ(mapped.message.keys.front(), Key::Pose(0, 3));
  EXPECT_EQ(elsewhere.size(), 3u);
  EXPECT_EQ(g5.alive(), (std::set<int>{0}));
  EXPECT_THROW(g5.publish(list), InvalidInputError);
  EXPECT_THROW(GroupTransport(*t5, {2, 7}, 9, [](Received) {}), InvalidInputError);
}

}  // namespace
}  // namespace moslam
