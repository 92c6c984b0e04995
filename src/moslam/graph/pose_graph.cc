#include "moslam/graph/pose_graph.h"

#include <algorithm>
#include <queue>
#include <utility>
#include <unordered_map>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

const SE3& Lookup(const Values& values, Key key) {
  const auto it = values.find(key);
  if (it == values.end()) {
    throw InvalidInputError("no estimate for variable " + ToString(key) +
                            " (it appears in a factor but not in the values)");
  }
  return it->second;
}

// Lexicographic order of (pose, information) over the doubles of the rotation matrix, the
// translation and the information matrix.
bool Before(const SE3& x, const Matrix6& ix, const SE3& y, const Matrix6& iy) {
  const auto less = [](const auto& u, const auto& v) {
    return std::lexicographical_compare(u.data(), u.data() + u.size(), v.data(),
                                        v.data() + v.size());
  };
  const auto same = [](const auto& u, const auto& v) {
    return std::equal(u.data(), u.data() + u.size(), v.data());
  };
  const Matrix3& rx = x.rotation().matrix();
  const Matrix3& ry = y.rotation().matrix();
  if (!same(rx, ry)) return less(rx, ry);
  if (!same(x.translation(), y.translation())) return less(x.translation(), y.translation());
  return less(ix, iy);
}

}  // namespace

bool CanonicalBefore(const RelativePoseFactor& x, const RelativePoseFactor& y) {
  if (x.a() < y.a() || y.a() < x.a()) return x.a() < y.a();
  if (x.b() < y.b() || y.b() < x.b()) return x.b() < y.b();
  return Before(x.measured(), x.information(), y.measured(), y.information());
}

bool CanonicalBefore(const PriorFactor& x, const PriorFactor& y) {
  if (x.key() < y.key() || y.key() < x.key()) return x.key() < y.key();
  return Before(x.prior(), x.information(), y.prior(), y.information());
}

std::vector<std::size_t> CanonicalOrder(const std::vector<RelativePoseFactor>& factors) {
  std::vector<std::size_t> order(factors.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
    return CanonicalBefore(factors[i], factors[j]);
  });
  return order;
}

PoseGraph::PoseGraph(std::vector<RelativePoseFactor> factors) : factors_(std::move(factors)) {
  for (const auto& f : factors_) {
    keys_.insert(f.a());
    keys_.insert(f.b());
  }
}

void PoseGraph::add(const RelativePoseFactor& factor) {
  factors_.push_back(factor);
  keys_.insert(factor.a());
  keys_.insert(factor.b());
}

void PoseGraph::add(const PriorFactor& prior) {
  priors_.push_back(prior);
  keys_.insert(prior.key());
}

int PoseGraph::numRobots() const {
  int n = 0;
  for (const Key& k : keys()) n = std::max(n, k.robot + 1);
  return n;
}

double PoseGraph::cost(const Values& values) const {
  double total = 0.0;
  for (const auto& f : factors_) total += f.cost(Lookup(values, f.a()), Lookup(values, f.b()));
  for (const auto& p : priors_) total += p.cost(Lookup(values, p.key()));
  return total;
}

Key GaugeAnchor(const PoseGraph& graph) {
  if (graph.factors().empty() && graph.priors().empty()) {
    throw UnderdeterminedError(
        "nothing to solve: the graph has no factors (vertices alone constrain nothing; does the "
        "g2o file lack its EDGE_SE3:QUAT lines?)");
  }
  for (const Key& k : graph.keys()) {
    if (k.robot == 0 && k.isPose()) return k;  // keys() is ordered: the first is the smallest
  }
  throw UnderdeterminedError(
      "no gauge anchor: robot 0 has no pose (the first pose of robot 0 is held fixed; "
      "is robot 0's file missing or empty?)");
}

std::vector<Key> UnreachableFrom(const PoseGraph& graph, Key root) {
  std::unordered_map<Key, std::vector<Key>> adj;
  for (const auto& f : graph.factors()) {
    adj[f.a()].push_back(f.b());
    adj[f.b()].push_back(f.a());
  }
  std::set<Key> seen{root};
  std::queue<Key> q;
  q.push(root);
  for (const auto& p : graph.priors()) {
    if (seen.insert(p.key()).second) q.push(p.key());
  }
  while (!q.empty()) {
    const Key k = q.front();
    q.pop();
    for (const Key& n : adj[k]) {
      if (seen.insert(n).second) q.push(n);
    }
  }
  std::vector<Key> out;
  for (const Key& k : graph.keys()) {
    if (!seen.count(k)) out.push_back(k);
  }
  return out;
}

void RequireAnchored(const PoseGraph& graph, Key root) {
  const std::vector<Key> loose = UnreachableFrom(graph, root);
  if (loose.empty()) return;
  std::string names;
  for (size_t i = 0; i < loose.size() && i < 5; ++i) names += (i ? ", " : "") + ToString(loose[i]);
  if (loose.size() > 5) names += ", ...";
  throw UnderdeterminedError("the graph is disconnected: " + std::to_string(loose.size()) +
                             " variable(s) (" + names + ") are linked neither to the anchor " +
                             ToString(root) + " nor to a prior, so their gauge is free "
                             "(a missing inter-robot edge or a missing file?)");
}

}  // namespace moslam
