// The departure rules of a robot session (team_membership.h) over the in-process transport.
#include "moslam/transport/team_membership.h"

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/transport/in_process_transport.h"

namespace moslam {
namespace {

using std::chrono::milliseconds;

struct Robot0 {
  InProcessNetwork net;
  std::unique_ptr<Transport> transport = net.connect(0, {[](const std::string&) {}});
  std::vector<std::pair<int, int>> journal;
  std::unique_ptr<TeamMembership> membership;
  Robot0() {
    TeamMembership::Options o;
    o.leave_timeout = milliseconds(100);
    o.journal = [this](int robot, int step) { journal.emplace_back(robot, step); };
    membership = std::make_unique<TeamMembership>(0, 3, *transport, o);
  }
  // Hands robot 0 what reached it.
  void receive() {
    for (const Received& r : transport->poll(milliseconds(0))) membership->onPacket(r);
  }
};

StatusPacket Presence(int robot, std::vector<int> gone, RobotState state = RobotState::kJoining) {
  StatusPacket p;
  p.robot = robot;
  p.solve = kPresenceSolve;
  p.state = state;
  p.neighbours = std::move(gone);
  return p;
}

// The presence statuses `t` received.
std::vector<StatusPacket> Presences(Transport& t) {
  std::vector<StatusPacket> out;
  for (const Received& r : t.poll(milliseconds(0))) {
    if (const auto* st = std::get_if<StatusPacket>(&r.packet); st && st->solve == kPresenceSolve) {
      out.push_back(*st);
    }
  }
  return out;
}

// Waited for and not alive for leave_timeout: gone, whether it was seen alive before or never;
// alive: never gone. Journaled at the step it is found gone.
TEST(TeamMembership, ARobotNotAliveForTheLeaveTimeoutHasLeftSeenOrNever) {
  Robot0 r0;
  auto t2 = r0.net.connect(2, {[](const std::string&) {}});
  std::map<int, TeamMembership::Clock::time_point> since;
  const auto now = TeamMembership::Clock::now();
  EXPECT_FALSE(r0.membership->foundLeft(1, 3, since, now));  // robot 1 never started
  EXPECT_FALSE(r0.membership->foundLeft(1, 3, since, now + milliseconds(99)));
  EXPECT_TRUE(r0.membership->foundLeft(1, 3, since, now + milliseconds(100)));
  EXPECT_TRUE(r0.membership->hasLeft(1, 3));
  EXPECT_FALSE(r0.membership->hasLeft(1, 2));
  EXPECT_FALSE(r0.membership->foundLeft(2, 3, since, now + milliseconds(1000)));  // alive
  EXPECT_EQ(since.count(2), 0u);
  EXPECT_EQ(r0.journal, (std::vector<std::pair<int, int>>{{1, 3}}));
  // Its presence status lists robot 1 now.
  const std::vector<StatusPacket> got = Presences(*t2);
  ASSERT_FALSE(got.empty());
  EXPECT_EQ(got.back().neighbours, std::vector<int>{1});
  EXPECT_FALSE(r0.membership->out());
}

// A robot that reads its own id in another's presence status was found gone by the team: it
// leaves the team (journaled as its own departure), every other robot is gone for it, and its
// presence status says so; restored from the journal, the same.
TEST(TeamMembership, ARobotListedGoneByAnotherLeavesTheTeamAndSaysSo) {
  Robot0 r0;
  auto t1 = r0.net.connect(1, {[](const std::string&) {}});
  auto t2 = r0.net.connect(2, {[](const std::string&) {}});
  t1->publish(Presence(1, {0}));
  r0.receive();
  std::map<int, TeamMembership::Clock::time_point> since;
  EXPECT_EQ(r0.membership->outStep(), -1);
  EXPECT_TRUE(r0.membership->foundLeft(1, 5, since));
  EXPECT_TRUE(r0.membership->out());
  EXPECT_EQ(r0.membership->outStep(), 5);
  EXPECT_TRUE(r0.membership->hasLeft(2, 5));
  EXPECT_EQ(r0.journal, (std::vector<std::pair<int, int>>{{0, 5}}));
  const std::vector<StatusPacket> got = Presences(*t2);
  ASSERT_FALSE(got.empty());
  EXPECT_EQ(got.back().state, RobotState::kFailed);

  Robot0 again;
  again.membership->restore(0, 5);
  EXPECT_TRUE(again.membership->out());
  EXPECT_TRUE(again.membership->hasLeft(1, 5));
  EXPECT_FALSE(again.membership->hasLeft(1, 4));
  EXPECT_TRUE(again.journal.empty());  // restoring writes nothing
  EXPECT_THROW(again.membership->restore(3, 1), InvalidInputError);
}

// A robot whose presence status says it left the team is gone at once, alive or not.
TEST(TeamMembership, ARobotThatLeftTheTeamIsGoneAtOnce) {
  Robot0 r0;
  auto t1 = r0.net.connect(1, {[](const std::string&) {}});
  t1->publish(Presence(1, {}, RobotState::kFailed));
  r0.receive();
  std::map<int, TeamMembership::Clock::time_point> since;
  EXPECT_TRUE(r0.membership->foundLeft(1, 7, since));
  EXPECT_EQ(r0.journal, (std::vector<std::pair<int, int>>{{1, 7}}));
  EXPECT_FALSE(r0.membership->out());
}

// A robot it found gone that sends its presence status (it is back) gets this robot's presence
// again, once per news: the same status again brings no answer.
TEST(TeamMembership, ItAnswersARobotItFoundGoneOncePerNews) {
  Robot0 r0;
  auto t1 = r0.net.connect(1, {[](const std::string&) {}});
  r0.membership->markLeft(1, 2, "test");
  EXPECT_EQ(Presences(*t1).size(), 1u);
  t1->publish(Presence(1, {}));
  r0.receive();
  const std::vector<StatusPacket> answer = Presences(*t1);
  ASSERT_EQ(answer.size(), 1u);
  EXPECT_EQ(answer[0].neighbours, std::vector<int>{1});
  t1->publish(Presence(1, {}));
  r0.receive();
  EXPECT_TRUE(Presences(*t1).empty());
  t1->publish(Presence(1, {2}));  // news: answered again
  r0.receive();
  EXPECT_EQ(Presences(*t1).size(), 1u);
}

// A group forming applies every member's list: gone for one member, gone for this robot; a
// member that lists this robot makes it leave the team.
TEST(TeamMembership, AGroupAppliesEveryMembersList) {
  Robot0 r0;
  auto t1 = r0.net.connect(1, {[](const std::string&) {}});
  t1->publish(Presence(1, {2}));
  r0.receive();
  r0.membership->applyGoneLists({0, 1}, 4);
  EXPECT_TRUE(r0.membership->hasLeft(2, 4));
  EXPECT_FALSE(r0.membership->out());
  t1->publish(Presence(1, {0, 2}));
  r0.receive();
  r0.membership->applyGoneLists({0, 1}, 6);
  EXPECT_TRUE(r0.membership->out());
  EXPECT_EQ(r0.journal, (std::vector<std::pair<int, int>>{{2, 4}, {0, 6}}));
}

TEST(TeamMembership, ValidatesItsInputs) {
  InProcessNetwork net;
  auto t = net.connect(1);
  EXPECT_THROW(TeamMembership(0, 3, *t, {}), InvalidInputError);  // another robot's transport
  EXPECT_THROW(TeamMembership(1, 1, *t, {}), InvalidInputError);
  TeamMembership::Options o;
  o.leave_timeout = milliseconds(0);
  EXPECT_THROW(TeamMembership(1, 3, *t, o), InvalidInputError);
}

}  // namespace
}  // namespace moslam
