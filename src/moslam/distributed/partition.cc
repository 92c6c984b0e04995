#include "moslam/distributed/partition.h"

#include <string>

#include "moslam/common/errors.h"

namespace moslam {

std::vector<RobotSubgraph> PartitionByRobot(const PoseGraph& graph) {
  std::map<int, PoseGraph> by_robot;
  for (const RelativePoseFactor& f : graph.factors()) {
    by_robot[f.a().robot].add(f);
    if (f.b().robot != f.a().robot) by_robot[f.b().robot].add(f);
  }
  for (const PriorFactor& p : graph.priors()) by_robot[p.key().robot].add(p);
  std::vector<RobotSubgraph> out;
  out.reserve(by_robot.size());
  for (auto& [robot, sub] : by_robot) out.push_back({robot, std::move(sub)});
  return out;
}

SplitGraph SplitIntoRobots(const PoseGraph& graph, const Values& initial, int num_robots) {
  const std::set<Key> keys = graph.keys();
  for (const Key& k : keys) {
    if (k.robot != 0 || !k.isPose()) {
      throw InvalidInputError("split into robots: " + ToString(k) +
                              " is not a pose of robot 0 (only single-robot pose graphs split)");
    }
  }
  const int n = static_cast<int>(keys.size());
  if (num_robots < 1 || num_robots > n) {
    throw InvalidInputError("split into robots: the factors join " + std::to_string(n) +
                            " poses (vertices without a factor do not count): cannot split them "
                            "among " +
                            std::to_string(num_robots) + " robots");
  }
  SplitGraph out;
  std::map<Key, Key> new_key;
  int i = 0;
  for (const Key& k : keys) {
    // Block b holds poses [b*n/N, (b+1)*n/N) in key order.
    const int robot = static_cast<int>((static_cast<long long>(i) * num_robots) / n);
    const Key nk = Key::Pose(robot, k.index);
    new_key[k] = nk;
    out.original_key[nk] = k;
    const auto it = initial.find(k);
    if (it != initial.end()) out.initial[nk] = it->second;
    ++i;
  }
  for (const RelativePoseFactor& f : graph.factors()) {
    out.graph.add(RelativePoseFactor(new_key.at(f.a()), new_key.at(f.b()), f.measured(),
                                     f.information()));
  }
  for (const PriorFactor& p : graph.priors()) {
    out.graph.add(PriorFactor(new_key.at(p.key()), p.prior(), p.information()));
  }
  return out;
}

Values RestoreOriginalKeys(const Values& values, const std::map<Key, Key>& original_key) {
  Values out;
  for (const auto& [k, v] : values) {
    const auto it = original_key.find(k);
    if (it == original_key.end()) {
      throw InvalidInputError("restore keys: " + ToString(k) + " is not a key of the split graph");
    }
    out[it->second] = v;
  }
  return out;
}

}  // namespace moslam
