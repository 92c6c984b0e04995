#include "moslam/robust/spoil.h"

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/geometry/so3.h"

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
  std::vector<std::size_t> separators;
  std::set<std::pair<Key, Key>> linked;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    linked.insert({std::min(f.a(), f.b()), std::max(f.a(), f.b())});
    if (f.a().robot != f.b().robot) separators.push_back(i);
  }
  if (poses.size() < 2) {
    throw InvalidInputError("spoil: the graph has " + std::to_string(poses.size()) +
                            " robot(s) with poses; separators need two");
  }
  if (separators.empty()) {
    throw InvalidInputError("spoil: the graph has no inter-robot factor to imitate");
  }
  SpoiledGraph out;
  out.graph = graph;
  out.outlier.assign(graph.factors().size(), false);
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
      throw InvalidInputError("spoil: could not find " + std::to_string(k) +
                              " unlinked pose pairs between robots");
    }
    const std::size_t ra = uniform(robots.size());
    std::size_t rb = uniform(robots.size() - 1);
    if (rb >= ra) ++rb;
    const std::vector<Key>& pa = poses.at(robots[ra]);
    const std::vector<Key>& pb = poses.at(robots[rb]);
    const Key a = pa[uniform(pa.size())], b = pb[uniform(pb.size())];
    if (!linked.insert({std::min(a, b), std::max(a, b)}).second) continue;
    const RelativePoseFactor& like = graph.factors()[separators[uniform(separators.size())]];
    // A uniformly random rotation: the axis uniform on the sphere, the angle with density
    // (1 - cos t) / pi on [0, pi] (by rejection).
    double angle = 0.0;
    for (;;) {
      angle = M_PI * unit(rng);
      if (unit(rng) * 2.0 <= 1.0 - std::cos(angle)) break;
    }
    const SO3 R = SO3::Exp(angle * direction());
    const Vector3 t = like.measured().translation().norm() * direction();
    out.graph.add(RelativePoseFactor(a, b, SE3(R, t), like.information()));
    out.outlier.push_back(true);
    ++out.added;
  }
  return out;
}

}  // namespace moslam
