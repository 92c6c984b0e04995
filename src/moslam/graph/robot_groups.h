// Robots grouped by their links: the connected components of a robot graph (the robots in range
// at a rendezvous, the robots a separator check has linked).
#pragma once

#include <utility>
#include <vector>

namespace moslam {

// `robots` (any order; repeats count once) grouped by connection through `links` (pairs of
// robots; a link with an end outside `robots`, or a robot to itself, is ignored): each group
// sorted, groups by their lowest robot.
std::vector<std::vector<int>> ConnectedRobots(const std::vector<int>& robots,
                                              const std::vector<std::pair<int, int>>& links);

}  // namespace moslam
