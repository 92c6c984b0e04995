#include "moslam/slam/constellation.h"

#include <Eigen/SVD>
#include <cmath>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/geometry/so3.h"
#include "moslam/robust/max_clique.h"

namespace moslam {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Whether two associations agree: the relative pose of their objects in map a and in map b.
bool Agree(const SE3& ai, const SE3& ak, const SE3& bj, const SE3& bl,
           const ConstellationConfig& c) {
  const SE3 A = ai.between(ak), B = bj.between(bl);
  const double s_R = c.sigma_rotation_deg * kDeg;
  const double angle = SO3::Log(A.rotation().inverse() * B.rotation()).norm();
  if (angle > c.num_sigmas * 2.0 * s_R) return false;
  const double d = 0.5 * (A.translation().norm() + B.translation().norm());
  const double s_t = c.sigma_translation;
  const double tau = c.num_sigmas * std::sqrt(4.0 * s_t * s_t + 2.0 * d * d * s_R * s_R) +
                     c.drift_per_m * d;
  return (A.translation() - B.translation()).norm() <= tau;
}

// A transform agrees with a candidate when the candidate's object of a, moved by it, lands on its
// object of b within the tolerance of one object at `lever` from the set's centroid.
bool TransformAgrees(const SE3& T, const SE3& ai, const SE3& bj, double lever,
                     const ConstellationConfig& c) {
  const SE3 moved = T * ai;
  const double s_R = c.sigma_rotation_deg * kDeg;
  const double angle = SO3::Log(moved.rotation().inverse() * bj.rotation()).norm();
  if (angle > c.num_sigmas * 2.0 * s_R) return false;
  const double s_t = c.sigma_translation;
  const double tau = c.num_sigmas * std::sqrt(2.0 * s_t * s_t + 2.0 * lever * lever * s_R * s_R) +
                     c.drift_per_m * lever;
  return (moved.translation() - bj.translation()).norm() <= tau;
}

// The consistency graph over candidate pairs (ia, ib) of indices.
ConsistencyGraph BuildGraph(const std::vector<ConstellationObject>& a,
                            const std::vector<ConstellationObject>& b,
                            const std::vector<std::pair<std::size_t, std::size_t>>& candidates,
                            const ConstellationConfig& config) {
  const int n = static_cast<int>(candidates.size());
  ConsistencyGraph g(n);
  for (int p = 0; p < n; ++p) {
    const auto [i, j] = candidates[static_cast<std::size_t>(p)];
    for (int q = p + 1; q < n; ++q) {
      const auto [k, l] = candidates[static_cast<std::size_t>(q)];
      if (i == k || j == l) continue;  // an object is matched at most once
      if (Agree(a[i].pose, a[k].pose, b[j].pose, b[l].pose, config)) g.connect(p, q);
    }
  }
  return g;
}

// The distinct objects a set of candidates (`nodes`, indices into `candidates`) stands for
// (constellation.h, step 4): the most of them no two of which may be one object (their objects of
// a, or of b, of one label and within same_object_radius): a maximum clique of the complement of
// "may be one object".
int DistinctObjects(const std::vector<ConstellationObject>& a,
                    const std::vector<ConstellationObject>& b,
                    const std::vector<std::pair<std::size_t, std::size_t>>& candidates,
                    const std::vector<int>& nodes, const ConstellationConfig& c) {
  const auto near = [&](const ConstellationObject& x, const ConstellationObject& y) {
    return x.label == y.label &&
           (x.pose.translation() - y.pose.translation()).norm() <= c.same_object_radius;
  };
  const int n = static_cast<int>(nodes.size());
  ConsistencyGraph distinct(n);
  for (int p = 0; p < n; ++p) {
    for (int q = p + 1; q < n; ++q) {
      const auto [i, j] = candidates[static_cast<std::size_t>(nodes[static_cast<std::size_t>(p)])];
      const auto [k, l] = candidates[static_cast<std::size_t>(nodes[static_cast<std::size_t>(q)])];
      if (!near(a[i], a[k]) && !near(b[j], b[l])) distinct.connect(p, q);
    }
  }
  return static_cast<int>(MaximumClique(distinct, {}, c.max_search_nodes).nodes.size());
}

SE3 FitTransform(const std::vector<ConstellationObject>& a,
                 const std::vector<ConstellationObject>& b,
                 const std::vector<std::pair<std::size_t, std::size_t>>& pairs) {
  Matrix3 sum = Matrix3::Zero();
  for (const auto& [i, j] : pairs) {
    sum += b[j].pose.rotation().matrix() * a[i].pose.rotation().matrix().transpose();
  }
  const SO3 R = SO3::FromMatrixNormalized(sum);
  Vector3 t = Vector3::Zero();
  for (const auto& [i, j] : pairs) t += b[j].pose.translation() - R * a[i].pose.translation();
  t /= static_cast<double>(pairs.size());
  return SE3(R, t);
}

}  // namespace

void ConstellationConfig::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw InvalidInputError(std::string("constellation config: ") + name +
                              " must be positive and finite");
    }
  };
  positive(sigma_translation, "sigma_translation");
  positive(sigma_rotation_deg, "sigma_rotation_deg");
  positive(num_sigmas, "num_sigmas");
  if (!(drift_per_m >= 0.0) || !std::isfinite(drift_per_m)) {
    throw InvalidInputError("constellation config: drift_per_m must be finite and >= 0");
  }
  if (min_support < 2) {
    throw InvalidInputError("constellation config: min_support must be at least 2 (one object "
                            "fixes a transform by itself, but nothing confirms it)");
  }
  if (ambiguity_margin < 0) {
    throw InvalidInputError("constellation config: ambiguity_margin must be >= 0");
  }
  if (!(same_object_radius >= 0.0) || !std::isfinite(same_object_radius)) {
    throw InvalidInputError("constellation config: same_object_radius must be finite and >= 0");
  }
  if (max_search_nodes < 1) {
    throw InvalidInputError("constellation config: max_search_nodes must be positive");
  }
}

std::string ToString(AlignmentStatus status) {
  switch (status) {
    case AlignmentStatus::kAligned:
      return "aligned";
    case AlignmentStatus::kTooFew:
      return "too few consistent objects";
    case AlignmentStatus::kAmbiguous:
      return "ambiguous";
    case AlignmentStatus::kContradicted:
      return "contradicted by the overlap";
  }
  return "unknown";
}

ConstellationAlignment AlignConstellations(const std::vector<ConstellationObject>& a,
                                           const std::vector<ConstellationObject>& b,
                                           const ConstellationConfig& config) {
  config.validate();
  ConstellationAlignment out;
  std::vector<std::pair<std::size_t, std::size_t>> candidates;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = 0; j < b.size(); ++j) {
      if (a[i].label == b[j].label) candidates.emplace_back(i, j);
    }
  }
  out.candidates = static_cast<int>(candidates.size());
  if (candidates.empty()) {
    out.reason = "no object label in common";
    return out;
  }
  const ConsistencyGraph graph = BuildGraph(a, b, candidates, config);
  const CliqueResult best = MaximumClique(graph, {}, config.max_search_nodes);
  out.exact = best.exact;
  std::vector<std::pair<std::size_t, std::size_t>> set;
  for (int p : best.nodes) set.push_back(candidates[static_cast<std::size_t>(p)]);
  out.support = DistinctObjects(a, b, candidates, best.nodes, config);
  const SE3 T = FitTransform(a, b, set);
  // The rival: the best set among the candidates that associate the best set's objects
  // otherwise (an object of the best set with another partner): another reading of the same
  // objects, as a symmetric layout allows.
  std::vector<char> a_used(a.size(), 0), b_used(b.size(), 0);
  for (const auto& [i, j] : set) {
    a_used[i] = 1;
    b_used[j] = 1;
  }
  std::vector<bool> in_best(candidates.size(), false);
  for (int p : best.nodes) in_best[static_cast<std::size_t>(p)] = true;
  Vector3 centroid = Vector3::Zero();
  for (const auto& [i, j] : set) centroid += b[j].pose.translation();
  centroid /= static_cast<double>(set.size());
  std::vector<bool> other(candidates.size(), false);
  for (std::size_t p = 0; p < candidates.size(); ++p) {
    const auto [i, j] = candidates[p];
    if (in_best[p] || !(a_used[i] || b_used[j])) continue;
    // A duplicate landmark of the same object (same reading, the transform agrees) is no rival.
    const double lever = (b[j].pose.translation() - centroid).norm();
    other[p] = !TransformAgrees(T, a[i].pose, b[j].pose, lever, config);
  }
  const CliqueResult rival = MaximumClique(graph, other, config.max_search_nodes);
  out.exact = out.exact && rival.exact;
  bool any_other = false;
  for (bool o : other) any_other = any_other || o;
  out.rival = any_other ? DistinctObjects(a, b, candidates, rival.nodes, config) : 0;
  if (out.support < config.min_support) {
    out.status = AlignmentStatus::kTooFew;
    out.reason = std::to_string(out.support) + " consistent object(s), " +
                 std::to_string(config.min_support) + " needed";
    return out;
  }
  if (out.rival >= out.support - config.ambiguity_margin) {
    out.status = AlignmentStatus::kAmbiguous;
    out.reason = "a set of " + std::to_string(out.rival) +
                 " objects agrees with another transform, against " +
                 std::to_string(out.support);
    return out;
  }
  out.status = AlignmentStatus::kAligned;
  out.b_T_a = T;
  for (const auto& [i, j] : set) out.pairs.emplace_back(a[i].id, b[j].id);
  return out;
}

std::vector<std::size_t> ConsistentSubset(
    const std::vector<ConstellationObject>& a, const std::vector<ConstellationObject>& b,
    const std::vector<std::pair<std::size_t, std::size_t>>& pairs,
    const ConstellationConfig& config) {
  config.validate();
  if (pairs.empty()) return {};
  const ConsistencyGraph graph = BuildGraph(a, b, pairs, config);
  const CliqueResult best = MaximumClique(graph, {}, config.max_search_nodes);
  return std::vector<std::size_t>(best.nodes.begin(), best.nodes.end());
}

}  // namespace moslam
