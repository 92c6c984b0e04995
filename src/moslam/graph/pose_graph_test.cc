#include "moslam/graph/pose_graph.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

SE3 Step() { return SE3(SO3::Exp(Vector3(0, 0, 0.1)), Vector3(1, 0, 0)); }

TEST(PoseGraph, CostSumsFactorsAndPriors) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), Step(), 2.0 * Matrix6::Identity()));
  g.add(PriorFactor(Key::Pose(0, 0), SE3(), Matrix6::Identity()));
  Values v{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  const Vector6 r = SE3::Log(Step().inverse());
  EXPECT_NEAR(g.cost(v), r.squaredNorm(), 1e-12);  // 1/2 * 2 * |r|^2 + 0
  v.erase(Key::Pose(0, 1));
  EXPECT_THROW(g.cost(v), InvalidInputError);
}

TEST(PoseGraph, AnchorIsFirstPoseOfRobotZero) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(0, 5), Step(), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(0, 5), Key::Pose(0, 9), Step(), Matrix6::Identity()));
  EXPECT_EQ(GaugeAnchor(g), Key::Pose(0, 5));
  EXPECT_EQ(g.numRobots(), 2);
  PoseGraph h;
  h.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), Step(), Matrix6::Identity()));
  EXPECT_THROW(GaugeAnchor(h), UnderdeterminedError);
}

TEST(PoseGraph, FindsComponentsThatNothingAnchors) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), Step(), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), Step(), Matrix6::Identity()));
  EXPECT_EQ(UnreachableFrom(g, Key::Pose(0, 0)).size(), 2u);
  g.add(PriorFactor(Key::Pose(1, 1), SE3(), Matrix6::Identity()));  // a prior anchors it
  EXPECT_TRUE(UnreachableFrom(g, Key::Pose(0, 0)).empty());
}

}  // namespace
}  // namespace moslam

namespace moslam {
namespace {

// `items` sorted by CanonicalBefore.
template <typename T>
std::vector<T> Canonical(std::vector<T> items) {
  std::stable_sort(items.begin(), items.end(),
                   [](const T& x, const T& y) { return CanonicalBefore(x, y); });
  return items;
}

bool SamePose(const SE3& x, const SE3& y) {
  return x.translation() == y.translation() && x.rotation().matrix() == y.rotation().matrix();
}
bool Same(const RelativePoseFactor& x, const RelativePoseFactor& y) {
  return x.a() == y.a() && x.b() == y.b() && SamePose(x.measured(), y.measured()) &&
         x.information() == y.information();
}
bool Same(const PriorFactor& x, const PriorFactor& y) {
  return x.key() == y.key() && SamePose(x.prior(), y.prior()) && x.information() == y.information();
}

// Of every listing of `items` (each permutation, counted in *listings), how many sort to another
// canonical order than `items` itself.
template <typename T>
int ListingsSortedOtherwise(const std::vector<T>& items, int* listings) {
  const std::vector<T> expected = Canonical(items);
  std::vector<std::size_t> perm(items.size());
  for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = i;
  std::vector<T> listed = items;
  int otherwise = 0;
  *listings = 0;
  do {
    for (std::size_t i = 0; i < perm.size(); ++i) listed[i] = items[perm[i]];
    const std::vector<T> got = Canonical(listed);
    otherwise += !std::equal(got.begin(), got.end(), expected.begin(),
                             [](const T& x, const T& y) { return Same(x, y); });
    ++*listings;
  } while (std::next_permutation(perm.begin(), perm.end()));
  return otherwise;
}

// The canonical order does not depend on the order a graph lists its factors in: ends first,
// then the measurement and the information tell apart factors between the same two variables.
TEST(PoseGraph, CanonicalOrderIsTheSameWhateverTheListingOrder) {
  const Key a = Key::Pose(0, 0), b = Key::Pose(0, 1), c = Key::Pose(1, 0);
  const Matrix6 I = Matrix6::Identity();
  const SE3 x(SO3::Exp(Vector3(0.0, 0.0, 0.1)), Vector3(1.0, 0.0, 0.0));
  const SE3 y(SO3::Exp(Vector3(0.0, 0.0, 0.1)), Vector3(1.0, 0.0, 1e-12));  // translation only
  const std::vector<RelativePoseFactor> factors = {
      RelativePoseFactor(b, c, x, I),     RelativePoseFactor(a, b, y, I),
      RelativePoseFactor(a, b, x, 2 * I), RelativePoseFactor(a, b, x, I),
      RelativePoseFactor(a, c, SE3(), I), RelativePoseFactor(a, b, SE3(), I)};
  int listings = 0;
  EXPECT_EQ(ListingsSortedOtherwise(factors, &listings), 0);
  EXPECT_EQ(listings, 720);
  // The four factors between a and b come first, told apart by measurement, then information.
  const std::vector<RelativePoseFactor> expected = Canonical(factors);
  EXPECT_EQ(expected[4].b(), c);
  EXPECT_EQ(expected[5].a(), b);
  for (std::size_t i = 0; i + 1 < 4; ++i) {
    EXPECT_TRUE(CanonicalBefore(expected[i], expected[i + 1])) << i;
    EXPECT_FALSE(CanonicalBefore(expected[i + 1], expected[i])) << i;
  }
  EXPECT_FALSE(CanonicalBefore(factors[3], factors[3]));
}

// Priors likewise: by key, then prior, then information (a robot's own file and the driver's
// partition may list a robot's priors differently; LocalGraph sums over them in this order).
TEST(PoseGraph, CanonicalOrderOfPriorsIsTheSameWhateverTheListingOrder) {
  const Key a = Key::Pose(0, 0), b = Key::Pose(0, 3);
  const Matrix6 I = Matrix6::Identity();
  const SE3 x(SO3::Exp(Vector3(0.0, 0.1, 0.0)), Vector3(0.0, 2.0, 0.0));
  const SE3 y(SO3::Exp(Vector3(0.0, 0.1, 0.0)), Vector3(0.0, 2.0, 1e-12));  // translation only
  const std::vector<PriorFactor> priors = {PriorFactor(b, SE3(), I), PriorFactor(a, y, I),
                                           PriorFactor(a, x, 3 * I), PriorFactor(a, x, I),
                                           PriorFactor(a, SE3(), I)};
  int listings = 0;
  EXPECT_EQ(ListingsSortedOtherwise(priors, &listings), 0);
  EXPECT_EQ(listings, 120);
  // The four priors on a come first, told apart by prior, then information; b's last.
  const std::vector<PriorFactor> expected = Canonical(priors);
  EXPECT_EQ(expected[4].key(), b);
  for (std::size_t i = 0; i + 1 < expected.size(); ++i) {
    EXPECT_TRUE(CanonicalBefore(expected[i], expected[i + 1])) << i;
    EXPECT_FALSE(CanonicalBefore(expected[i + 1], expected[i])) << i;
  }
  EXPECT_FALSE(CanonicalBefore(priors[3], priors[3]));
}

}  // namespace
}  // namespace moslam
