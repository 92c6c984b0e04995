// Object constellations aligned with no initial guess (constellation.h), on hand-made layouts.
#include "moslam/slam/constellation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/geometry/so3.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

SE3 Yawed(double yaw, double x, double y) {
  return SE3(SO3::Exp(Vector3(0, 0, yaw)), Vector3(x, y, 0.0));
}

// A 5 x 5 grid of chairs 2 m apart, yaw per chair (random, or all 0), and a few other objects.
std::vector<ConstellationObject> Room(bool random_yaws, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> yaw(-kPi, kPi);
  std::vector<ConstellationObject> objects;
  std::uint32_t id = 0;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      objects.push_back({id++, "chair", Yawed(random_yaws ? yaw(rng) : 0.0, 2.0 * i, 2.0 * j)});
    }
  }
  return objects;
}

// What a robot maps of `world` seen from frame `world_T_robot`: the objects with the given
// indices, in its frame, with noise, under ids of its own.
std::vector<ConstellationObject> Mapped(const std::vector<ConstellationObject>& world,
                                        const std::vector<int>& seen, const SE3& world_T_robot,
                                        double sigma_t, double sigma_r_deg, unsigned seed,
                                        std::uint32_t first_id) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<ConstellationObject> out;
  std::uint32_t id = first_id;
  for (int k : seen) {
    const Vector3 dt(n(rng) * sigma_t, n(rng) * sigma_t, n(rng) * sigma_t);
    const Vector3 dr = Vector3(n(rng), n(rng), n(rng)) * sigma_r_deg * kPi / 180.0;
    const SE3 pose = world_T_robot.inverse() * world[static_cast<std::size_t>(k)].pose *
                     SE3(SO3::Exp(dr), dt);
    out.push_back({id++, world[static_cast<std::size_t>(k)].label, pose});
  }
  return out;
}

TEST(Constellation, RecoversTheExactTransformWithNoNoise) {
  const std::vector<ConstellationObject> world = Room(true, 1);
  const SE3 world_T_a(SO3::Exp(Vector3(0.1, -0.2, 1.3)), Vector3(4.0, -7.0, 1.0));
  const SE3 world_T_b(SO3::Exp(Vector3(-0.3, 0.2, -2.1)), Vector3(-3.0, 5.0, 0.5));
  // a sees chairs 0-9, b sees chairs 5-19: 5 in common.
  std::vector<int> seen_a, seen_b;
  for (int k = 0; k < 10; ++k) seen_a.push_back(k);
  for (int k = 5; k < 20; ++k) seen_b.push_back(k);
  const auto a = Mapped(world, seen_a, world_T_a, 0.0, 0.0, 2, 0);
  const auto b = Mapped(world, seen_b, world_T_b, 0.0, 0.0, 3, 100);
  ConstellationConfig exact;  // noise-free maps: tight tolerances
  exact.sigma_translation = 0.01;
  exact.sigma_rotation_deg = 0.5;
  exact.drift_per_m = 0.0;
  const ConstellationAlignment r = AlignConstellations(a, b, exact);
  ASSERT_EQ(r.status, AlignmentStatus::kAligned) << r.reason;
  EXPECT_EQ(r.support, 5);
  const SE3 expected = world_T_b.inverse() * world_T_a;
  EXPECT_LT((r.b_T_a.translation() - expected.translation()).norm(), 1e-9);
  EXPECT_LT(SO3::Log(r.b_T_a.rotation().inverse() * expected.rotation()).norm(), 1e-9);
  ASSERT_EQ(r.pairs.size(), 5u);
  for (const auto& [ia, ib] : r.pairs) {
    EXPECT_EQ(seen_a[ia], seen_b[ib - 100]);  // the same chair
  }
}

TEST(Constellation, ASymmetricGridIsAmbiguousWithoutOrientationsAndAlignedWithThem) {
  for (bool yaws : {false, true}) {
    SCOPED_TRACE(yaws ? "random yaws" : "all chairs facing the same way");
    const std::vector<ConstellationObject> world = Room(yaws, 5);
    const SE3 world_T_a(SO3::Exp(Vector3(0, 0, 0.4)), Vector3(1.0, 2.0, 0.0));
    const SE3 world_T_b(SO3::Exp(Vector3(0, 0, -1.1)), Vector3(-2.0, 3.0, 0.0));
    // a: a 3 x 3 block of the grid; b: the whole grid. Without orientations the block fits at
    // nine places of the grid.
    std::vector<int> block, all;
    for (int i = 1; i < 4; ++i) {
      for (int j = 1; j < 4; ++j) block.push_back(5 * i + j);
    }
    for (int k = 0; k < 25; ++k) all.push_back(k);
    const auto a = Mapped(world, block, world_T_a, 0.02, 0.5, 6, 0);
    const auto b = Mapped(world, all, world_T_b, 0.02, 0.5, 7, 100);
    ConstellationConfig config;  // the maps' noise
    config.sigma_translation = 0.03;
    config.sigma_rotation_deg = 1.0;
    const ConstellationAlignment r = AlignConstellations(a, b, config);
    if (!yaws) {
      EXPECT_EQ(r.status, AlignmentStatus::kAmbiguous) << r.reason;
      EXPECT_GE(r.rival, r.support - 1);
      EXPECT_TRUE(r.pairs.empty());
    } else {
      ASSERT_EQ(r.status, AlignmentStatus::kAligned) << r.reason;
      EXPECT_EQ(r.support, 9);
      for (const auto& [ia, ib] : r.pairs) EXPECT_EQ(block[ia], all[ib - 100]);
      const SE3 expected = world_T_b.inverse() * world_T_a;
      EXPECT_LT((r.b_T_a.translation() - expected.translation()).norm(), 0.1);
    }
  }
}

TEST(Constellation, TooFewObjectsAreRefused) {
  const std::vector<ConstellationObject> world = Room(true, 9);
  const auto a = Mapped(world, {0, 1, 2}, SE3(), 0.0, 0.0, 1, 0);
  const auto b = Mapped(world, {1, 2, 10, 11}, SE3(), 0.0, 0.0, 2, 100);
  const ConstellationAlignment r = AlignConstellations(a, b, ConstellationConfig());
  EXPECT_EQ(r.status, AlignmentStatus::kTooFew);
  EXPECT_EQ(r.support, 2);
  EXPECT_TRUE(r.pairs.empty());
  EXPECT_FALSE(r.reason.empty());
  // Three shared objects: too few by default (min_support 4: three agree by chance too often in
  // a team of 16), not with min_support 3 (which still refuses them as ambiguous here: on this
  // grid a pair of other objects reads them otherwise).
  const auto a3 = Mapped(world, {0, 1, 2, 3}, SE3(), 0.0, 0.0, 1, 0);
  const auto b3 = Mapped(world, {1, 2, 3, 10, 11}, SE3(), 0.0, 0.0, 2, 100);
  const ConstellationAlignment three = AlignConstellations(a3, b3, ConstellationConfig());
  EXPECT_EQ(three.status, AlignmentStatus::kTooFew) << three.reason;
  EXPECT_EQ(three.support, 3);
  ConstellationConfig three_enough;
  three_enough.min_support = 3;
  EXPECT_EQ(AlignConstellations(a3, b3, three_enough).status, AlignmentStatus::kAmbiguous);
  // Different labels: no candidate at all.
  std::vector<ConstellationObject> tables = a;
  for (auto& o : tables) o.label = "table";
  EXPECT_EQ(AlignConstellations(tables, b, ConstellationConfig()).candidates, 0);
  ConstellationConfig bad;
  bad.min_support = 1;
  EXPECT_THROW(AlignConstellations(a, b, bad), InvalidInputError);
}

TEST(Constellation, DuplicateLandmarksCountOnce) {
  // Both robots map chairs 0-2, and each maps chair 2 twice (a second landmark 1.2 m and 10 deg
  // off, the same offset in both maps): four pairwise consistent candidates, three objects.
  const std::vector<ConstellationObject> world = Room(true, 5);
  auto a = Mapped(world, {0, 1, 2}, Yawed(0.4, 1.0, 2.0), 0.0, 0.0, 1, 0);
  auto b = Mapped(world, {0, 1, 2}, Yawed(-1.1, -3.0, 0.5), 0.0, 0.0, 2, 100);
  const SE3 offset(SO3::Exp(Vector3(0.0, 0.0, 10.0 * kPi / 180.0)), Vector3(1.2, 0.0, 0.0));
  a.push_back({3, "chair", a[2].pose * offset});
  b.push_back({103, "chair", b[2].pose * offset});
  const ConstellationAlignment r = AlignConstellations(a, b, ConstellationConfig());
  EXPECT_EQ(r.status, AlignmentStatus::kTooFew) << r.reason;
  EXPECT_EQ(r.support, 3);
  ConstellationConfig three;
  three.min_support = 3;
  const ConstellationAlignment aligned = AlignConstellations(a, b, three);
  ASSERT_EQ(aligned.status, AlignmentStatus::kAligned) << aligned.reason;
  EXPECT_EQ(aligned.support, 3);
  EXPECT_EQ(aligned.pairs.size(), 4u);  // the duplicates are shared with each other
  // Told apart when the radius says so: four objects then.
  ConstellationConfig apart;
  apart.same_object_radius = 1.0;
  EXPECT_EQ(AlignConstellations(a, b, apart).support, 4);
  ConstellationConfig bad;
  bad.same_object_radius = -1.0;
  EXPECT_THROW(AlignConstellations(a, b, bad), InvalidInputError);
}

TEST(Constellation, NoisyMapsAlignAndAWrongPairFailsConsistency) {
  const std::vector<ConstellationObject> world = Room(true, 11);
  std::vector<int> seen_a, seen_b;
  for (int k = 0; k < 15; ++k) seen_a.push_back(k);
  for (int k = 8; k < 25; ++k) seen_b.push_back(k);
  const SE3 world_T_a = Yawed(0.7, 3.0, 1.0), world_T_b = Yawed(-2.0, -1.0, 4.0);
  const auto a = Mapped(world, seen_a, world_T_a, 0.1, 3.0, 12, 0);
  const auto b = Mapped(world, seen_b, world_T_b, 0.1, 3.0, 13, 100);
  ConstellationConfig config;  // the maps' noise
  config.sigma_translation = 0.1;
  config.sigma_rotation_deg = 3.0;
  const ConstellationAlignment r = AlignConstellations(a, b, config);
  ASSERT_EQ(r.status, AlignmentStatus::kAligned) << r.reason;
  int correct = 0;
  for (const auto& [ia, ib] : r.pairs) correct += seen_a[ia] == seen_b[ib - 100] ? 1 : 0;
  EXPECT_EQ(correct, static_cast<int>(r.pairs.size()));  // no wrong pair
  EXPECT_GE(correct, 5);                                  // of the 7 in common

  // Consistency of given pairs: the seven true pairs and one swapped, label-consistent pair.
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i < seen_a.size(); ++i) {
    for (std::size_t j = 0; j < seen_b.size(); ++j) {
      if (seen_a[i] == seen_b[j]) pairs.emplace_back(i, j);
    }
  }
  ASSERT_EQ(pairs.size(), 7u);
  pairs.emplace_back(0, 16);  // chair 0 of a as chair 24 of b: wrong
  const std::vector<std::size_t> kept = ConsistentSubset(a, b, pairs, config);
  EXPECT_EQ(kept.size(), 7u);
  for (std::size_t k : kept) EXPECT_NE(k, 7u);
}

TEST(Constellation, BadOptionsNameTheField) {
  using C = ConstellationConfig;
  EXPECT_TRUE(test::EachChangeIsRefused<C>({
      {"sigma_translation", [](C& c) { c.sigma_translation = 0.0; }},
      {"sigma_rotation_deg", [](C& c) { c.sigma_rotation_deg = std::nan(""); }},
      {"num_sigmas", [](C& c) { c.num_sigmas = INFINITY; }},
      {"drift_per_m", [](C& c) { c.drift_per_m = -0.01; }},
      {"min_support", [](C& c) { c.min_support = 1; }},
      {"ambiguity_margin", [](C& c) { c.ambiguity_margin = -1; }},
      {"same_object_radius", [](C& c) { c.same_object_radius = std::nan(""); }},
      {"max_search_nodes", [](C& c) { c.max_search_nodes = 0; }},
  }));
}

}  // namespace
}  // namespace moslam
