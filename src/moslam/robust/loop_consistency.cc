#include "moslam/robust/loop_consistency.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/robust/max_clique.h"

namespace moslam {

// A right perturbation x Exp(d) of P_k's variable in L = P1 P2 P3 P4 P5 P6 =
// z_i^-1 A_i^-1 A_j z_j B_j^-1 B_i moves to the right end of L as Ad(T_k^-1) d, T_k =
// P_{k+1} ... P6 (P3, P4, P6: the variable itself), and a variable that enters inverted (P1, P2,
// P5: Exp(-d) P_k) as -Ad(S_k^-1) d, S_k = P_k ... P6.
double LoopStatistic(const LoopEnd& i, const LoopEnd& j, const Matrix12& SA, const Matrix12& SB) {
  const SE3 P[6] = {i.z.inverse(), i.A.inverse(), j.A, j.z, j.B.inverse(), i.B};
  SE3 suffix[7];  // suffix[k] = P_k ... P6 (0-based), suffix[6] = identity
  for (int k = 5; k >= 0; --k) suffix[k] = P[k] * suffix[k + 1];
  const SE3& L = suffix[0];
  auto inverted = [&](int k) -> Matrix6 { return -suffix[k].inverse().Adjoint(); };
  auto direct = [&](int k) -> Matrix6 { return suffix[k + 1].inverse().Adjoint(); };
  const Matrix6 Jzi = inverted(0), Jzj = direct(3);
  Eigen::Matrix<double, 6, 12> JA, JB;
  JA << inverted(1), direct(2);  // (A_i, A_j)
  JB << direct(5), inverted(4);  // (B_i, B_j)
  Matrix6 S = Jzi * i.sigma_z * Jzi.transpose() + Jzj * j.sigma_z * Jzj.transpose() +
              JA * SA * JA.transpose() + JB * SB * JB.transpose();
  Matrix6 Jl;
  const Vector6 e = SE3::Log(L, &Jl);  // Jr^-1(e): e's change for a right perturbation of L
  S = Jl * S * Jl.transpose();
  const Eigen::LDLT<Matrix6> ldlt(S);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
    return std::numeric_limits<double>::infinity();
  }
  return e.dot(ldlt.solve(e));
}

void OdometryCheckOptions::validate() const {
  if (!(threshold > 0.0) || !std::isfinite(threshold)) {
    throw InvalidInputError("odometry check: threshold must be positive and finite, got " +
                            std::to_string(threshold));
  }
  if (min_support < 1) {
    throw InvalidInputError("odometry check: min_support must be at least 1, got " +
                            std::to_string(min_support));
  }
}

namespace {

Matrix6 Covariance(const RelativePoseFactor& f) {
  const Eigen::LDLT<Matrix6> ldlt(f.information());
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
    throw InvalidInputError("odometry chain: the factor " + ToString(f.a()) + " - " +
                            ToString(f.b()) +
                            " has an information matrix that is not positive "
                            "definite");
  }
  return ldlt.solve(Matrix6::Identity());
}

}  // namespace

OdometryChain::OdometryChain(const PoseGraph& graph, bool uncertainty,
                             const std::vector<bool>& not_odometry) {
  const std::vector<RelativePoseFactor>& factors = graph.factors();
  if (!not_odometry.empty() && not_odometry.size() != factors.size()) {
    throw InvalidInputError("odometry chain: " + std::to_string(not_odometry.size()) +
                            " flags of factors that are not odometry for " +
                            std::to_string(factors.size()) + " factors");
  }
  std::map<std::uint64_t, const RelativePoseFactor*> step;  // index -> factor to index + 1
  for (const Key& k : graph.keys()) {
    if (!k.isPose()) continue;
    if (robot_ >= 0 && k.robot != robot_) {
      throw InvalidInputError("odometry chain: the graph's poses belong to more than one robot (" +
                              std::to_string(robot_) + " and " + std::to_string(k.robot) + ")");
    }
    robot_ = k.robot;
    nodes_.emplace(k.index, Node{});
  }
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const RelativePoseFactor& f = factors[i];
    if (!f.a().isPose() || !f.b().isPose() || (!not_odometry.empty() && not_odometry[i])) continue;
    const std::uint64_t lo = std::min(f.a().index, f.b().index);
    if (std::max(f.a().index, f.b().index) == lo + 1) step.emplace(lo, &f);
  }
  int stretch = -1;
  const Node* before = nullptr;
  std::uint64_t last = 0;
  for (auto& [index, node] : nodes_) {
    const auto s = before && last + 1 == index ? step.find(last) : step.end();
    if (s == step.end()) {  // a new stretch starts here, at the identity
      node.stretch = ++stretch;
    } else {
      const RelativePoseFactor& f = *s->second;
      const bool forward = f.a().index == last;
      node.stretch = before->stretch;
      node.T = before->T * (forward ? f.measured() : f.measured().inverse());
      node.G = node.T.inverse().Adjoint();
      node.S = before->S;
      if (uncertainty) {
        Matrix6 sigma = Covariance(f);
        if (!forward) {  // the inverse's: Ad(z) Sigma Ad(z)^T
          const Matrix6 Az = f.measured().Adjoint();
          sigma = Az * sigma * Az.transpose();
        }
        const Matrix6 At = node.T.Adjoint();
        node.S += At * sigma * At.transpose();
      }
    }
    before = &node;
    last = index;
  }
}

bool OdometryChain::has(const Key& k) const {
  return k.isPose() && k.robot == robot_ && nodes_.count(k.index) > 0;
}

int OdometryChain::stretch(const Key& k) const { return node(k).stretch; }

const SE3& OdometryChain::pose(const Key& k) const { return node(k).T; }

Matrix12 OdometryChain::joint(const Key& p, const Key& q) const {
  const Node& a = node(p);
  const Node& b = node(q);
  if (a.stretch != b.stretch) {
    throw InvalidInputError("odometry chain: " + ToString(p) + " and " + ToString(q) +
                            " are on two stretches of odometry: no joint covariance");
  }
  const Matrix6& S = p.index <= q.index ? a.S : b.S;
  Matrix12 out;
  out.topLeftCorner<6, 6>() = a.G * a.S * a.G.transpose();
  out.bottomRightCorner<6, 6>() = b.G * b.S * b.G.transpose();
  out.topRightCorner<6, 6>() = a.G * S * b.G.transpose();
  out.bottomLeftCorner<6, 6>() = out.topRightCorner<6, 6>().transpose();
  return out;
}

const OdometryChain::Node& OdometryChain::node(const Key& k) const {
  const auto it = k.isPose() && k.robot == robot_ ? nodes_.find(k.index) : nodes_.end();
  if (it == nodes_.end()) {
    throw InvalidInputError("odometry chain: no pose " + ToString(k));
  }
  return it->second;
}

namespace {

void CheckInputs(const PoseGraph& graph, const std::vector<bool>& robust,
                 const OdometryCheckOptions& options) {
  options.validate();
  if (robust.size() != graph.factors().size()) {
    throw InvalidInputError("odometry check: " + std::to_string(robust.size()) +
                            " robust flags for " + std::to_string(graph.factors().size()) +
                            " factors");
  }
}

}  // namespace

OdometryCheckResult CheckLoopClosuresByOdometry(const PoseGraph& graph,
                                                const std::vector<bool>& robust,
                                                const OdometryCheckOptions& options) {
  CheckInputs(graph, robust, options);
  const std::vector<RelativePoseFactor>& factors = graph.factors();
  const OdometryChain chain(graph, options.odometry_uncertainty, robust);
  OdometryCheckResult out;
  out.kept.assign(factors.size(), true);
  out.along_odometry.assign(factors.size(), false);
  std::vector<std::size_t> checked;
  std::vector<LoopEnd> ends;
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const RelativePoseFactor& f = factors[i];
    if (!robust[i] || !chain.has(f.a()) || !chain.has(f.b())) continue;
    checked.push_back(i);
    out.along_odometry[i] = chain.stretch(f.a()) == chain.stretch(f.b());
    const Matrix6 sigma = options.odometry_uncertainty ? Covariance(f) : Matrix6::Zero();
    ends.push_back({f.measured(), sigma, chain.pose(f.a()), chain.pose(f.b())});
  }
  const int n = static_cast<int>(checked.size());
  out.loop_closures = n;
  ConsistencyGraph g(n);
  for (int i = 0; i < n; ++i) {
    const RelativePoseFactor& fi = factors[checked[static_cast<std::size_t>(i)]];
    for (int j = i + 1; j < n; ++j) {
      const RelativePoseFactor& fj = factors[checked[static_cast<std::size_t>(j)]];
      ++out.pairs;
      if (chain.stretch(fi.a()) != chain.stretch(fj.a()) ||
          chain.stretch(fi.b()) != chain.stretch(fj.b())) {
        ++out.untestable;
        g.connect(i, j);
        continue;
      }
      const double stat =
          LoopStatistic(ends[static_cast<std::size_t>(i)], ends[static_cast<std::size_t>(j)],
                        chain.joint(fi.a(), fj.a()), chain.joint(fi.b(), fj.b()));
      if (stat <= options.threshold) g.connect(i, j);
    }
  }
  const CliqueResult best = MaximumClique(g);
  out.largest = static_cast<int>(best.nodes.size());
  out.exact = best.exact;
  if (out.largest < options.min_support) return out;  // nothing confirmed: GNC decides
  for (std::size_t i : checked) out.kept[i] = false;
  for (int v : best.nodes) out.kept[checked[static_cast<std::size_t>(v)]] = true;
  out.rejected = n - out.largest;
  return out;
}

OdometryCheckResult CheckEachRobotsLoopClosures(const PoseGraph& graph,
                                                const std::vector<bool>& robust,
                                                const OdometryCheckOptions& options) {
  CheckInputs(graph, robust, options);
  const std::vector<RelativePoseFactor>& factors = graph.factors();
  // Per robot with a loop closure to check: its own factors (indices into the graph).
  std::map<int, std::vector<std::size_t>> own;
  std::set<int> checking;
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const Key a = factors[i].a(), b = factors[i].b();
    if (a.robot != b.robot) continue;
    own[a.robot].push_back(i);
    if (robust[i] && a.isPose() && b.isPose()) checking.insert(a.robot);
  }
  OdometryCheckResult out;
  out.kept.assign(factors.size(), true);
  out.along_odometry.assign(factors.size(), false);
  for (int robot : checking) {
    const std::vector<std::size_t>& index = own.at(robot);
    PoseGraph mine;
    std::vector<bool> mine_robust;
    for (std::size_t i : index) {
      mine.add(factors[i]);
      mine_robust.push_back(robust[i]);
    }
    const OdometryCheckResult r = CheckLoopClosuresByOdometry(mine, mine_robust, options);
    for (std::size_t j = 0; j < index.size(); ++j) {
      out.kept[index[j]] = r.kept[j];
      out.along_odometry[index[j]] = r.along_odometry[j];
    }
    out.loop_closures += r.loop_closures;
    out.rejected += r.rejected;
    out.largest = std::max(out.largest, r.largest);
    out.exact = out.exact && r.exact;
    out.pairs += r.pairs;
    out.untestable += r.untestable;
  }
  return out;
}

}  // namespace moslam
