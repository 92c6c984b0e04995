#include "moslam/metrics/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

// Below this ratio of the second to the first singular value of the cross-covariance the points
// are treated as collinear: exactly collinear points give ~1e-16 after rounding.
constexpr double kCollinearRatio = 1e-12;

bool IsFinite(const SE3& x) {
  return x.rotation().matrix().allFinite() && x.translation().allFinite();
}

const SE3& Lookup(const Values& estimate, const Key& key) {
  const auto it = estimate.find(key);
  if (it == estimate.end()) {
    throw InvalidInputError("variable " + ToString(key) +
                            " of the reference is missing from the estimate (the two come from "
                            "different graphs or the estimate is partial)");
  }
  return it->second;
}

}  // namespace

ErrorStats ComputeErrorStats(const Values& estimate, const Values& reference,
                             const std::function<bool(const Key&)>& select) {
  double sum_t2 = 0.0;
  double sum_r2 = 0.0;
  int count = 0;
  for (const auto& [key, ref] : reference) {
    if (!select(key)) continue;
    const SE3& est = Lookup(estimate, key);
    if (!IsFinite(est) || !IsFinite(ref)) {
      throw InvalidInputError("variable " + ToString(key) + " is not finite in the " +
                              (IsFinite(ref) ? "estimate" : "reference") +
                              " (a diverged solve?)");
    }
    sum_t2 += (est.translation() - ref.translation()).squaredNorm();
    const SO3 dR(ref.rotation().matrix().transpose() * est.rotation().matrix());
    sum_r2 += SO3::Log(dR).squaredNorm();
    ++count;
  }
  ErrorStats stats;
  stats.count = count;
  if (count > 0) {
    stats.ate = std::sqrt(sum_t2 / count);
    stats.are_deg = std::sqrt(sum_r2 / count) * kRadToDeg;
  }
  return stats;
}

TrajectoryErrors CompareEstimates(const Values& estimate, const Values& reference) {
  TrajectoryErrors errors;
  errors.poses = ComputeErrorStats(estimate, reference, [](const Key& k) { return k.isPose(); });
  errors.objects =
      ComputeErrorStats(estimate, reference, [](const Key& k) { return k.isObject(); });
  return errors;
}

SE3 AlignRigid(const std::vector<Vector3>& source, const std::vector<Vector3>& target) {
  if (source.size() != target.size()) {
    throw InvalidInputError("AlignRigid: " + std::to_string(source.size()) +
                            " source points but " + std::to_string(target.size()) +
                            " target points");
  }
  const std::size_t n = source.size();
  if (n < 3) {
    throw UnderdeterminedError("AlignRigid: " + std::to_string(n) +
                               " point pairs cannot fix a rotation (at least 3 non-collinear "
                               "points are needed)");
  }
  Vector3 mu_src = Vector3::Zero();
  Vector3 mu_dst = Vector3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!source[i].allFinite() || !target[i].allFinite()) {
      throw InvalidInputError("AlignRigid: point pair " + std::to_string(i) + " is not finite");
    }
    mu_src += source[i];
    mu_dst += target[i];
  }
  const double inv_n = 1.0 / static_cast<double>(n);
  mu_src *= inv_n;
  mu_dst *= inv_n;

  // Cross-covariance Sigma = 1/n sum (y - mu_y)(x - mu_x)^T = U D V^T; R = U S V^T with
  // S = diag(1, 1, det(U) det(V)) (Umeyama 1991, eq. 39-43, scale fixed to 1).
  Matrix3 sigma = Matrix3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    sigma += (target[i] - mu_dst) * (source[i] - mu_src).transpose();
  }
  sigma *= inv_n;
  const Eigen::JacobiSVD<Matrix3> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vector3& d = svd.singularValues();
  if (!(d(0) > 0.0) || d(1) <= kCollinearRatio * d(0)) {
    throw UnderdeterminedError(
        "AlignRigid: the points are collinear or coincident, so the rotation about their line "
        "is not determined (degenerate cross-covariance)");
  }
  Matrix3 S = Matrix3::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  const Matrix3 R = svd.matrixU() * S * svd.matrixV().transpose();
  return SE3(SO3(R), mu_dst - R * mu_src);
}

Values TransformValues(const SE3& T, const Values& values) {
  Values out;
  for (const auto& [key, x] : values) out.emplace_hint(out.end(), key, T * x);
  return out;
}

double MaxPoseDifference(const Values& estimate, const Values& reference) {
  double worst = 0.0;
  for (const auto& [key, r] : reference) {
    const auto it = estimate.find(key);
    if (it == estimate.end()) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, (it->second.translation() - r.translation()).norm());
    worst = std::max(worst, (it->second.rotation().matrix() - r.rotation().matrix()).norm());
  }
  return worst;
}

GroundTruthErrors CompareToGroundTruth(const Values& estimate, const Values& ground_truth) {
  GroundTruthErrors result;
  // Also validates: every ground-truth key present in the estimate, every compared pose finite.
  result.unaligned = CompareEstimates(estimate, ground_truth);

  std::vector<Vector3> source;
  std::vector<Vector3> target;
  for (const auto& [key, gt] : ground_truth) {
    if (!key.isPose()) continue;
    source.push_back(estimate.at(key).translation());
    target.push_back(gt.translation());
  }
  result.alignment = AlignRigid(source, target);
  result.aligned = CompareEstimates(TransformValues(result.alignment, estimate), ground_truth);
  return result;
}

}  // namespace moslam
