// Online mapping between robot sessions (robot_session.h with online = true) as threads over the
// in-process transport: every group solve, and every robot's map after it and at the end, equal
// the in-process twin (online/online_team.h on RunMultiRobotObjectSlam). Between processes over
// DDS: apps/team_test.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
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

OnlineRun RunTwin(const SimulationData& data, const RobotSessionOptions& session) {
  OnlineOptions options;
  options.solver = DriverOptions(session.dgs);
  options.lambda = session.slam.rendezvous.lambda();
  return RunOnline(data, session.slam, options);
}

TEST(OnlineSession, OverTheInProcessTransportEqualsTheInProcessTwin) {
  ScenarioSpec spec;
  spec.scenario = "chairs25";
  spec.robots = 6;
  spec.poses_per_robot = 40;
  spec.seed = 2;
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

  InProcessNetwork net;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {[](const std::string&) {}}));
  std::vector<RobotSessionResult> results(static_cast<std::size_t>(spec.robots));
  std::vector<std::string> errors(results.size());
  std::vector<std::thread> threads;
  for (int r = 0; r < spec.robots; ++r) {
    threads.emplace_back([&, r]() {
      try {
        RobotSession session(SliceForRobot(data, r), *transports[static_cast<std::size_t>(r)],
                             options);
        results[static_cast<std::size_t>(r)] = session.run();
      } catch (const std::exception& e) {
        errors[static_cast<std::size_t>(r)] = e.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& e : errors) ASSERT_EQ(e, "");

  std::size_t solves = 0;
  double largest_difference = 0.0;
  for (int r = 0; r < spec.robots; ++r) {
    const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
    std::vector<const GroupSolveRecord*> expected;
    for (const GroupSolveRecord& s : twin.solves) {
      if (std::find(s.robots.begin(), s.robots.end(), r) != s.robots.end()) expected.push_back(&s);
    }
    ASSERT_EQ(got.solves.size(), expected.size()) << "robot " << r;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const SessionSolve& s = got.solves[i];
      EXPECT_EQ(s.step, expected[i]->step);
      EXPECT_EQ(s.robots, expected[i]->robots);
      EXPECT_EQ(s.refine_steps, expected[i]->refine_steps);
      EXPECT_EQ(s.rotation_rounds, expected[i]->rotation_sweeps);
      EXPECT_GT(s.sent.estimates_bytes + s.sent.status_bytes, 0);
      const Values& map = twin.maps.at({s.step, r});
      largest_difference = std::max(largest_difference, MaxPoseDifference(s.estimate, map));
      EXPECT_EQ(s.estimate.size(), map.size());
      ++solves;
    }
    const Values& final_map = twin.slam.robots[static_cast<std::size_t>(r)].estimate();
    EXPECT_EQ(got.final_estimate.size(), final_map.size());
    largest_difference = std::max(largest_difference, MaxPoseDifference(got.final_estimate, final_map));
  }
  EXPECT_GT(solves, twin.solves.size());  // each solve counted once per robot of it
  EXPECT_LE(largest_difference, 1e-9);
  std::printf("online twin vs sessions: %zu group solves (largest %zu robots, %d team factors), "
              "largest difference %.2e\n",
              twin.solves.size(), largest, team_factors, largest_difference);
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
