#include "moslam/geometry/se3.h"

namespace moslam {
namespace {
using namespace lie_detail;

// The off-diagonal block Q(w, v) of the SE(3) left Jacobian, Jl = [Jl(w) 0; Q Jl(w)]
// (Barfoot, "State Estimation for Robotics", eq. 7.86, in (w, v) order).
Matrix3 LeftJacobianQ(const Vector3& w, const Vector3& v) {
  const double theta = w.norm();
  const Matrix3 W = SO3::Hat(w);
  const Matrix3 V = SO3::Hat(v);
  const Matrix3 WV = W * V, VW = V * W, WVW = WV * W;
  const double c1 = TMinusSinOverTheta3(theta);
  const double c2 = CosTaylor4OverTheta4(theta);
  // (1 - t^2/2 - cos t)/t^4 - 3 (t - sin t - t^3/6)/t^5 = -c2 - 3 c5
  const double c3 = -c2 - 3.0 * SinTaylor5OverTheta5(theta);
  return 0.5 * V + c1 * (WV + VW + WVW) + c2 * (W * WV + VW * W - 3.0 * WVW) -
         0.5 * c3 * (WVW * W + W * WVW);
}
}  // namespace

Eigen::Matrix4d SE3::matrix() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R_.matrix();
  T.topRightCorner<3, 1>() = t_;
  return T;
}

Matrix6 SE3::Adjoint() const {
  Matrix6 A;
  const Matrix3& R = R_.matrix();
  A.topLeftCorner<3, 3>() = R;
  A.topRightCorner<3, 3>().setZero();
  A.bottomLeftCorner<3, 3>() = SO3::Hat(t_) * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

SE3 SE3::inverse(Matrix6* H) const {
  if (H) *H = -Adjoint();
  const SO3 Rt = R_.inverse();
  return SE3(Rt, -(Rt * t_));
}

SE3 SE3::compose(const SE3& other, Matrix6* H1, Matrix6* H2) const {
  // (x y) Exp(d) = x Exp(d1) y  =>  d = Ad_{y^-1} d1 ;  (x y Exp(d2)) => d = d2.
  if (H1) *H1 = other.inverse().Adjoint();
  if (H2) H2->setIdentity();
  return SE3(R_ * other.R_, R_ * other.t_ + t_);
}

SE3 SE3::between(const SE3& other, Matrix6* H1, Matrix6* H2) const {
  const SE3 result = inverse() * other;
  // d(x^-1 y)/dx = -Ad_{(x^-1 y)^-1}, d(x^-1 y)/dy = I.
  if (H1) *H1 = -result.inverse().Adjoint();
  if (H2) H2->setIdentity();
  return result;
}

SE3 SE3::Exp(const Vector6& xi, Matrix6* H) {
  const Vector3 w = xi.head<3>();
  const Vector3 v = xi.tail<3>();
  if (H) *H = RightJacobian(xi);
  return SE3(SO3::Exp(w), SO3::LeftJacobian(w) * v);
}

Vector6 SE3::Log(const SE3& x, Matrix6* H) {
  const Vector3 w = SO3::Log(x.R_);
  Vector6 xi;
  xi << w, SO3::LeftJacobianInverse(w) * x.t_;
  if (H) *H = RightJacobianInverse(xi);
  return xi;
}

Matrix6 SE3::RightJacobian(const Vector6& xi) {
  // Jr(xi) = Jl(-xi).
  const Vector3 w = -xi.head<3>();
  const Vector3 v = -xi.tail<3>();
  const Matrix3 J = SO3::LeftJacobian(w);
  Matrix6 Jr;
  Jr.topLeftCorner<3, 3>() = J;
  Jr.topRightCorner<3, 3>().setZero();
  Jr.bottomLeftCorner<3, 3>() = LeftJacobianQ(w, v);
  Jr.bottomRightCorner<3, 3>() = J;
  return Jr;
}

Matrix6 SE3::RightJacobianInverse(const Vector6& xi) {
  const Vector3 w = -xi.head<3>();
  const Vector3 v = -xi.tail<3>();
  const Matrix3 Jinv = SO3::LeftJacobianInverse(w);
  Matrix6 Jr_inv;
  Jr_inv.topLeftCorner<3, 3>() = Jinv;
  Jr_inv.topRightCorner<3, 3>().setZero();
  Jr_inv.bottomLeftCorner<3, 3>() = -Jinv * LeftJacobianQ(w, v) * Jinv;
  Jr_inv.bottomRightCorner<3, 3>() = Jinv;
  return Jr_inv;
}

}  // namespace moslam
