#include "moslam/graph/factors.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"
#include "moslam/geometry/lie_testing.h"

namespace moslam {
namespace {

Matrix6 SomeInformation() {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  return A * A.transpose() + Matrix6::Identity();
}

TEST(RelativePoseFactor, ZeroResidualAtTheMeasurement) {
  const auto fx = test::LieFixtures();
  const SE3 a = fx[1], z = fx[2];
  const RelativePoseFactor f(Key::Pose(0, 0), Key::Pose(0, 1), z, SomeInformation());
  EXPECT_LT(f.residual(a, a * z).norm(), 1e-12);
  EXPECT_LT(f.cost(a, a * z), 1e-20);
}

TEST(RelativePoseFactor, CostIsHalfMahalanobis) {
  const Matrix6 info = SomeInformation();
  const auto fx = test::LieFixtures();
  const RelativePoseFactor f(Key::Pose(0, 0), Key::Object(0, 0), fx[3], info);
  const Vector6 r = f.residual(fx[4], fx[5]);
  EXPECT_NEAR(f.cost(fx[4], fx[5]), 0.5 * r.dot(info * r), 1e-9 * (1.0 + r.squaredNorm()));
}

TEST(RelativePoseFactor, JacobiansMatchNumericalDerivatives) {
  const auto fixtures = test::LieFixtures();
  for (size_t k = 0; k < fixtures.size(); ++k) {
    const SE3& a = fixtures[k];
    const SE3& b = fixtures[(k + 3) % fixtures.size()];
    // Measurements close to a^-1 b (small residual, the usual case) and far from it (near pi).
    for (const SE3& z : {a.between(b) * SE3::Exp(Vector6::Constant(0.01)), fixtures[(k + 7) % fixtures.size()]}) {
      const RelativePoseFactor f(Key::Pose(0, 0), Key::Pose(0, 1), z, Matrix6::Identity());
      Matrix6 Ha, Hb;
      f.residual(a, b, &Ha, &Hb);
      auto fa = [&](const SE3& x) { return Eigen::VectorXd(f.residual(x, b)); };
      auto fb = [&](const SE3& x) { return Eigen::VectorXd(f.residual(a, x)); };
      EXPECT_LT((test::NumericalDerivative(fa, a) - Ha).norm(), 1e-5) << "fixture " << k;
      EXPECT_LT((test::NumericalDerivative(fb, b) - Hb).norm(), 1e-5) << "fixture " << k;
    }
  }
}

TEST(PriorFactor, JacobianMatchesNumericalDerivative) {
  const auto fixtures = test::LieFixtures();
  for (size_t k = 0; k < fixtures.size(); ++k) {
    const PriorFactor p(Key::Pose(0, 0), fixtures[(k + 1) % fixtures.size()], Matrix6::Identity());
    Matrix6 H;
    p.residual(fixtures[k], &H);
    auto fn = [&](const SE3& x) { return Eigen::VectorXd(p.residual(x)); };
    EXPECT_LT((test::NumericalDerivative(fn, fixtures[k]) - H).norm(), 1e-5) << "fixture " << k;
  }
}

TEST(RelativePoseFactor, RejectsBadInformationAndMeasurements) {
  const Key a = Key::Pose(0, 0), b = Key::Pose(0, 1);
  Matrix6 not_pd = Matrix6::Identity();
  not_pd(3, 3) = 0.0;
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(), not_pd), InvalidInputError);
  Matrix6 negative = -Matrix6::Identity();
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(), negative), InvalidInputError);
  Matrix6 asym = Matrix6::Identity();
  asym(0, 1) = 0.5;
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(), asym), InvalidInputError);
  Matrix6 nan = Matrix6::Identity();
  nan(2, 2) = NAN;
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(), nan), InvalidInputError);
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(SO3(), Vector3(INFINITY, 0, 0)), Matrix6::Identity()),
               InvalidInputError);
  EXPECT_THROW(RelativePoseFactor(a, a, SE3(), Matrix6::Identity()), InvalidInputError);
  // Entries near DBL_MAX are valid; symmetrising must not overflow them to Inf.
  Matrix6 huge = 1.7e308 * Matrix6::Identity();
  huge(0, 1) = huge(1, 0) = 1e300;
  const RelativePoseFactor big(a, b, SE3(), huge);
  EXPECT_TRUE(big.information().allFinite());
  EXPECT_TRUE(big.sqrtInformation().allFinite());
  huge(0, 1) = huge(1, 0) = 1e308;  // largest eigenvalue 2.7e308: not representable
  EXPECT_THROW(RelativePoseFactor(a, b, SE3(), huge), InvalidInputError);
  EXPECT_THROW(PriorFactor(a, SE3(), not_pd), InvalidInputError);
}

}  // namespace
}  // namespace moslam
