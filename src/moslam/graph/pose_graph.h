// A pose graph: relative-pose factors and priors over SE(3) variables, and its cost
//   F(x) = sum_f 1/2 r_f^T Omega_f r_f   (GTSAM NonlinearFactorGraph::error).
#pragma once

#include <map>
#include <set>
#include <vector>

#include "moslam/graph/factors.h"

namespace moslam {

// An estimate: one pose per variable, ordered by key (deterministic iteration).
using Values = std::map<Key, SE3>;

class PoseGraph {
 public:
  PoseGraph() = default;
  // The graph of these factors (taken over, not copied).
  explicit PoseGraph(std::vector<RelativePoseFactor> factors);

  void add(const RelativePoseFactor& factor);
  void add(const PriorFactor& prior);
  // Room for `factors` relative-pose factors without reallocating.
  void reserve(std::size_t factors) { factors_.reserve(factors); }

  const std::vector<RelativePoseFactor>& factors() const { return factors_; }
  const std::vector<PriorFactor>& priors() const { return priors_; }
  bool empty() const { return factors_.empty() && priors_.empty(); }

  // Every variable some factor touches, ordered (kept up to date by add()).
  const std::set<Key>& keys() const { return keys_; }
  // Number of robots: 1 + the largest robot id of any variable (0 for an empty graph).
  int numRobots() const;

  // Throws InvalidInputError naming the first variable missing from `values`.
  double cost(const Values& values) const;

 private:
  std::vector<RelativePoseFactor> factors_;
  std::vector<PriorFactor> priors_;
  std::set<Key> keys_;
};

// A total order on factors up to identical ones, whatever order a graph lists them in: by ends
// (a, then b), then measurement (rotation matrix, translation), then information, each by its
// doubles in lexicographic order. Robots that read their subgraphs from different files sum and
// exchange their factors in this order, so that they round alike and name the same separators.
bool CanonicalBefore(const RelativePoseFactor& x, const RelativePoseFactor& y);
bool CanonicalBefore(const PriorFactor& x, const PriorFactor& y);  // by key, prior, information

// The positions of `factors` in canonical order (stable: identical factors keep their order).
std::vector<std::size_t> CanonicalOrder(const std::vector<RelativePoseFactor>& factors);

// The gauge of CONVENTIONS.md: the first pose of robot 0 (smallest key with robot 0, kind pose).
// Throws UnderdeterminedError when robot 0 has no pose.
Key GaugeAnchor(const PoseGraph& graph);

// Variables connected through factors neither to `root` nor to any prior: the part of the graph
// whose gauge nothing fixes (empty when the problem is well posed).
std::vector<Key> UnreachableFrom(const PoseGraph& graph, Key root);

// Throws UnderdeterminedError, naming a few of the variables, when UnreachableFrom is not empty.
void RequireAnchored(const PoseGraph& graph, Key root);

}  // namespace moslam
