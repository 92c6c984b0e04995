// SO(3): rotation matrices with the exact exponential/logarithm and their Jacobians.
//
// Conventions (shared/CONVENTIONS.md):
//   - Tangent vectors w in R^3 are rotation vectors (axis * angle).
//   - Perturbations are on the right: R (+) w = R * Exp(w).
//   - Right Jacobian Jr(w): Exp(w + dw) ~= Exp(w) * Exp(Jr(w) dw).
//   - Left Jacobian  Jl(w) = Jr(-w): Exp(w + dw) ~= Exp(Jl(w) dw) * Exp(w).
// All functions are exact (series expansions near 0) and stable near pi.
#pragma once

#include <Eigen/Core>

namespace moslam {

using Matrix3 = Eigen::Matrix3d;
using Vector3 = Eigen::Vector3d;

class SO3 {
 public:
  SO3() : R_(Matrix3::Identity()) {}
  // Takes R as given; callers that are unsure it is orthonormal use FromMatrixNormalized.
  explicit SO3(const Matrix3& R) : R_(R) {}
  // Nearest rotation (in Frobenius norm) to an arbitrary 3x3 matrix, via SVD.
  static SO3 FromMatrixNormalized(const Matrix3& M);
  // From a quaternion (qw, qx, qy, qz) of any finite non-zero norm (normalised first, without
  // overflow or underflow). Throws std::invalid_argument on a zero or non-finite quaternion.
  static SO3 FromQuaternion(double qw, double qx, double qy, double qz);

  const Matrix3& matrix() const { return R_; }
  // Unit quaternion (w, x, y, z) with w >= 0.
  Eigen::Vector4d quaternionWxyz() const;

  SO3 inverse() const { return SO3(R_.transpose()); }
  SO3 operator*(const SO3& other) const { return SO3(R_ * other.R_); }
  Vector3 operator*(const Vector3& p) const { return R_ * p; }

  // Exp: R^3 -> SO(3); H (optional) = Jr(w).
  static SO3 Exp(const Vector3& w, Matrix3* H = nullptr);
  // Log: SO(3) -> R^3 with |w| <= pi; H (optional) = Jr^{-1}(Log(R)).
  static Vector3 Log(const SO3& R, Matrix3* H = nullptr);

  static Matrix3 Hat(const Vector3& w);
  static Vector3 Vee(const Matrix3& W);

  static Matrix3 RightJacobian(const Vector3& w);
  static Matrix3 RightJacobianInverse(const Vector3& w);
  static Matrix3 LeftJacobian(const Vector3& w) { return RightJacobian(-w); }
  static Matrix3 LeftJacobianInverse(const Vector3& w) { return RightJacobianInverse(-w); }

  // Adjoint: R Exp(w) R^T = Exp(Ad w), Ad = R.
  Matrix3 Adjoint() const { return R_; }

 private:
  Matrix3 R_;
};

namespace lie_detail {
// The coefficient functions of the exact SO(3)/SE(3) formulas, each with its Taylor series near
// theta = 0 (where the closed form cancels catastrophically). Exposed for tests.
double SinOverTheta(double theta);            // sin t / t
double OneMinusCosOverTheta2(double theta);   // (1 - cos t) / t^2
double TMinusSinOverTheta3(double theta);     // (t - sin t) / t^3
double CosTaylor4OverTheta4(double theta);    // (t^2/2 + cos t - 1) / t^4
double SinTaylor5OverTheta5(double theta);    // (t - sin t - t^3/6) / t^5
}  // namespace lie_detail

}  // namespace moslam
