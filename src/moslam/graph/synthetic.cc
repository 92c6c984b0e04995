#include "moslam/graph/synthetic.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

void SyntheticGraphOptions::validate() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw InvalidInputError(std::string("SyntheticGraphOptions.") + what);
  };
  require(num_robots >= 1 && num_robots <= kMaxRobots, "num_robots must be in [1, kMaxRobots]");
  require(poses_per_robot >= 2, "poses_per_robot must be >= 2");
  require(sigma_rotation >= 0.0 && std::isfinite(sigma_rotation),
          "sigma_rotation must be finite and >= 0");
  require(sigma_translation >= 0.0 && std::isfinite(sigma_translation),
          "sigma_translation must be finite and >= 0");
  require(loop_closure_radius >= 0.0 && std::isfinite(loop_closure_radius),
          "loop_closure_radius must be finite and >= 0");
  require(max_loop_closures_per_pose >= 0, "max_loop_closures_per_pose must be >= 0");
}

SyntheticGraph MakeSyntheticGraph(const SyntheticGraphOptions& o) {
  o.validate();
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u01(0.0, 1.0);

  SyntheticGraph out;
  // Ground truth: each robot starts at its own offset and follows a lawnmower path with small
  // random roll/pitch, so every rotation axis is exercised.
  for (int r = 0; r < o.num_robots; ++r) {
    SE3 x(SO3::Exp(Vector3(0.0, 0.0, 0.3 * r)), Vector3(0.7 * r, 0.5 * r, 0.1 * r));
    for (int i = 0; i < o.poses_per_robot; ++i) {
      out.ground_truth.emplace(Key::Pose(r, static_cast<std::uint64_t>(i)), x);
      const bool turn = (i % 8) == 7;
      const Vector3 w(0.05 * n01(rng), 0.05 * n01(rng), turn ? 1.5707963267948966 : 0.1 * n01(rng));
      x = x * SE3(SO3::Exp(w), Vector3(1.0, 0.0, 0.02 * n01(rng)));
    }
  }
  const double sr = std::max(o.sigma_rotation, 1e-3), st = std::max(o.sigma_translation, 1e-3);
  Vector6 diag;
  diag << Vector3::Constant(1.0 / (sr * sr)), Vector3::Constant(1.0 / (st * st));
  const Matrix6 info = diag.asDiagonal();
  auto noisy = [&](const SE3& z) {
    Vector6 xi;
    xi << o.sigma_rotation * n01(rng), o.sigma_rotation * n01(rng), o.sigma_rotation * n01(rng),
        o.sigma_translation * n01(rng), o.sigma_translation * n01(rng),
        o.sigma_translation * n01(rng);
    return z.retract(xi);
  };
  auto add = [&](Key a, Key b) {
    const SE3 z = out.ground_truth.at(a).between(out.ground_truth.at(b));
    out.graph.add(RelativePoseFactor(a, b, noisy(z), info));
  };
  for (int r = 0; r < o.num_robots; ++r) {
    for (int i = 0; i + 1 < o.poses_per_robot; ++i) {
      add(Key::Pose(r, static_cast<std::uint64_t>(i)), Key::Pose(r, static_cast<std::uint64_t>(i + 1)));
    }
  }
  // Loop closures (intra- and inter-robot) between poses close in space but not in time.
  std::vector<Key> keys;
  for (const auto& kv : out.ground_truth) keys.push_back(kv.first);
  for (size_t i = 0; i < keys.size(); ++i) {
    int added = 0;
    for (size_t j = 0; j < i && added < o.max_loop_closures_per_pose; ++j) {
      const Key a = keys[j], b = keys[i];
      if (a.robot == b.robot && b.index - a.index < 3) continue;
      const double d = (out.ground_truth.at(a).translation() - out.ground_truth.at(b).translation()).norm();
      if (d < o.loop_closure_radius && u01(rng) < 0.5) {
        add(a, b);
        ++added;
      }
    }
  }
  return out;
}

}  // namespace moslam
