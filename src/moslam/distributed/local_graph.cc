#include "moslam/distributed/local_graph.h"

#include <algorithm>
#include <numeric>
#include <string>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

LocalGraph::LocalGraph(int robot, const PoseGraph& subgraph, const Values& initial,
                       const Key& anchor)
    : robot_(robot), anchor_(anchor) {
  const std::set<Key> own = takeFactors(subgraph);
  if (own.empty()) {
    throw UnderdeterminedError("DGS robot " + std::to_string(robot_) +
                               ": its subgraph touches none of its variables");
  }
  numberNeighbours();
  own_.assign(own.begin(), own.end());
  owns_anchor_ = own.count(anchor_) > 0;
  for (const Key& k : own_) {
    const auto it = initial.find(k);
    initial_[k] = it != initial.end() ? it->second : SE3();
    if (k == anchor_) continue;
    unknown_index_[k] = static_cast<int>(unknowns_.size());
    unknowns_.push_back(k);
  }
  groupUnknowns();
}

std::set<Key> LocalGraph::takeFactors(const PoseGraph& subgraph) {
  std::set<Key> own;
  // In canonical order, not the subgraph's: a robot that reads its own file and the driver that
  // partitions the whole graph list a robot's factors differently, and the sums over them must
  // round alike for the two to reach the same estimate (README, "A long 2D chain over DDS").
  std::vector<RelativePoseFactor> factors = subgraph.factors();
  std::stable_sort(factors.begin(), factors.end(),
                   [](const auto& x, const auto& y) { return CanonicalBefore(x, y); });
  for (const RelativePoseFactor& f : factors) {
    const bool own_a = f.a().robot == robot_;
    const bool own_b = f.b().robot == robot_;
    if (!own_a && !own_b) {
      throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": factor " +
                              ToString(f.a()) + "-" + ToString(f.b()) +
                              " touches none of its variables");
    }
    const std::size_t index = factors_.size();
    factors_.push_back(f);
    if (own_a) own.insert(f.a());
    if (own_b) own.insert(f.b());
    if (own_a && own_b) {
      inner_.push_back(index);
    } else {
      const Key mine = own_a ? f.a() : f.b();
      const Key theirs = own_a ? f.b() : f.a();
      separators_.push_back({index, mine, theirs, theirs.robot, 0});
      neighbour_keys_.insert(theirs);
      shared_with_[theirs.robot].push_back(mine);
    }
  }
  std::vector<PriorFactor> priors = subgraph.priors();
  std::stable_sort(priors.begin(), priors.end(),
                   [](const auto& x, const auto& y) { return CanonicalBefore(x, y); });
  for (const PriorFactor& p : priors) {
    if (p.key().robot != robot_) {
      throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": prior on " +
                              ToString(p.key()) + " is another robot's");
    }
    priors_.push_back(p);
    own.insert(p.key());
  }
  return own;
}

void LocalGraph::numberNeighbours() {
  for (auto& [r, keys] : shared_with_) {
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  }
  neighbour_list_.assign(neighbour_keys_.begin(), neighbour_keys_.end());
  for (std::size_t i = 0; i < neighbour_list_.size(); ++i) {
    neighbour_slot_[neighbour_list_[i]] = static_cast<int>(i);
  }
  for (Separator& sep : separators_) sep.slot = neighbour_slot_.at(sep.foreign);
}

void LocalGraph::groupUnknowns() {
  const int n = static_cast<int>(unknowns_.size());
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (std::size_t i : inner_) {
    const int a = unknownIndex(factors_[i].a()), b = unknownIndex(factors_[i].b());
    if (a >= 0 && b >= 0) parent[Find(parent, a)] = Find(parent, b);
  }
  std::map<int, int> root_to_group;
  group_of_.assign(static_cast<std::size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    const auto [it, inserted] =
        root_to_group.emplace(Find(parent, i), static_cast<int>(root_to_group.size()));
    group_of_[i] = it->second;
  }
  group_fixed_.assign(root_to_group.size(), false);
  group_separators_.assign(root_to_group.size(), {});
  for (std::size_t i : inner_) {
    const Key a = factors_[i].a(), b = factors_[i].b();
    if (a == anchor_ && b != anchor_) group_fixed_[group_of_[unknownIndex(b)]] = true;
    if (b == anchor_ && a != anchor_) group_fixed_[group_of_[unknownIndex(a)]] = true;
  }
  for (const PriorFactor& p : priors_) {
    const int i = unknownIndex(p.key());
    if (i >= 0) group_fixed_[group_of_[i]] = true;
  }
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    const int i = unknownIndex(separators_[s].own);
    if (i >= 0) group_separators_[group_of_[i]].push_back(s);
  }
}

int LocalGraph::unknownIndex(const Key& key) const {
  const auto it = unknown_index_.find(key);
  return it == unknown_index_.end() ? -1 : it->second;
}

int LocalGraph::slot(const Key& key) const {
  const auto it = neighbour_slot_.find(key);
  return it == neighbour_slot_.end() ? -1 : it->second;
}

std::set<int> LocalGraph::neighbourRobots() const {
  std::set<int> robots;
  for (const Key& k : neighbour_keys_) robots.insert(k.robot);
  return robots;
}

std::map<int, int> LocalGraph::neighbourLinks() const {
  std::map<int, int> links;
  for (const Key& k : neighbour_keys_) ++links[k.robot];
  return links;
}

std::vector<bool> LocalGraph::anchoredUnknowns(const std::vector<bool>& usable) const {
  std::vector<bool> group(group_fixed_.size());
  for (std::size_t g = 0; g < group.size(); ++g) {
    bool reached = group_fixed_[g];
    for (std::size_t s : group_separators_[g]) reached = reached || usable[s];
    group[g] = reached;
  }
  std::vector<bool> out(group_of_.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = group[static_cast<std::size_t>(group_of_[i])];
  return out;
}

}  // namespace moslam
