#include "moslam/transport/group_formation.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {
namespace {

Received Joining(int sender, std::uint32_t solve, std::vector<int> neighbours,
                 std::vector<TeamPairEntry> team = {}) {
  StatusPacket p;
  p.robot = sender;
  p.solve = solve;
  p.neighbours = std::move(neighbours);
  p.team = std::move(team);
  return {sender, p};
}

TeamPairEntry Pair(std::uint64_t mine, int other_robot, std::uint64_t other) {
  TeamPairEntry e;
  e.mine = mine;
  e.other_robot = other_robot;
  e.other = other;
  return e;
}

TEST(GroupFormation, TheClosureGrowsThroughTheListsHeardWithinTheRange) {
  // 0 - 1 - 2 - 3 and 2 - 5: robot 0 heard 1 and 2; 3 is not heard yet, 5 is out of range.
  const std::map<int, std::vector<int>> lists = {{1, {0, 2}}, {2, {1, 3, 5}}, {4, {3}}};
  std::set<int> group = {0, 1};
  const std::set<int> range = {0, 1, 2, 3, 4};
  GrowClosure(group, lists, &range);
  EXPECT_EQ(group, (std::set<int>{0, 1, 2, 3}));  // 4 lists 3, but nobody heard lists 4
  std::set<int> unrestricted = {0, 1};
  GrowClosure(unrestricted, lists);
  EXPECT_EQ(unrestricted, (std::set<int>{0, 1, 2, 3, 5}));
  std::set<int> alone = {7};
  GrowClosure(alone, lists, &range);
  EXPECT_EQ(alone, std::set<int>{7});
}

TEST(GroupFormation, ASendersFirstStatusOfTheSolveIsItsJoiningStatus) {
  const std::vector<Received> packets = {
      Joining(1, 9, {0}),  // another solve
      Joining(1, 10, {0, 2}, {Pair(4, 3, 7)}),
      Joining(2, 10, {1}),
      Joining(1, 10, {0}),  // its DgsNode's later status: the group that formed
      Joining(6, 10, {0}),  // out of range
  };
  const JoiningStatuses heard = ReadJoiningStatuses(packets, 10, {0, 1, 2, 3});
  EXPECT_EQ(heard.neighbours, (std::map<int, std::vector<int>>{{1, {0, 2}}, {2, {1}}}));
  ASSERT_EQ(heard.team.at(1).size(), 1u);
  EXPECT_EQ(heard.team.at(1)[0].other_robot, 3);
  EXPECT_TRUE(heard.team.at(2).empty());
}

TEST(GroupFormation, PairsWithRobotsOutsideTheGroupAreHeld) {
  std::map<int, std::vector<TeamPairEntry>> team;
  team[0] = {Pair(1, 1, 5), Pair(2, 3, 8)};  // with member 1, with robot 3 outside
  team[1] = {Pair(5, 0, 1), Pair(6, 4, 2)};
  team[1][1].held = true;
  team[1][1].step = 12;
  team[1][1].pose = SE3(SO3(), Vector3(1, 2, 3));
  const std::vector<TeamPair> held = GroupHeldPairs({0, 1}, team);
  ASSERT_EQ(held.size(), 2u);
  EXPECT_EQ(held[0].mine, Key::Object(0, 2));
  EXPECT_EQ(held[0].other, Key::Object(3, 8));
  EXPECT_FALSE(held[0].held);
  EXPECT_EQ(held[1].mine, Key::Object(1, 6));
  EXPECT_EQ(held[1].other, Key::Object(4, 2));
  EXPECT_TRUE(held[1].held);
  EXPECT_EQ(held[1].copy.step, 12);
  EXPECT_EQ(held[1].copy.pose.translation(), Vector3(1, 2, 3));
  EXPECT_THROW(GroupHeldPairs({0, 2}, team), InvalidInputError);  // no status of member 2
}

}  // namespace
}  // namespace moslam::transport_detail
