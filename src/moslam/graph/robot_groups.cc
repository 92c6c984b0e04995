#include "moslam/graph/robot_groups.h"

#include <algorithm>
#include <map>
#include <utility>

namespace moslam {

std::vector<std::vector<int>> ConnectedRobots(const std::vector<int>& robots,
                                              const std::vector<std::pair<int, int>>& links) {
  std::map<int, int> parent;  // union-find, each root the lowest robot of its group
  for (int r : robots) parent[r] = r;
  const auto find = [&](int r) {
    while (parent.at(r) != r) r = parent[r] = parent.at(parent.at(r));
    return r;
  };
  for (const auto& [a, b] : links) {
    if (a == b || parent.count(a) == 0 || parent.count(b) == 0) continue;
    const int ra = find(a), rb = find(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  std::map<int, std::vector<int>> groups;
  for (const auto& [r, p] : parent) groups[find(r)].push_back(r);  // robots come sorted
  std::vector<std::vector<int>> out;
  for (auto& [root, g] : groups) out.push_back(std::move(g));
  return out;
}

}  // namespace moslam
