#include "moslam/distributed/separator_consistency.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <map>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/geometry/so3.h"
#include "moslam/robust/max_clique.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"

namespace moslam {

void SeparatorConsistencyOptions::validate() const {
  if (!(threshold > 0.0)) {
    throw InvalidInputError("separator consistency: threshold must be positive");
  }
  if (min_support < 1) throw InvalidInputError("separator consistency: min_support must be >= 1");
}

namespace {

// Robot r's own estimate of its variables: its intra-robot factors solved alone, re-keyed as
// robot 0 for the gauge (its first pose at the identity). Empty when it has none.
Values LocalEstimate(const PoseGraph& graph, int robot) {
  PoseGraph local;
  auto rekey = [](Key k) { return Key{0, k.kind, k.index}; };
  for (const RelativePoseFactor& f : graph.factors()) {
    if (f.a().robot == robot && f.b().robot == robot) {
      local.add(RelativePoseFactor(rekey(f.a()), rekey(f.b()), f.measured(), f.information()));
    }
  }
  Values out;
  if (local.factors().empty()) return out;
  OptimizerOptions options;
  options.max_iterations = 50;
  const Values solved = Optimize(local, ChordalInitialization(local, SE3()), options).values;
  for (const auto& [k, x] : solved) out[Key{robot, k.kind, k.index}] = x;
  return out;
}

}  // namespace

SeparatorConsistencyResult CheckSeparatorConsistency(const PoseGraph& graph,
                                                     const SeparatorConsistencyOptions& options) {
  options.validate();
  const auto& factors = graph.factors();
  SeparatorConsistencyResult out;
  out.kept.assign(factors.size(), true);
  std::map<std::pair<int, int>, std::vector<std::size_t>> pairs;
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const int a = factors[i].a().robot, b = factors[i].b().robot;
    if (a == b) continue;
    ++out.separators;
    pairs[{std::min(a, b), std::max(a, b)}].push_back(i);
  }
  std::map<int, Values> local;
  auto estimate = [&](int robot) -> const Values& {
    auto it = local.find(robot);
    if (it == local.end()) it = local.emplace(robot, LocalEstimate(graph, robot)).first;
    return it->second;
  };
  for (const auto& [pair, list] : pairs) {
    ++out.robot_pairs;
    const auto [ra, rb] = pair;
    const Values& A = estimate(ra);
    const Values& B = estimate(rb);
    // What robot b sends robot a: the local estimates of its separator poses.
    Message m;
    m.stage = DgsStage::kPose;
    m.sender = rb;
    std::set<Key> keys;
    for (std::size_t i : list) {
      keys.insert(factors[i].a().robot == rb ? factors[i].a() : factors[i].b());
    }
    bool known = true;
    for (const Key& k : keys) {
      const auto it = B.find(k);
      if (it == B.end()) {
        known = false;
        break;
      }
      m.keys.push_back(k);
      const Vector3 w = SO3::Log(it->second.rotation());
      for (int c = 0; c < 3; ++c) m.values.push_back(w[c]);
      for (int c = 0; c < 3; ++c) m.values.push_back(it->second.translation()[c]);
    }
    if (!known) continue;  // a pose the robot's own factors do not reach: nothing to check with
    const std::vector<std::uint8_t> wire = EncodeMessage(m);
    out.bytes += static_cast<std::int64_t>(wire.size());
    ++out.messages;
    const Message received = DecodeMessage(wire);
    std::map<Key, SE3> b_poses;
    for (std::size_t e = 0; e < received.keys.size(); ++e) {
      const double* v = received.entry(e);
      b_poses[received.keys[e]] = SE3(SO3::Exp(Vector3(v[0], v[1], v[2])), Vector3(v[3], v[4], v[5]));
    }
    // T_i: robot b's frame in robot a's, from separator i.
    std::vector<SE3> T;
    std::vector<Matrix6> covariance;
    bool usable = true;
    for (std::size_t i : list) {
      const RelativePoseFactor& f = factors[i];
      const bool a_first = f.a().robot == ra;
      const Key ka = a_first ? f.a() : f.b(), kb = a_first ? f.b() : f.a();
      if (!A.count(ka)) {
        usable = false;
        break;
      }
      const SE3 z = a_first ? f.measured() : f.measured().inverse();
      T.push_back(A.at(ka) * z * b_poses.at(kb).inverse());
      covariance.push_back(f.information().inverse());
    }
    if (!usable) continue;
    const int n = static_cast<int>(list.size());
    ConsistencyGraph g(n);
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) {
        const SE3 d = T[static_cast<std::size_t>(i)].inverse() * T[static_cast<std::size_t>(j)];
        Vector6 e;
        e << SO3::Log(d.rotation()), d.translation();
        const Matrix6 S = covariance[static_cast<std::size_t>(i)] + covariance[static_cast<std::size_t>(j)];
        if (e.dot(S.ldlt().solve(e)) <= options.threshold) g.connect(i, j);
      }
    }
    const CliqueResult best = MaximumClique(g);
    std::vector<bool> in(list.size(), false);
    if (static_cast<int>(best.nodes.size()) >= options.min_support) {
      for (int p : best.nodes) in[static_cast<std::size_t>(p)] = true;
    } else {
      ++out.robot_pairs_rejected;
    }
    for (std::size_t p = 0; p < list.size(); ++p) {
      if (!in[p]) {
        out.kept[list[p]] = false;
        ++out.rejected;
      }
    }
  }
  return out;
}

}  // namespace moslam
