#include "moslam/geometry/so3.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace moslam {
namespace lie_detail {
namespace {
// Below this angle the closed forms lose digits to cancellation; the series (5 terms, error
// ~ theta^10 / (2k+10)!) is exact to machine precision there.
constexpr double kSeriesThreshold = 0.2;

// sum_k (-1)^k t^(2k) / (2k + offset)!
double AlternatingSeries(double theta, int offset) {
  const double t2 = theta * theta;
  double fact = 1.0;
  for (int i = 2; i <= offset; ++i) fact *= i;
  double term = 1.0 / fact, sum = 0.0;
  for (int k = 0; k < 6; ++k) {
    sum += term;
    term *= -t2 / ((2 * k + offset + 1) * (2 * k + offset + 2));
  }
  return sum;
}
}  // namespace

double SinOverTheta(double t) {
  return std::abs(t) < kSeriesThreshold ? AlternatingSeries(t, 1) : std::sin(t) / t;
}
double OneMinusCosOverTheta2(double t) {
  return std::abs(t) < kSeriesThreshold ? AlternatingSeries(t, 2) : (1.0 - std::cos(t)) / (t * t);
}
double TMinusSinOverTheta3(double t) {
  return std::abs(t) < kSeriesThreshold ? AlternatingSeries(t, 3)
                                        : (t - std::sin(t)) / (t * t * t);
}
double CosTaylor4OverTheta4(double t) {
  const double t2 = t * t;
  return std::abs(t) < kSeriesThreshold ? AlternatingSeries(t, 4)
                                        : (t2 / 2.0 + std::cos(t) - 1.0) / (t2 * t2);
}
double SinTaylor5OverTheta5(double t) {
  const double t2 = t * t;
  return std::abs(t) < kSeriesThreshold ? -AlternatingSeries(t, 5)
                                        : (t - std::sin(t) - t * t2 / 6.0) / (t2 * t2 * t);
}
}  // namespace lie_detail

using namespace lie_detail;

Matrix3 SO3::Hat(const Vector3& w) {
  Matrix3 W;
  W << 0.0, -w.z(), w.y(),  //
      w.z(), 0.0, -w.x(),   //
      -w.y(), w.x(), 0.0;
  return W;
}

Vector3 SO3::Vee(const Matrix3& W) { return Vector3(W(2, 1), W(0, 2), W(1, 0)); }

SO3 SO3::FromMatrixNormalized(const Matrix3& M) {
  Eigen::JacobiSVD<Matrix3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Matrix3& U = svd.matrixU();
  const Matrix3& V = svd.matrixV();
  Vector3 d(1.0, 1.0, (U * V.transpose()).determinant() < 0.0 ? -1.0 : 1.0);
  return SO3(U * d.asDiagonal() * V.transpose());
}

SO3 SO3::FromQuaternion(double qw, double qx, double qy, double qz) {
  const double largest = std::max({std::abs(qw), std::abs(qx), std::abs(qy), std::abs(qz)});
  if (!std::isfinite(largest) || largest == 0.0) {  // NaN compares false: caught by isfinite
    throw std::invalid_argument("quaternion is zero or not finite");
  }
  double n = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  if (!std::isfinite(n) || n < 1e-100) {
    // The squares overflow or underflow: scale by the largest component first. Only there, so
    // that ordinary quaternions give the same bits as a plain normalisation.
    qw /= largest;
    qx /= largest;
    qy /= largest;
    qz /= largest;
    n = std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  }
  return SO3(Eigen::Quaterniond(qw / n, qx / n, qy / n, qz / n).toRotationMatrix());
}

Eigen::Vector4d SO3::quaternionWxyz() const {
  Eigen::Quaterniond q(R_);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() *= -1.0;
  return Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
}

SO3 SO3::Exp(const Vector3& w, Matrix3* H) {
  const double theta = w.norm();
  const Matrix3 W = Hat(w);
  if (H) *H = RightJacobian(w);
  return SO3(Matrix3::Identity() + SinOverTheta(theta) * W +
             OneMinusCosOverTheta2(theta) * W * W);
}

Vector3 SO3::Log(const SO3& R, Matrix3* H) {
  // Through the quaternion: theta = 2 atan2(|v|, |w|) is well conditioned at 0 and at pi, where
  // the trace formula acos((tr R - 1) / 2) loses half the digits.
  Eigen::Quaterniond q(R.R_);
  q.normalize();
  const double vnorm = q.vec().norm();
  const double sign = q.w() < 0.0 ? -1.0 : 1.0;
  const double aw = std::abs(q.w());
  Vector3 w;
  if (vnorm < 1e-8) {
    // theta = 2 atan(vnorm / aw) ~= 2 vnorm / aw (1 - vnorm^2 / (3 aw^2)); the cubic term is
    // below machine precision here.
    w = sign * (2.0 / aw) * q.vec();
  } else {
    const double theta = 2.0 * std::atan2(vnorm, aw);
    w = sign * (theta / vnorm) * q.vec();
  }
  if (H) *H = RightJacobianInverse(w);
  return w;
}

Matrix3 SO3::RightJacobian(const Vector3& w) {
  const double theta = w.norm();
  const Matrix3 W = Hat(w);
  return Matrix3::Identity() - OneMinusCosOverTheta2(theta) * W +
         TMinusSinOverTheta3(theta) * W * W;
}

Matrix3 SO3::RightJacobianInverse(const Vector3& w) {
  // Jr^{-1} = I + W/2 + c W^2 with c = 1/t^2 - cot(t/2) / (2t): finite up to 2 pi.
  const double theta = w.norm();
  const Matrix3 W = Hat(w);
  double c;
  if (theta < 0.2) {
    const double t2 = theta * theta;
    c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0;
  } else {
    c = 1.0 / (theta * theta) - 1.0 / (2.0 * theta * std::tan(theta / 2.0));
  }
  return Matrix3::Identity() + 0.5 * W + c * W * W;
}

}  // namespace moslam
