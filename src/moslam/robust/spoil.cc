#include "moslam/robust/spoil.h"

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/geometry/so3.h"
#include "moslam/robust/gnc.h"

namespace moslam {

void SpoilOptions::validate() const {
  if (!(fraction >= 0.0 && fraction < 1.0)) {
    throw InvalidInputError("spoil: the outlier fraction must be in [0, 1), got " +
                            std::to_string(fraction));
  }
}

SpoiledGraph SpoilSeparators(const PoseGraph& graph, const SpoilOptions& options) {
  options.validate();
  std::map<int, std::vector<Key>> poses;
  for (const Key& k : graph.keys()) {
    if (k.isPose()) poses[k.robot].push_back(k);
  }
  if (poses.empty()) throw InvalidInputError("spoil: the graph has no pose");
  const bool single_robot = poses.size() == 1;
  // Imitated: the separators, or the one robot's loop closures between two of its poses (of the
  // factors DefaultRobustFactors makes robust, those joining two poses).
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  std::vector<std::size_t> separators;
  std::set<std::pair<Key, Key>> linked;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    linked.insert({std::min(f.a(), f.b()), std::max(f.a(), f.b())});
    const bool imitated =
        single_robot ? robust[i] && f.a().isPose() && f.b().isPose() : f.a().robot != f.b().robot;
    if (imitated) separators.push_back(i);
  }
  if (separators.empty()) {
    throw InvalidInputError(single_robot
                                ? "spoil: the graph's one robot has no loop closure (a factor "
                                  "between two poses that are not consecutive) to imitate"
                                : "spoil: the graph has no inter-robot factor to imitate");
  }
  SpoiledGraph out;
  out.graph = graph;
  out.outlier.assign(graph.factors().size(), false);
  out.single_robot = single_robot;
  out.separators = static_cast<int>(separators.size());
  const double n = static_cast<double>(separators.size());
  const int k = static_cast<int>(std::lround(options.fraction / (1.0 - options.fraction) * n));
  std::vector<int> robots;
  for (const auto& [r, list] : poses) robots.push_back(r);
  std::mt19937_64 rng(options.seed);
  auto uniform = [&](std::size_t size) {
    return std::uniform_int_distribution<std::size_t>(0, size - 1)(rng);
  };
  std::normal_distribution<double> normal(0.0, 1.0);
  auto direction = [&]() {
    Vector3 v(normal(rng), normal(rng), normal(rng));
    while (v.norm() < 1e-9) v = Vector3(normal(rng), normal(rng), normal(rng));
    return Vector3(v.normalized());
  };
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int attempts = 0;
  while (out.added < k) {
    if (++attempts > 100 * (k + 10)) {
      throw InvalidInputError(
          "spoil: could not find " + std::to_string(k) + " unlinked pairs of " +
          (single_robot ? "poses that are not consecutive" : "poses of two robots"));
    }
    const std::size_t ra = uniform(robots.size());
    std::size_t rb = 0;
    if (!single_robot) {
      rb = uniform(robots.size() - 1);
      if (rb >= ra) ++rb;
    }
    const std::vector<Key>& pa = poses.at(robots[ra]);
    const std::vector<Key>& pb = poses.at(robots[rb]);
    const Key a = pa[uniform(pa.size())], b = pb[uniform(pb.size())];
    if (single_robot && (a.index + 1 == b.index || b.index + 1 == a.index || a == b)) continue;
    if (!linked.insert({std::min(a, b), std::max(a, b)}).second) continue;
    const RelativePoseFactor& like = graph.factors()[separators[uniform(separators.size())]];
    SO3 R;
    Vector3 t;
    if (options.planar) {  // a uniform rotation about z, a uniform direction in the plane
      const double angle = M_PI * (2.0 * unit(rng) - 1.0), heading = 2.0 * M_PI * unit(rng);
      R = SO3::Exp(Vector3(0.0, 0.0, angle));
      t = like.measured().translation().norm() * Vector3(std::cos(heading), std::sin(heading), 0.0);
    } else {
      // A uniformly random rotation: the axis uniform on the sphere, the angle with density
      // (1 - cos t) / pi on [0, pi] (by rejection).
      double angle = 0.0;
      for (;;) {
        angle = M_PI * unit(rng);
        if (unit(rng) * 2.0 <= 1.0 - std::cos(angle)) break;
      }
      R = SO3::Exp(angle * direction());
      t = like.measured().translation().norm() * direction();
    }
    out.graph.add(RelativePoseFactor(a, b, SE3(R, t), like.information()));
    out.outlier.push_back(true);
    ++out.added;
  }
  return out;
}

}  // namespace moslam
