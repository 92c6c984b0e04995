// An independent Ceres implementation of the moslam pose-graph cost (benchmark cross-check only).
//
// Per edge (a, b, z, Omega = U^T U) the residual is U * Log(z^-1 a^-1 b) with the exact SE(3) Log
// in tangent order (w, v), exactly the cost of shared/CONVENTIONS.md, so Ceres' cost
// 1/2 sum ||U r||^2 equals moslam's F. Nothing here uses moslam's geometry code: the group
// operations and the logarithm are written from the formulas, templated for ceres::Jet, and
// differentiated by ceres::AutoDiffCostFunction. A disagreement in cost or optimum therefore points
// at a bug in one of the two implementations.
//
// Pose parameter block (7 doubles): [qx qy qz qw tx ty tz], a unit quaternion (Eigen order, for
// ceres::EigenQuaternionManifold) and the translation; R, t map body to world.
#pragma once

#include <array>

#include <Eigen/Core>
#include <ceres/autodiff_cost_function.h>
#include <ceres/cost_function.h>

namespace moslam_bench {

constexpr int kPoseSize = 7;

// Quaternions as (w, x, y, z) arrays inside the templates (independent of the block layout).
template <typename T>
using Quat = std::array<T, 4>;
template <typename T>
using Vec3 = std::array<T, 3>;

template <typename T>
Quat<T> QuatFromBlock(const T* p) {
  return {p[3], p[0], p[1], p[2]};
}

template <typename T>
Quat<T> QuatConjugate(const Quat<T>& q) {
  return {q[0], -q[1], -q[2], -q[3]};
}

// Hamilton product p * q.
template <typename T>
Quat<T> QuatMultiply(const Quat<T>& p, const Quat<T>& q) {
  return {p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
          p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
          p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
          p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]};
}

template <typename T>
Vec3<T> Cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// R(q) p for a unit quaternion: p + 2 w (u x p) + 2 u x (u x p).
template <typename T>
Vec3<T> QuatRotate(const Quat<T>& q, const Vec3<T>& p) {
  const Vec3<T> u{q[1], q[2], q[3]};
  const Vec3<T> c1 = Cross(u, p);
  const Vec3<T> c2 = Cross(u, c1);
  const T two(2.0);
  return {p[0] + two * (q[0] * c1[0] + c2[0]), p[1] + two * (q[0] * c1[1] + c2[1]),
          p[2] + two * (q[0] * c1[2] + c2[2])};
}

// Rotation vector w (|w| <= pi) of a unit quaternion. theta = 2 atan2(|u|, qw) after choosing
// qw >= 0, w = theta / |u| * u; for |u| -> 0 the series theta/|u| = (2/qw)(1 - s^2/3 + s^4/5),
// s = |u|/qw, avoids the non-differentiable |u| at 0.
template <typename T>
Vec3<T> QuatToRotationVector(Quat<T> q) {
  using std::atan2;
  using std::sqrt;
  if (q[0] < T(0.0)) {
    for (T& c : q) c = -c;
  }
  const T u2 = q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  T scale;
  if (u2 > T(1e-12)) {
    const T un = sqrt(u2);
    scale = T(2.0) * atan2(un, q[0]) / un;
  } else {
    const T s2 = u2 / (q[0] * q[0]);
    scale = T(2.0) / q[0] * (T(1.0) - s2 / T(3.0) + s2 * s2 / T(5.0));
  }
  return {scale * q[1], scale * q[2], scale * q[3]};
}

// The translation part of the SE(3) log: v = V(w)^-1 t with
//   V^-1 = I - 1/2 W + c(theta) W^2,   c = (1 - (theta/2) cot(theta/2)) / theta^2,
// W = hat(w); c = 1/12 + theta^2/720 + theta^4/30240 + O(theta^6) near 0.
template <typename T>
Vec3<T> SE3LogTranslation(const Vec3<T>& w, const Vec3<T>& t) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  T c;
  if (th2 > T(1e-4)) {
    const T th = sqrt(th2);
    const T half = th / T(2.0);
    c = (T(1.0) - half * cos(half) / sin(half)) / th2;
  } else {
    c = T(1.0 / 12.0) + th2 / T(720.0) + th2 * th2 / T(30240.0);
  }
  const Vec3<T> wt = Cross(w, t);
  const Vec3<T> wwt = Cross(w, wt);
  return {t[0] - T(0.5) * wt[0] + c * wwt[0], t[1] - T(0.5) * wt[1] + c * wwt[1],
          t[2] - T(0.5) * wt[2] + c * wwt[2]};
}

// r = Log(z^-1 a^-1 b) in (w, v) order, poses given as (unit quaternion, translation).
template <typename T>
void RelativePoseLog(const Quat<T>& qa, const Vec3<T>& ta, const Quat<T>& qb, const Vec3<T>& tb,
                     const Quat<double>& qz_d, const Vec3<double>& tz_d, T* r) {
  const Quat<T> qz{T(qz_d[0]), T(qz_d[1]), T(qz_d[2]), T(qz_d[3])};
  const Quat<T> qz_inv = QuatConjugate(qz);
  const Quat<T> qa_inv = QuatConjugate(qa);
  // a^-1 b = (Ra^T Rb, Ra^T (tb - ta)); z^-1 (a^-1 b) = (Rz^T Rab, Rz^T (tab - tz)).
  const Quat<T> qe = QuatMultiply(qz_inv, QuatMultiply(qa_inv, qb));
  const Vec3<T> tab = QuatRotate(qa_inv, Vec3<T>{tb[0] - ta[0], tb[1] - ta[1], tb[2] - ta[2]});
  const Vec3<T> te =
      QuatRotate(qz_inv, Vec3<T>{tab[0] - T(tz_d[0]), tab[1] - T(tz_d[1]), tab[2] - T(tz_d[2])});
  const Vec3<T> w = QuatToRotationVector(qe);
  const Vec3<T> v = SE3LogTranslation(w, te);
  r[0] = w[0];
  r[1] = w[1];
  r[2] = w[2];
  r[3] = v[0];
  r[4] = v[1];
  r[5] = v[2];
}

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Whitened relative-pose residual U * Log(z^-1 a^-1 b) over two 7-double pose blocks.
struct RelativePoseCost {
  // z as a unit quaternion (w, x, y, z) and a translation; U upper triangular, U^T U = Omega.
  RelativePoseCost(const Quat<double>& qz, const Vec3<double>& tz, const Matrix6d& sqrt_info)
      : qz_(qz), tz_(tz), sqrt_info_(sqrt_info) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    T r[6];
    RelativePoseLog(QuatFromBlock(a), Vec3<T>{a[4], a[5], a[6]}, QuatFromBlock(b),
                    Vec3<T>{b[4], b[5], b[6]}, qz_, tz_, r);
    for (int i = 0; i < 6; ++i) {
      residual[i] = T(0.0);
      for (int j = i; j < 6; ++j) residual[i] += T(sqrt_info_(i, j)) * r[j];
    }
    return true;
  }

  static ceres::CostFunction* Create(const Quat<double>& qz, const Vec3<double>& tz,
                                     const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 6, kPoseSize, kPoseSize>(
        new RelativePoseCost(qz, tz, sqrt_info));
  }

  Quat<double> qz_;
  Vec3<double> tz_;
  Matrix6d sqrt_info_;
};

// Whitened prior residual U * Log(z^-1 x) over one pose block.
struct PriorCost {
  PriorCost(const Quat<double>& qz, const Vec3<double>& tz, const Matrix6d& sqrt_info)
      : qz_(qz), tz_(tz), sqrt_info_(sqrt_info) {}

  template <typename T>
  bool operator()(const T* x, T* residual) const {
    T r[6];
    const Quat<T> identity{T(1.0), T(0.0), T(0.0), T(0.0)};
    const Vec3<T> zero{T(0.0), T(0.0), T(0.0)};
    RelativePoseLog(identity, zero, QuatFromBlock(x), Vec3<T>{x[4], x[5], x[6]}, qz_, tz_, r);
    for (int i = 0; i < 6; ++i) {
      residual[i] = T(0.0);
      for (int j = i; j < 6; ++j) residual[i] += T(sqrt_info_(i, j)) * r[j];
    }
    return true;
  }

  static ceres::CostFunction* Create(const Quat<double>& qz, const Vec3<double>& tz,
                                     const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<PriorCost, 6, kPoseSize>(
        new PriorCost(qz, tz, sqrt_info));
  }

  Quat<double> qz_;
  Vec3<double> tz_;
  Matrix6d sqrt_info_;
};

}  // namespace moslam_bench
