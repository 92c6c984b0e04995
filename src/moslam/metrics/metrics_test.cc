#include "moslam/metrics/metrics.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

class Random {
 public:
  explicit Random(unsigned seed) : rng_(seed) {}
  double Normal() { return n01_(rng_); }
  double Uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  Vector3 Axis() { return Vector3(Normal(), Normal(), Normal()).normalized(); }
  Vector3 Point(double sigma) { return sigma * Vector3(Normal(), Normal(), Normal()); }
  SE3 Pose(double sigma) { return SE3(SO3::Exp(Uniform(0.0, 3.1) * Axis()), Point(sigma)); }

 private:
  std::mt19937 rng_;
  std::normal_distribution<double> n01_;
};

// Two robots with 10 poses each along a wiggly path and 4 objects each: a 3D (non-collinear)
// trajectory with poses far from the origin.
Values MakeScene(unsigned seed = 3) {
  Random rnd(seed);
  Values v;
  for (int r = 0; r < 2; ++r) {
    SE3 x(SO3::Exp(rnd.Uniform(0.0, 3.0) * rnd.Axis()), Vector3(10.0 * r, 5.0, 2.0));
    for (std::uint64_t i = 0; i < 10; ++i) {
      v[Key::Pose(r, i)] = x;
      x = x * SE3(SO3::Exp(0.3 * rnd.Axis()), Vector3(1.0, 0.2 * rnd.Normal(), 0.2 * rnd.Normal()));
    }
    for (std::uint64_t k = 0; k < 4; ++k) v[Key::Object(r, k)] = rnd.Pose(8.0);
  }
  return v;
}

TEST(CompareEstimates, IdenticalValuesGiveZeroErrors) {
  const Values v = MakeScene();
  const TrajectoryErrors e = CompareEstimates(v, v);
  EXPECT_EQ(e.poses.count, 20);
  EXPECT_EQ(e.objects.count, 8);
  EXPECT_EQ(e.poses.ate, 0.0);
  EXPECT_EQ(e.objects.ate, 0.0);
  // R^T R is the identity only up to rounding.
  EXPECT_NEAR(e.poses.are_deg, 0.0, 1e-12);
  EXPECT_NEAR(e.objects.are_deg, 0.0, 1e-12);
}

TEST(CompareEstimates, EmptyReferenceGivesZeroCount) {
  const TrajectoryErrors e = CompareEstimates(MakeScene(), Values{});
  EXPECT_EQ(e.poses.count, 0);
  EXPECT_EQ(e.objects.count, 0);
  EXPECT_EQ(e.poses.ate, 0.0);
  EXPECT_EQ(e.poses.are_deg, 0.0);
  const TrajectoryErrors both_empty = CompareEstimates(Values{}, Values{});
  EXPECT_EQ(both_empty.poses.count + both_empty.objects.count, 0);
}

TEST(CompareEstimates, TranslationOffsetOnEveryPose) {
  Random rnd(11);
  const Values ref = MakeScene();
  Values est = ref;
  for (auto& [key, x] : est) {
    if (key.isPose()) x = SE3(x.rotation(), x.translation() + 0.1 * rnd.Axis());
  }
  const TrajectoryErrors e = CompareEstimates(est, ref);
  EXPECT_NEAR(e.poses.ate, 0.1, 1e-14);
  EXPECT_NEAR(e.poses.are_deg, 0.0, 1e-12);
  EXPECT_EQ(e.objects.ate, 0.0);  // objects untouched
}

TEST(CompareEstimates, AteIsRootMeanSquareNotMean) {
  Values ref{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  Values est{{Key::Pose(0, 0), SE3(SO3(), Vector3(0.1, 0, 0))},
             {Key::Pose(0, 1), SE3(SO3::Exp(Vector3(0, 0, 3 * kDeg)), Vector3(0, 0, -0.3))}};
  const ErrorStats e = CompareEstimates(est, ref).poses;
  EXPECT_NEAR(e.ate, std::sqrt((0.01 + 0.09) / 2.0), 1e-15);
  EXPECT_NEAR(e.are_deg, std::sqrt(9.0 / 2.0), 1e-12);
}

TEST(CompareEstimates, RotationOffsetOfTwoDegrees) {
  Random rnd(12);
  const Values ref = MakeScene();
  Values est = ref;
  for (auto& [key, x] : est) {
    // About a different axis for every pose, in the body frame: positions stay identical.
    if (key.isPose()) x = SE3(x.rotation() * SO3::Exp(2.0 * kDeg * rnd.Axis()), x.translation());
  }
  const TrajectoryErrors e = CompareEstimates(est, ref);
  EXPECT_NEAR(e.poses.are_deg, 2.0, 1e-12);
  EXPECT_EQ(e.poses.ate, 0.0);
  EXPECT_NEAR(e.objects.are_deg, 0.0, 1e-12);
}

TEST(CompareEstimates, RotationErrorNearPi) {
  Random rnd(13);
  for (double angle : {kPi - 1e-5, kPi - 1e-9, kPi}) {
    const SE3 ref(SO3::Exp(2.0 * rnd.Axis()), Vector3(1, 2, 3));
    const SE3 est(ref.rotation() * SO3::Exp(angle * rnd.Axis()), ref.translation());
    const ErrorStats e =
        CompareEstimates(Values{{Key::Object(1, 4), est}}, Values{{Key::Object(1, 4), ref}})
            .objects;
    EXPECT_EQ(e.count, 1);
    // 1e-5 rad below pi is 5.7e-4 degrees below 180: resolved to ~1e-12 degrees.
    EXPECT_NEAR(e.are_deg, angle / kDeg, 1e-11) << "angle = " << angle;
  }
}

TEST(CompareEstimates, PosesAndObjectsAreSeparate) {
  const Values ref = MakeScene();
  Values est = ref;
  for (auto& [key, x] : est) {
    if (key.isObject()) x = SE3(x.rotation(), x.translation() + Vector3(0, 0.5, 0));
  }
  const TrajectoryErrors e = CompareEstimates(est, ref);
  EXPECT_EQ(e.poses.ate, 0.0);
  EXPECT_EQ(e.poses.count, 20);
  EXPECT_NEAR(e.objects.ate, 0.5, 1e-14);
  EXPECT_EQ(e.objects.count, 8);
}

TEST(CompareEstimates, MissingKeyThrowsAndNamesIt) {
  const Values ref = MakeScene();
  Values est = ref;
  est.erase(Key::Object(1, 2));
  try {
    CompareEstimates(est, ref);
    FAIL() << "expected InvalidInputError";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("B2"), std::string::npos) << e.what();
  }
}

TEST(CompareEstimates, ExtraKeysOfTheEstimateAreIgnored) {
  const Values ref = MakeScene();
  Values est = ref;
  est[Key::Pose(5, 0)] = SE3(SO3(), Vector3(100, 0, 0));
  est[Key::Object(5, 0)] = SE3(SO3(), Vector3(100, 0, 0));
  const TrajectoryErrors e = CompareEstimates(est, ref);
  EXPECT_EQ(e.poses.count, 20);
  EXPECT_EQ(e.objects.count, 8);
  EXPECT_EQ(e.poses.ate, 0.0);
  EXPECT_EQ(e.objects.ate, 0.0);
}

TEST(CompareEstimates, NonFinitePoseThrows) {
  const Values ref = MakeScene();
  Values est = ref;
  est[Key::Pose(0, 3)] =
      SE3(SO3(), Vector3(std::numeric_limits<double>::quiet_NaN(), 0, 0));
  EXPECT_THROW(CompareEstimates(est, ref), InvalidInputError);
  EXPECT_THROW(CompareEstimates(ref, est), InvalidInputError);
}

TEST(ComputeErrorStats, SelectsASubset) {
  const Values ref = MakeScene();
  Values est = ref;
  for (auto& [key, x] : est) {
    if (key.robot == 1 && key.isPose()) x = SE3(x.rotation(), x.translation() + Vector3(0.2, 0, 0));
  }
  const auto robot = [](int r) { return [r](const Key& k) { return k.robot == r && k.isPose(); }; };
  const ErrorStats r0 = ComputeErrorStats(est, ref, robot(0));
  const ErrorStats r1 = ComputeErrorStats(est, ref, robot(1));
  EXPECT_EQ(r0.count, 10);
  EXPECT_EQ(r0.ate, 0.0);
  EXPECT_EQ(r1.count, 10);
  EXPECT_NEAR(r1.ate, 0.2, 1e-14);
  // Both robots together: sqrt((10 * 0 + 10 * 0.04) / 20).
  EXPECT_NEAR(CompareEstimates(est, ref).poses.ate, 0.2 / std::sqrt(2.0), 1e-14);
}

std::vector<Vector3> Transformed(const SE3& T, const std::vector<Vector3>& points) {
  std::vector<Vector3> out;
  for (const Vector3& p : points) out.push_back(T.transformFrom(p));
  return out;
}

double MaxAbsDiff(const SE3& a, const SE3& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

TEST(AlignRigid, RecoversAnExactTransform) {
  Random rnd(21);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Vector3> src;
    for (int i = 0; i < 3 + trial; ++i) src.push_back(rnd.Point(5.0));
    const SE3 T = rnd.Pose(20.0);
    const SE3 found = AlignRigid(src, Transformed(T, src));
    EXPECT_LT(MaxAbsDiff(found, T), 1e-12) << "trial " << trial;
    EXPECT_NEAR(found.rotation().matrix().determinant(), 1.0, 1e-14);
  }
}

TEST(AlignRigid, MatchesEigenUmeyamaOnNoisyPoints) {
  Random rnd(22);
  std::vector<Vector3> src;
  for (int i = 0; i < 50; ++i) src.push_back(rnd.Point(5.0));
  std::vector<Vector3> dst = Transformed(rnd.Pose(10.0), src);
  for (Vector3& p : dst) p += rnd.Point(0.3);
  Eigen::Matrix3Xd s(3, 50), d(3, 50);
  for (int i = 0; i < 50; ++i) {
    s.col(i) = src[i];
    d.col(i) = dst[i];
  }
  const Eigen::Matrix4d expected = Eigen::umeyama(s, d, false);
  EXPECT_LT((AlignRigid(src, dst).matrix() - expected).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(AlignRigid, ReturnsAProperRotationForAMirroredTarget) {
  Random rnd(23);
  std::vector<Vector3> src;
  for (int i = 0; i < 10; ++i) src.push_back(rnd.Point(3.0));
  std::vector<Vector3> dst = src;
  for (Vector3& p : dst) p.z() = -p.z();  // the best orthogonal fit is the reflection
  const SE3 T = AlignRigid(src, dst);
  EXPECT_NEAR(T.rotation().matrix().determinant(), 1.0, 1e-14);
  // No proper rotation does better: small perturbations of T only raise the residual.
  const auto residual = [&](const SE3& X) {
    double s = 0.0;
    for (std::size_t i = 0; i < src.size(); ++i) s += (X.transformFrom(src[i]) - dst[i]).squaredNorm();
    return s;
  };
  const double best = residual(T);
  for (int i = 0; i < 30; ++i) {
    Vector6 xi;
    for (int j = 0; j < 6; ++j) xi(j) = 1e-3 * rnd.Normal();
    EXPECT_GT(residual(T.retract(xi)), best);
  }
}

TEST(AlignRigid, RejectsDegenerateInput) {
  const std::vector<Vector3> two{Vector3(0, 0, 0), Vector3(1, 0, 0)};
  EXPECT_THROW(AlignRigid(two, two), UnderdeterminedError);
  const std::vector<Vector3> line{Vector3(0, 0, 0), Vector3(1, 1, 1), Vector3(2.5, 2.5, 2.5),
                                  Vector3(-3, -3, -3)};
  EXPECT_THROW(AlignRigid(line, line), UnderdeterminedError);
  const std::vector<Vector3> point(5, Vector3(1, 2, 3));
  EXPECT_THROW(AlignRigid(point, point), UnderdeterminedError);
  const std::vector<Vector3> plane{Vector3(0, 0, 0), Vector3(1, 0, 0), Vector3(0, 1, 0)};
  EXPECT_NO_THROW(AlignRigid(plane, plane));  // 3 non-collinear points suffice
  EXPECT_THROW(AlignRigid(plane, line), InvalidInputError);
  std::vector<Vector3> nan = plane;
  nan[1].y() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(AlignRigid(nan, plane), InvalidInputError);
}

TEST(CompareToGroundTruth, RecoversARigidTransformOfTheWholeEstimate) {
  Random rnd(31);
  const Values gt = MakeScene();
  const SE3 T = rnd.Pose(10.0);
  const Values est = TransformValues(T, gt);  // poses and objects in another world frame
  const GroundTruthErrors e = CompareToGroundTruth(est, gt);
  EXPECT_LT(MaxAbsDiff(e.alignment, T.inverse()), 1e-12);
  EXPECT_LT(e.aligned.poses.ate, 1e-12);
  EXPECT_LT(e.aligned.poses.are_deg, 1e-10);
  // Objects are moved by the alignment too.
  EXPECT_LT(e.aligned.objects.ate, 1e-12);
  EXPECT_LT(e.aligned.objects.are_deg, 1e-10);
  EXPECT_EQ(e.aligned.objects.count, 8);
  // Without alignment the same estimate is far off.
  const TrajectoryErrors raw = CompareEstimates(est, gt);
  EXPECT_GT(raw.poses.ate, 1.0);
  EXPECT_GT(raw.poses.are_deg, 10.0);
  EXPECT_EQ(e.unaligned.poses.ate, raw.poses.ate);
  EXPECT_EQ(e.unaligned.objects.are_deg, raw.objects.are_deg);
}

TEST(CompareToGroundTruth, AlignmentUsesPosesOnlyAndMinimisesPoseAte) {
  Random rnd(32);
  const Values gt = MakeScene();
  Values est = TransformValues(rnd.Pose(5.0), gt);
  for (auto& [key, x] : est) {
    // Noisy poses; objects grossly wrong, which must not pull the alignment.
    const double sigma = key.isPose() ? 0.05 : 3.0;
    x = x.retract((Vector6() << 0.02 * rnd.Axis(), rnd.Point(sigma)).finished());
  }
  const GroundTruthErrors e = CompareToGroundTruth(est, gt);
  EXPECT_LT(e.aligned.poses.ate, e.unaligned.poses.ate);
  // The alignment minimises the pose ATE: any nearby rigid transform does worse.
  for (int i = 0; i < 30; ++i) {
    Vector6 xi;
    for (int j = 0; j < 6; ++j) xi(j) = 1e-3 * rnd.Normal();
    const Values moved = TransformValues(SE3::Exp(xi) * e.alignment, est);
    EXPECT_GT(CompareEstimates(moved, gt).poses.ate, e.aligned.poses.ate);
  }
}

TEST(CompareToGroundTruth, PropagatesMissingKeysAndTooFewPoses) {
  const Values gt = MakeScene();
  Values est = gt;
  est.erase(Key::Pose(1, 9));
  EXPECT_THROW(CompareToGroundTruth(est, gt), InvalidInputError);
  const Values two{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3(SO3(), Vector3(1, 0, 0))},
                   {Key::Object(0, 0), SE3(SO3(), Vector3(0, 1, 0))}};
  EXPECT_THROW(CompareToGroundTruth(two, two), UnderdeterminedError);
}

TEST(MaxPoseDifference, LargestTranslationOrRotationGapOverTheReferenceKeys) {
  const Values reference{{Key::Pose(0, 0), SE3()},
                         {Key::Pose(0, 1), SE3(SO3(), Vector3(1, 0, 0))}};
  EXPECT_EQ(MaxPoseDifference(reference, reference), 0.0);
  Values estimate = reference;
  estimate[Key::Pose(0, 1)] = SE3(SO3(), Vector3(1, 0.25, 0));
  EXPECT_NEAR(MaxPoseDifference(estimate, reference), 0.25, 1e-15);
  // A 0.1 rad turn (||R - I||_F = 2 sqrt(2) sin(0.05) = 0.141) stays below the 0.25 m gap.
  estimate[Key::Pose(0, 0)] = SE3(SO3::Exp(Vector3(0, 0, 0.1)), Vector3::Zero());
  EXPECT_NEAR(MaxPoseDifference(estimate, reference), 0.25, 1e-15);
  estimate[Key::Pose(0, 0)] = SE3(SO3::Exp(Vector3(0, 0, 0.5)), Vector3::Zero());
  EXPECT_NEAR(MaxPoseDifference(estimate, reference), 2.0 * std::sqrt(2.0) * std::sin(0.25),
              1e-12);
  // Only the reference's keys count; one missing from the estimate is an infinite gap.
  estimate[Key::Object(0, 0)] = SE3(SO3(), Vector3(9, 9, 9));
  EXPECT_NEAR(MaxPoseDifference(estimate, reference), 2.0 * std::sqrt(2.0) * std::sin(0.25),
              1e-12);
  EXPECT_EQ(MaxPoseDifference(reference, estimate), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace moslam
