#include "moslam/graph/robot_groups.h"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

namespace moslam {
namespace {

TEST(ConnectedRobots, GroupsByLinksIgnoringOutsideEndsAndSelfLinks) {
  // 5 - 2 - 7 linked (2 listed twice, counted once); 3 alone: a link to itself, and one to 9,
  // which is not listed.
  const std::vector<int> robots = {7, 3, 2, 5, 2};
  const std::vector<std::pair<int, int>> links = {{5, 2}, {7, 2}, {3, 3}, {3, 9}};
  const std::vector<std::vector<int>> groups = ConnectedRobots(robots, links);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0], (std::vector<int>{2, 5, 7}));
  EXPECT_EQ(groups[1], (std::vector<int>{3}));
  EXPECT_TRUE(ConnectedRobots({}, links).empty());
}

}  // namespace
}  // namespace moslam
