#include "moslam/geometry/se3.h"

#include <gtest/gtest.h>

#include "moslam/geometry/lie_testing.h"

namespace moslam {
namespace {

using test::LieFixtures;
using test::NumericalDerivative;

constexpr double kTol = 1e-6;  // central differences with h = 1e-6: error ~ h^2 * |f'''| + eps/h

TEST(SE3, ExpLogRoundTrip) {
  for (const SE3& x : LieFixtures()) {
    const SE3 y = SE3::Exp(SE3::Log(x));
    EXPECT_LT((y.matrix() - x.matrix()).norm(), 1e-10);
  }
}

TEST(SE3, ExpIsExactNotDecoupled) {
  // A screw motion: the translation of Exp is Jl(w) v, not v.
  Vector6 xi;
  xi << 0.0, 0.0, 1.5707963267948966, 1.0, 0.0, 0.0;
  const SE3 x = SE3::Exp(xi);
  EXPECT_NEAR(x.translation().x(), 2.0 / 3.14159265358979323846, 1e-12);
  EXPECT_NEAR(x.translation().y(), 2.0 / 3.14159265358979323846, 1e-12);
}

TEST(SE3, GroupAxioms) {
  const auto fx = LieFixtures();
  for (size_t i = 0; i + 2 < fx.size(); ++i) {
    const SE3 &a = fx[i], &b = fx[i + 1], &c = fx[i + 2];
    EXPECT_LT((((a * b) * c).matrix() - (a * (b * c)).matrix()).norm(), 1e-12);
    EXPECT_LT(((a * a.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
    EXPECT_LT((a.between(b).matrix() - (a.inverse() * b).matrix()).norm(), 1e-12);
  }
}

TEST(SE3, AdjointMovesTangentVectorsAcross) {
  const Vector6 xi = (Vector6() << 0.1, -0.2, 0.3, 1.0, 2.0, -0.5).finished();
  for (const SE3& x : LieFixtures()) {
    const SE3 lhs = x * SE3::Exp(xi) * x.inverse();
    const SE3 rhs = SE3::Exp(x.Adjoint() * xi);
    EXPECT_LT((lhs.matrix() - rhs.matrix()).norm(), 1e-10);
  }
}

// The harness: every Jacobian of the type against central differences at every fixture.
TEST(SE3, JacobiansMatchNumericalDerivatives) {
  const auto fixtures = LieFixtures();
  for (size_t k = 0; k < fixtures.size(); ++k) {
    const SE3& x = fixtures[k];
    const SE3& y = fixtures[(k + 5) % fixtures.size()];
    SCOPED_TRACE(::testing::Message() << "fixture " << k << " angle "
                                    << SO3::Log(x.rotation()).norm());
    Matrix6 H, H1, H2;

    x.inverse(&H);
    EXPECT_LT((NumericalDerivative([](const SE3& a) { return a.inverse(); }, x) - H).norm(),
              kTol);

    x.compose(y, &H1, &H2);
    EXPECT_LT((NumericalDerivative([&](const SE3& a) { return a * y; }, x) - H1).norm(), kTol);
    EXPECT_LT((NumericalDerivative([&](const SE3& b) { return x * b; }, y) - H2).norm(), kTol);

    x.between(y, &H1, &H2);
    EXPECT_LT((NumericalDerivative([&](const SE3& a) { return a.between(y); }, x) - H1).norm(),
              kTol);
    EXPECT_LT((NumericalDerivative([&](const SE3& b) { return x.between(b); }, y) - H2).norm(),
              kTol);

    const Eigen::VectorXd xi = SE3::Log(x);
    SE3::Log(x, &H);
    auto log_fn = [](const SE3& a) { return Eigen::VectorXd(SE3::Log(a)); };
    EXPECT_LT((NumericalDerivative(log_fn, x) - H).norm(), kTol);

    SE3::Exp(xi, &H);
    auto exp_fn = [](const Eigen::VectorXd& v) { return SE3::Exp(v); };
    EXPECT_LT((NumericalDerivative(exp_fn, xi) - H).norm(), kTol);

    EXPECT_LT((SE3::RightJacobian(xi) * SE3::RightJacobianInverse(xi) - Matrix6::Identity())
                  .norm(),
              1e-9);
  }
}

}  // namespace
}  // namespace moslam
