// SE(3): rigid-body transforms with the exact exponential/logarithm and Jacobians.
//
// Conventions (shared/CONVENTIONS.md, identical to GTSAM Pose3):
//   - x = (R, t) maps body to world: p_w = R p_b + t (world_T_body).
//   - Tangent vectors xi = (w, v): rotation first, then translation.
//   - Retraction on the right: x (+) xi = x * Exp(xi), with the exact (coupled) SE(3) Exp.
//   - All Jacobians are with respect to right perturbations of every argument:
//       d f(x) / d x  :=  d Log(f(x)^-1 f(x Exp(dx))) / d dx   (group-valued f)
//       d f(x) / d x  :=  d f(x Exp(dx)) / d dx                 (vector-valued f)
#pragma once

#include <Eigen/Core>

#include "moslam/geometry/so3.h"

namespace moslam {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

class SE3 {
 public:
  SE3() : t_(Vector3::Zero()) {}
  SE3(const SO3& R, const Vector3& t) : R_(R), t_(t) {}

  const SO3& rotation() const { return R_; }
  const Vector3& translation() const { return t_; }
  Eigen::Matrix4d matrix() const;

  SE3 inverse(Matrix6* H = nullptr) const;
  // this * other, with H1 = d/d this, H2 = d/d other.
  SE3 compose(const SE3& other, Matrix6* H1 = nullptr, Matrix6* H2 = nullptr) const;
  SE3 operator*(const SE3& other) const { return compose(other); }
  // this^-1 * other, with Jacobians (the relative-pose measurement model).
  SE3 between(const SE3& other, Matrix6* H1 = nullptr, Matrix6* H2 = nullptr) const;
  Vector3 transformFrom(const Vector3& p_body) const { return R_ * p_body + t_; }

  static SE3 Exp(const Vector6& xi, Matrix6* H = nullptr);  // H = Jr(xi)
  static Vector6 Log(const SE3& x, Matrix6* H = nullptr);   // H = Jr^{-1}(Log x)
  SE3 retract(const Vector6& xi) const { return compose(Exp(xi)); }
  Vector6 localCoordinates(const SE3& other) const { return Log(between(other)); }

  // Ad_x such that x Exp(xi) x^-1 = Exp(Ad_x xi); in (w, v) order Ad = [R 0; t^ R  R].
  Matrix6 Adjoint() const;

  static Matrix6 RightJacobian(const Vector6& xi);
  static Matrix6 RightJacobianInverse(const Vector6& xi);
  static Matrix6 LeftJacobian(const Vector6& xi) { return RightJacobian(-xi); }
  static Matrix6 LeftJacobianInverse(const Vector6& xi) { return RightJacobianInverse(-xi); }

 private:
  SO3 R_;
  Vector3 t_;
};

}  // namespace moslam
