#include "moslam/geometry/so3.h"

#include <gtest/gtest.h>

#include <cmath>

#include "moslam/geometry/lie_testing.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(SO3, SeriesCoefficientsAreContinuousAtTheSwitch) {
  using namespace lie_detail;
  // The series is used below 0.2, the closed form above: both sides must agree to ~1e-12.
  const double below = 0.2 - 1e-12, above = 0.2 + 1e-12;
  EXPECT_NEAR(SinOverTheta(below), SinOverTheta(above), 1e-11);
  EXPECT_NEAR(OneMinusCosOverTheta2(below), OneMinusCosOverTheta2(above), 1e-11);
  EXPECT_NEAR(TMinusSinOverTheta3(below), TMinusSinOverTheta3(above), 1e-11);
  EXPECT_NEAR(CosTaylor4OverTheta4(below), CosTaylor4OverTheta4(above), 1e-11);
  EXPECT_NEAR(SinTaylor5OverTheta5(below), SinTaylor5OverTheta5(above), 1e-11);
  EXPECT_DOUBLE_EQ(SinTaylor5OverTheta5(0.0), -1.0 / 120.0);
}

TEST(SO3, ExpLogRoundTripNearZeroAndPi) {
  for (double angle : {0.0, 1e-12, 1e-8, 1e-5, 0.1, 1.0, 3.0, kPi - 1e-5, kPi - 1e-9}) {
    const Vector3 w = angle * Vector3(1.0, -2.0, 0.5).normalized();
    const Vector3 back = SO3::Log(SO3::Exp(w));
    EXPECT_LT((back - w).norm(), 1e-12 * std::max(1.0, angle) + 1e-15) << "angle " << angle;
  }
}

TEST(SO3, LogOfRotationByPiHasNormPi) {
  const SO3 R(Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal().toDenseMatrix());  // pi about x
  const Vector3 w = SO3::Log(R);
  EXPECT_NEAR(w.norm(), kPi, 1e-12);
  EXPECT_NEAR(std::abs(w.x()), kPi, 1e-12);
}

TEST(SO3, VeeInvertsHatAndReadsTheCrossProduct) {
  const Vector3 w(0.3, -1.2, 2.5);
  EXPECT_EQ(SO3::Vee(SO3::Hat(w)), w);
  const Vector3 v(-0.7, 0.4, 1.1);
  EXPECT_LT((SO3::Hat(w) * v - w.cross(v)).norm(), 1e-15);
  // The axis of a small rotation: (R - R^T) / 2 = Hat(sin(theta) axis).
  const Vector3 small(1e-4, -2e-4, 3e-4);
  const Matrix3 R = SO3::Exp(small).matrix();
  EXPECT_LT((SO3::Vee((R - R.transpose()) / 2.0) - small).norm(), 1e-11);
}

TEST(SO3, ExpIsOrthonormal) {
  const SO3 R = SO3::Exp(Vector3(0.3, -2.0, 1.1));
  EXPECT_LT((R.matrix() * R.matrix().transpose() - Matrix3::Identity()).norm(), 1e-14);
  EXPECT_NEAR(R.matrix().determinant(), 1.0, 1e-14);
}

TEST(SO3, JacobiansMatchNumericalDerivatives) {
  for (const SE3& x : test::LieFixtures()) {
    const Vector3 w = SO3::Log(x.rotation());
    Matrix3 H_exp, H_log;
    SO3::Exp(w, &H_exp);
    SO3::Log(x.rotation(), &H_log);
    const Eigen::VectorXd wx = w;
    auto exp_fn = [](const Eigen::VectorXd& v) { return SO3::Exp(v); };
    auto log_fn = [](const SO3& R) { return Eigen::VectorXd(SO3::Log(R)); };
    EXPECT_LT((test::NumericalDerivative(exp_fn, wx) - H_exp).norm(), 1e-7) << w.norm();
    EXPECT_LT((test::NumericalDerivative(log_fn, x.rotation()) - H_log).norm(), 1e-6)
        << w.norm();
    EXPECT_LT((SO3::RightJacobian(w) * SO3::RightJacobianInverse(w) - Matrix3::Identity()).norm(),
              1e-10);
  }
}

TEST(SO3, FromMatrixNormalizedProjectsToNearestRotation) {
  const SO3 R = SO3::Exp(Vector3(0.4, 0.1, -0.7));
  const SO3 P = SO3::FromMatrixNormalized(2.0 * R.matrix());
  EXPECT_LT((P.matrix() - R.matrix()).norm(), 1e-12);
  // A reflection is projected to a proper rotation.
  const SO3 Q = SO3::FromMatrixNormalized(-Matrix3::Identity());
  EXPECT_NEAR(Q.matrix().determinant(), 1.0, 1e-12);
}

TEST(SO3, QuaternionRejectsZero) {
  EXPECT_THROW(SO3::FromQuaternion(0, 0, 0, 0), std::invalid_argument);
  EXPECT_THROW(SO3::FromQuaternion(NAN, 0, 0, 1), std::invalid_argument);
  const SO3 R = SO3::FromQuaternion(2.0, 0.0, 0.0, 0.0);  // normalised
  EXPECT_LT((R.matrix() - Matrix3::Identity()).norm(), 1e-15);
  // Norms whose squares overflow or underflow (finite components): the same rotation.
  const SO3 half_turn_z = SO3::FromQuaternion(0.0, 0.0, 0.0, 1.0);
  for (const double scale : {1e200, 1e-200, 4e-320}) {
    EXPECT_LT((SO3::FromQuaternion(0.0, 0.0, 0.0, scale).matrix() - half_turn_z.matrix()).norm(),
              1e-15)
        << scale;
  }
  const SO3 Q = SO3::FromQuaternion(1e300, 1e300, 0.0, 0.0);
  EXPECT_LT((Q.matrix() - SO3::FromQuaternion(1.0, 1.0, 0.0, 0.0).matrix()).norm(), 1e-15);
  EXPECT_THROW(SO3::FromQuaternion(1.0, INFINITY, 0, 0), std::invalid_argument);
}

}  // namespace
}  // namespace moslam
