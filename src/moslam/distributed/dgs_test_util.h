// Helpers shared by the distributed tests (not part of the library).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/geometry/so3.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/io/datasets_testing.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"

namespace moslam::test {

inline constexpr int kBlocksWorldRobots[] = {2, 4, 9, 16, 25, 36, 49};

// Three robots, each a chain of `n` poses along x (1 m apart, robot r starting at 10 + 10 r m),
// consecutive robots linked last pose to first pose; noise-free. Initial values: ground truth.
inline PoseGraph ChainOfRobots(int robots, int n, Values* ground_truth) {
  PoseGraph g;
  Values gt;
  auto pose = [](int r, int i) {
    return SE3(SO3::Exp(Vector3(0.0, 0.0, 0.1 * (r * 7 + i))),
               Vector3(10.0 + 10.0 * r + i, 0.3 * i, 0.0));
  };
  for (int r = 0; r < robots; ++r) {
    for (int i = 0; i < n; ++i) gt[Key::Pose(r, static_cast<std::uint64_t>(i))] = pose(r, i);
  }
  auto edge = [&](Key a, Key b) {
    g.add(RelativePoseFactor(a, b, gt.at(a).between(gt.at(b)), Matrix6::Identity()));
  };
  for (int r = 0; r < robots; ++r) {
    for (int i = 0; i + 1 < n; ++i) {
      edge(Key::Pose(r, static_cast<std::uint64_t>(i)), Key::Pose(r, static_cast<std::uint64_t>(i + 1)));
    }
    if (r + 1 < robots) edge(Key::Pose(r, static_cast<std::uint64_t>(n - 1)), Key::Pose(r + 1, 0));
  }
  if (ground_truth) *ground_truth = gt;
  return g;
}

// Two robots dead-reckoning 60 poses each (0.5 deg / 3 cm of odometry noise per step, information
// to match; seeded) and meeting every 10 poses (separators of 0.5 deg / 2 cm), then two
// right-looking separators to the wrong pose, 3 m and 30 deg off: `wrong` gets one flag per
// separator, in graph order (the separators are the last factors). Their maps drift apart by far
// more than the separators' noise.
inline PoseGraph DriftingPairWithWrongSeparators(std::vector<bool>* wrong) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n01;
  auto noise = [&](double sr, double st) {
    Vector6 xi;
    for (int c = 0; c < 6; ++c) xi[c] = n01(rng) * (c < 3 ? sr : st);
    return SE3::Exp(xi);
  };
  auto information = [](double sr, double st) {
    Vector6 d;
    d << Vector3::Constant(1.0 / (sr * sr)), Vector3::Constant(1.0 / (st * st));
    return Matrix6(d.asDiagonal());
  };
  const double deg = 3.14159265358979323846 / 180.0;
  const double sr = 0.5 * deg, st = 0.03, zr = 0.5 * deg, zt = 0.02;
  const int n = 60;
  std::vector<SE3> truth[2];
  for (int r = 0; r < 2; ++r) {
    SE3 x(SO3(), Vector3(0.0, 3.0 * r, 0.0));
    for (int i = 0; i < n; ++i) {
      truth[r].push_back(x);
      x = x * SE3(SO3::Exp(Vector3(0.0, 0.0, 0.05)), Vector3(0.5, 0.0, 0.0));
    }
  }
  auto key = [](int r, int i) { return Key::Pose(r, static_cast<std::uint64_t>(i)); };
  PoseGraph g;
  for (int r = 0; r < 2; ++r) {
    for (int i = 0; i + 1 < n; ++i) {
      g.add(RelativePoseFactor(key(r, i), key(r, i + 1),
                               truth[r][i].between(truth[r][i + 1]) * noise(sr, st),
                               information(sr, st)));
    }
  }
  wrong->clear();
  for (int i = 0; i < n; i += 10) {
    g.add(RelativePoseFactor(key(0, i), key(1, i), truth[0][i].between(truth[1][i]) * noise(zr, zt),
                             information(zr, zt)));
    wrong->push_back(false);
  }
  for (int i : {15, 35}) {
    g.add(RelativePoseFactor(key(1, i), key(0, i + 4), truth[1][i].between(truth[0][i]) *
                             SE3(SO3::Exp(Vector3(0.0, 0.0, 0.52)), Vector3(3.0, 0.0, 0.0)),
                             information(zr, zt)));
    wrong->push_back(true);
  }
  return g;
}

// The same pair, and a copy of its separator 3 turned 0.4 m / 2.3 deg (wrong, the last factor): a
// near miss that the drift between separators lets pass the pairwise test with several right ones.
inline PoseGraph DriftingPairWithANearMiss(std::vector<bool>* wrong) {
  PoseGraph g = DriftingPairWithWrongSeparators(wrong);
  const RelativePoseFactor copied = g.factors()[g.factors().size() - wrong->size() + 3];
  g.add(RelativePoseFactor(copied.a(), copied.b(),
                           copied.measured() * SE3(SO3::Exp(Vector3(0.0, 0.0, 0.04)),
                                                   Vector3(0.4, 0.0, 0.0)),
                           copied.information()));
  wrong->push_back(true);
  return g;
}

// Two robots that each saw six objects from two poses, objects 2 and 3 two chairs 0.3 m apart at
// one orientation, and a right object-object separator per landmark pair (the paper's Lambda,
// 5 deg / 0.2 m). Robot 1 maps the objects `twice` lists twice (see ObjectsMappedTwice);
// otherwise every observation is exact.
inline PoseGraph SixObjectsSeenByTwo(const std::vector<std::uint64_t>& twice) {
  const double deg = 3.14159265358979323846 / 180.0;
  const std::vector<SE3> objects = {
      SE3(SO3::Exp(Vector3(0.0, 0.0, 0.3)), Vector3(2.0, 0.0, 0.0)),
      SE3(SO3::Exp(Vector3(0.0, 0.0, 1.2)), Vector3(3.0, 2.0, 0.0)),
      SE3(SO3::Exp(Vector3(0.0, 0.0, -0.4)), Vector3(1.0, 3.5, 0.0)),
      SE3(SO3::Exp(Vector3(0.0, 0.0, -0.4)), Vector3(1.0, 3.5, 0.0)) *
          SE3(SO3(), Vector3(0.3, 0.0, 0.0)),
      SE3(SO3::Exp(Vector3(0.0, 0.0, 2.0)), Vector3(-2.0, 1.0, 0.0)),
      SE3(SO3::Exp(Vector3(0.0, 0.0, -2.2)), Vector3(-1.0, -2.5, 0.0)),
  };
  const SE3 start[2] = {SE3(), SE3(SO3::Exp(Vector3(0.0, 0.0, 2.5)), Vector3(4.0, 4.0, 0.0))};
  const SE3 step(SO3::Exp(Vector3(0.0, 0.0, 0.2)), Vector3(0.5, 0.1, 0.0));
  const SE3 off(SO3(), Vector3(0.02, 0.0, 0.0));
  Vector6 d;
  d << Vector3::Constant(1.0 / std::pow(1.0 * deg, 2)), Vector3::Constant(1.0 / (0.02 * 0.02));
  const Matrix6 precise = d.asDiagonal();
  d << Vector3::Constant(1.0 / std::pow(5.0 * deg, 2)), Vector3::Constant(1.0 / (0.2 * 0.2));
  const Matrix6 lambda = d.asDiagonal();
  const auto mapped_twice = [&](std::uint64_t k) {
    return std::find(twice.begin(), twice.end(), k) != twice.end();
  };
  PoseGraph g;
  for (int r = 0; r < 2; ++r) {
    const Key x0 = Key::Pose(r, 0), x1 = Key::Pose(r, 1);
    g.add(RelativePoseFactor(x0, x1, step, precise));
    const SE3 poses[2] = {start[r], start[r] * step};
    for (std::uint64_t i = 0; i < 2; ++i) {
      for (std::uint64_t k = 0; k < objects.size(); ++k) {
        const SE3 z = poses[i].between(objects[k]);
        if (r == 1 && mapped_twice(k)) {
          const std::uint64_t landmark = i == 0 ? k : objects.size() + k;
          g.add(RelativePoseFactor(Key::Pose(r, i), Key::Object(r, landmark), i == 0 ? z * off : z,
                                   precise));
        } else {
          g.add(RelativePoseFactor(Key::Pose(r, i), Key::Object(r, k), z, precise));
        }
      }
    }
  }
  for (std::uint64_t k = 0; k < objects.size(); ++k) {
    g.add(RelativePoseFactor(Key::Object(0, k), Key::Object(1, k), SE3(), lambda));
  }
  for (std::uint64_t k : twice) {
    g.add(RelativePoseFactor(Key::Object(0, k), Key::Object(1, objects.size() + k), SE3(), lambda));
  }
  return g;
}

// Two robots that each saw six objects from two poses (exact observations), objects 2 and 3 two
// chairs 0.3 m apart at one orientation; six right object-object separators (robot 0's landmark k
// is robot 1's landmark k; the paper's Lambda, 5 deg / 0.2 m) and a wrong one, the last factor:
// robot 0's chair 2 paired with robot 1's chair 3, which fits the right estimate within GNC's c2
// (r^T Omega r 2.25) and agrees with four right separators by their loops, but pairs two landmarks
// twice: the check's one-to-one rule leaves it out.
inline PoseGraph TwoChairsSideBySide() {
  PoseGraph g = SixObjectsSeenByTwo({});
  const Matrix6 lambda = g.factors().back().information();  // a separator's
  g.add(RelativePoseFactor(Key::Object(0, 2), Key::Object(1, 3), SE3(), lambda));
  return g;
}

// The six objects of TwoChairsSideBySide, robot 1 mapping objects 0-2 twice (a duplicate: its
// pose 0 saw them as landmarks 0-2, its pose 1 as landmarks 6-8, as a robot that failed to
// re-associate them does), its views of landmarks 0-2 2 cm off (along x in the object's frame),
// every other view exact; nine right separators, robot 0's landmark k paired with robot 1's
// landmarks k and, for k <= 2, 6 + k (the last three factors). The check keeps six, one partner
// per landmark (its one-to-one rule; here the pairs to robot 1's landmarks 3-8), and leaves the
// other three out: a consistent set, the pair's runner-up, each of which fits within c2.
inline PoseGraph ObjectsMappedTwice() { return SixObjectsSeenByTwo({0, 1, 2}); }

// The same pair, and wrong loop closures of robot 1 (the last `loop_closures` factors, 1-3):
// between its poses 0-59, 5-50 and 10-45, its dead reckoning with a 3 m jump at pose 30, far
// tighter than its odometry. They agree with one another exactly (the loop of two goes through
// the jump and back: the identity). Two are fewer than the odometry check's min_support, so its
// own check neither confirms nor rejects them; three confirm one another. GNC-TLS on robot 1's
// map alone takes them, which bends the map by metres. `wrong` flags the separators as
// DriftingPairWithWrongSeparators does; `robust` gets one flag per factor: the separators and the
// loop closures.
inline PoseGraph DriftingPairWithBendingLoopClosures(std::vector<bool>* wrong,
                                                     std::vector<bool>* robust,
                                                     int loop_closures = 2) {
  PoseGraph g = DriftingPairWithWrongSeparators(wrong);
  const auto pose = [](int i) { return Key::Pose(1, static_cast<std::uint64_t>(i)); };
  const auto dead_reckoning = [&](int from, int to) {
    SE3 x;
    for (const RelativePoseFactor& f : g.factors()) {  // robot 1's odometry, in pose order
      if (f.a().robot == 1 && f.b().robot == 1 && f.b().index == f.a().index + 1 &&
          f.a().index >= static_cast<std::uint64_t>(from) &&
          f.b().index <= static_cast<std::uint64_t>(to)) {
        x = x * f.measured();
      }
    }
    return x;
  };
  Vector6 d;
  d << Vector3::Constant(1e5), Vector3::Constant(1e4);
  robust->clear();
  for (const RelativePoseFactor& f : g.factors()) robust->push_back(f.a().robot != f.b().robot);
  const std::pair<int, int> ends[] = {{0, 59}, {5, 50}, {10, 45}};
  for (int k = 0; k < loop_closures; ++k) {
    const auto [a, b] = ends[k];
    const SE3 jump(SO3(), Vector3(-3.0, 0.0, 0.0));
    g.add(RelativePoseFactor(pose(a), pose(b), dead_reckoning(a, 30) * jump * dead_reckoning(30, b),
                             Matrix6(d.asDiagonal())));
    robust->push_back(true);
  }
  return g;
}

}  // namespace moslam::test
