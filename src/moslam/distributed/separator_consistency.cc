#include "moslam/distributed/separator_consistency.h"

#include <Eigen/LU>
#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/graph/robot_groups.h"
#include "moslam/robust/loop_consistency.h"
#include "moslam/robust/max_clique.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/marginals.h"
#include "moslam/solver/optimizer.h"

namespace moslam {

void SeparatorConsistencyOptions::validate() const {
  if (!(threshold > 0.0)) {
    throw InvalidInputError("separator consistency: threshold must be positive");
  }
  if (min_support < 1) throw InvalidInputError("separator consistency: min_support must be >= 1");
  if (linked_min_support < 1 || linked_min_support > min_support) {
    throw InvalidInputError("separator consistency: linked_min_support must be in [1, min_support]");
  }
}

namespace {

Key AsRobot(const Key& k, int robot) { return Key{robot, k.kind, k.index}; }

}  // namespace

// The map re-keyed as robot 0 (its own first pose the gauge).
struct SeparatorCheckMap::Impl {
  PoseGraph graph;
  Values estimate;
  std::unique_ptr<Marginals> marginals;
};

SeparatorCheckMap::SeparatorCheckMap(const PoseGraph& graph, int robot,
                                     const std::vector<bool>& robust, const GncOptions& gnc,
                                     bool marginals)
    : robot_(robot), impl_(std::make_unique<Impl>()) {
  std::vector<bool> local_robust;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    if (f.a().robot == robot && f.b().robot == robot) {
      impl_->graph.add(RelativePoseFactor(AsRobot(f.a(), 0), AsRobot(f.b(), 0), f.measured(),
                                          f.information()));
      local_robust.push_back(!robust.empty() && robust[i]);
    }
  }
  if (impl_->graph.factors().empty()) return;
  OptimizerOptions options;
  options.max_iterations = 50;
  const Values start = ChordalInitialization(impl_->graph, SE3());
  if (std::find(local_robust.begin(), local_robust.end(), true) == local_robust.end()) {
    impl_->estimate = Optimize(impl_->graph, start, options).values;
    if (marginals) impl_->marginals = std::make_unique<Marginals>(impl_->graph, impl_->estimate);
  } else {
    const GncResult r = SolveGnc(impl_->graph, start, local_robust, gnc, options);
    impl_->estimate = r.values;
    if (marginals) {
      impl_->marginals = std::make_unique<Marginals>(
          WeightedGraph(impl_->graph, r.weights, gnc.min_weight), impl_->estimate);
    }
  }
}

SeparatorCheckMap::~SeparatorCheckMap() = default;

bool SeparatorCheckMap::hasAll(const std::vector<Key>& keys) const {
  for (const Key& k : keys) {
    if (k.robot != robot_ || !impl_->estimate.count(AsRobot(k, 0))) return false;
  }
  return true;
}

const SE3& SeparatorCheckMap::pose(const Key& key) const {
  if (!hasAll({key})) {
    throw InvalidInputError("separator check: robot " + std::to_string(robot_) +
                            "'s map lacks " + ToString(key));
  }
  return impl_->estimate.at(AsRobot(key, 0));
}

Message SeparatorCheckMap::estimates(const std::vector<Key>& keys) const {
  if (!hasAll(keys)) {
    throw InvalidInputError("separator check: robot " + std::to_string(robot_) +
                            "'s map lacks a variable asked for");
  }
  Message m;
  m.stage = DgsStage::kPose;
  m.sender = robot_;
  for (const Key& k : keys) m.appendPose(k, impl_->estimate.at(AsRobot(k, 0)));
  return m;
}

Eigen::MatrixXd SeparatorCheckMap::covariance(const std::vector<Key>& keys) const {
  if (!impl_->marginals) return Eigen::MatrixXd();
  if (!hasAll(keys)) {
    throw InvalidInputError("separator check: robot " + std::to_string(robot_) +
                            "'s map lacks a variable asked for");
  }
  std::vector<Key> local;
  for (const Key& k : keys) local.push_back(AsRobot(k, 0));
  return impl_->marginals->jointCovariance(local);
}

std::vector<Key> SeparatorVariables(const std::vector<RelativePoseFactor>& separators, int robot) {
  std::set<Key> keys;
  for (const RelativePoseFactor& f : separators) {
    if (f.a().robot == robot) keys.insert(f.a());
    if (f.b().robot == robot) keys.insert(f.b());
  }
  return {keys.begin(), keys.end()};
}

namespace {

// Rows and columns (6 each) of blocks p and q of a joint covariance.
Matrix12 PairBlock(const Eigen::MatrixXd& S, int p, int q) {
  Matrix12 out;
  const int idx[2] = {p, q};
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) {
      out.block<6, 6>(6 * r, 6 * c) = S.block<6, 6>(6 * idx[r], 6 * idx[c]);
    }
  }
  return out;
}

// Robot a's view of the separators of a pair: each as a loop end (its measurement from A to B
// and both maps' estimates), the index of its variables among each robot's separator
// variables, and the two maps' joint covariances of those (zero: the maps taken as exact).
struct PairView {
  std::vector<LoopEnd> ends;
  std::vector<int> ia, ib;
  Eigen::MatrixXd SA, SB;
};

PairView ViewPair(const std::vector<RelativePoseFactor>& separators, const SeparatorCheckMap& a_map,
                  const Message& b_estimates, const Eigen::MatrixXd& b_covariance,
                  const SeparatorConsistencyOptions& options) {
  const int ra = a_map.robot(), rb = b_estimates.sender;
  const std::vector<Key> ka = SeparatorVariables(separators, ra);
  const std::vector<Key> kb = SeparatorVariables(separators, rb);
  if (b_estimates.keys != kb || b_estimates.stage != DgsStage::kPose) {
    throw InvalidInputError("separator check: robot " + std::to_string(rb) + " sent robot " +
                            std::to_string(ra) + " estimates of " +
                            std::to_string(b_estimates.keys.size()) + " variables for the " +
                            std::to_string(kb.size()) +
                            " its separators with it touch (their subgraphs disagree)");
  }
  PairView view;
  const auto na = 6 * static_cast<Eigen::Index>(ka.size());
  const auto nb = 6 * static_cast<Eigen::Index>(kb.size());
  view.SA = Eigen::MatrixXd::Zero(na, na);
  view.SB = Eigen::MatrixXd::Zero(nb, nb);
  if (options.map_uncertainty) {
    if (b_covariance.rows() != nb || b_covariance.cols() != nb) {
      throw InvalidInputError("separator check: robot " + std::to_string(rb) +
                              " sent a covariance of dimension " +
                              std::to_string(b_covariance.rows()) + " for " +
                              std::to_string(kb.size()) + " variables");
    }
    view.SB = b_covariance;
    view.SA = a_map.covariance(ka);
  }
  std::map<Key, int> a_index, b_index;
  for (std::size_t e = 0; e < ka.size(); ++e) a_index[ka[e]] = static_cast<int>(e);
  std::vector<SE3> b_poses;
  for (std::size_t e = 0; e < kb.size(); ++e) {
    b_index[kb[e]] = static_cast<int>(e);
    b_poses.push_back(b_estimates.pose(e));
  }
  for (const RelativePoseFactor& f : separators) {
    const bool a_first = f.a().robot == ra;
    const Key key_a = a_first ? f.a() : f.b(), key_b = a_first ? f.b() : f.a();
    view.ia.push_back(a_index.at(key_a));
    view.ib.push_back(b_index.at(key_b));
    // The covariance of z (from A to B): the factor's, or when the factor runs from B to A
    // that of its inverse: (z Exp(d))^-1 = z^-1 Exp(-Ad(z) d), so Ad(z) Sigma Ad(z)^T.
    const Matrix6 sigma = f.information().inverse();
    const Matrix6 Ad = f.measured().Adjoint();
    view.ends.push_back({a_first ? f.measured() : f.measured().inverse(),
                         a_first ? sigma : Matrix6(Ad * sigma * Ad.transpose()), a_map.pose(key_a),
                         b_poses[static_cast<std::size_t>(view.ib.back())]});
  }
  return view;
}

// The pairwise consistency graph: separators i and j joined when their loop statistic is within
// the threshold. Object separators pairing one landmark with two different ones exclude each
// other (options.one_to_one_objects).
ConsistencyGraph PairwiseConsistency(const std::vector<RelativePoseFactor>& separators,
                                     const PairView& view,
                                     const SeparatorConsistencyOptions& options) {
  auto exclusive = [&](std::size_t i, std::size_t j) {
    const RelativePoseFactor& fi = separators[i];
    const RelativePoseFactor& fj = separators[j];
    if (!options.one_to_one_objects || !fi.a().isObject() || !fi.b().isObject() ||
        !fj.a().isObject() || !fj.b().isObject()) {
      return false;
    }
    return (view.ia[i] == view.ia[j]) != (view.ib[i] == view.ib[j]);
  };
  ConsistencyGraph g(static_cast<int>(separators.size()));
  for (std::size_t i = 0; i < separators.size(); ++i) {
    for (std::size_t j = i + 1; j < separators.size(); ++j) {
      if (exclusive(i, j)) continue;
      const double stat =
          LoopStatistic(view.ends[i], view.ends[j], PairBlock(view.SA, view.ia[i], view.ia[j]),
                        PairBlock(view.SB, view.ib[i], view.ib[j]));
      if (stat <= options.threshold) g.connect(static_cast<int>(i), static_cast<int>(j));
    }
  }
  return g;
}

// Every vertex of some clique of `largest` vertices: one with largest - 1 neighbours that agree
// pairwise.
std::vector<std::size_t> MembersOfLargestCliques(const ConsistencyGraph& g, int largest) {
  std::vector<std::size_t> out;
  const int n = g.size();
  for (int v = 0; v < n; ++v) {
    if (g.degree(v) < largest - 1) continue;
    std::vector<bool> neighbours(static_cast<std::size_t>(n), false);
    for (int u = 0; u < n; ++u) neighbours[static_cast<std::size_t>(u)] = g.adjacent(u, v);
    if (largest == 1 ||
        static_cast<int>(MaximumClique(g, neighbours).nodes.size()) >= largest - 1) {
      out.push_back(static_cast<std::size_t>(v));
    }
  }
  return out;
}

// ConsistentSeparators on the separators in the order given: among tied largest sets, the
// maximum clique search returns the first it finds.
PairConsistency ConsistentInOrder(const std::vector<RelativePoseFactor>& separators,
                                  const SeparatorCheckMap& a_map, const Message& b_estimates,
                                  const Eigen::MatrixXd& b_covariance,
                                  const SeparatorConsistencyOptions& options) {
  const PairView view = ViewPair(separators, a_map, b_estimates, b_covariance, options);
  const ConsistencyGraph g = PairwiseConsistency(separators, view, options);
  PairConsistency out;
  const std::vector<int> best = MaximumClique(g).nodes;
  out.largest = static_cast<int>(best.size());
  if (out.largest >= options.min_support || out.largest < options.linked_min_support) {
    out.kept.assign(best.begin(), best.end());
  } else {
    out.kept = MembersOfLargestCliques(g, out.largest);  // ties of small sets: all to GNC
  }
  out.support.assign(separators.size(), 0);
  std::vector<bool> others(separators.size(), true);
  for (std::size_t m : out.kept) others[m] = false;
  for (std::size_t i = 0; i < separators.size(); ++i) {
    for (std::size_t m : out.kept) {
      if (m != i && g.adjacent(static_cast<int>(i), static_cast<int>(m))) ++out.support[i];
    }
  }
  for (int v : MaximumClique(g, others).nodes) out.runner_up.push_back(static_cast<std::size_t>(v));
  return out;
}

}  // namespace

PairConsistency ConsistentSeparators(const std::vector<RelativePoseFactor>& separators,
                                     const SeparatorCheckMap& a_map, const Message& b_estimates,
                                     const Eigen::MatrixXd& b_covariance,
                                     const SeparatorConsistencyOptions& options) {
  // Checked in canonical order (pose_graph.h), so that a tie is broken by the separators
  // themselves and not by how a file lists them: two robots, or a robot and the in-process
  // driver, that hold a pair's separators in different orders keep the same ones.
  const std::vector<std::size_t> order = CanonicalOrder(separators);
  std::vector<RelativePoseFactor> canonical;
  canonical.reserve(separators.size());
  for (std::size_t i : order) canonical.push_back(separators[i]);
  const PairConsistency c = ConsistentInOrder(canonical, a_map, b_estimates, b_covariance, options);
  auto positions = [&](const std::vector<std::size_t>& in_canonical) {
    std::vector<std::size_t> out;
    for (std::size_t p : in_canonical) out.push_back(order[p]);
    std::sort(out.begin(), out.end());
    return out;
  };
  PairConsistency out;
  out.largest = c.largest;
  out.kept = positions(c.kept);
  out.runner_up = positions(c.runner_up);
  out.support.assign(separators.size(), 0);
  for (std::size_t p = 0; p < order.size(); ++p) out.support[order[p]] = c.support[p];
  return out;
}

namespace {

using RobotPair = std::pair<int, int>;

// The robust separators (every one when `robust` is empty) of each robot pair (lower robot
// first), as factor indices.
std::map<RobotPair, std::vector<std::size_t>> SeparatorsByPair(
    const std::vector<RelativePoseFactor>& factors, const std::vector<bool>& robust) {
  std::map<RobotPair, std::vector<std::size_t>> pairs;
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const int a = factors[i].a().robot, b = factors[i].b().robot;
    if (a != b && (robust.empty() || robust[i])) {
      pairs[{std::min(a, b), std::max(a, b)}].push_back(i);
    }
  }
  return pairs;
}

// The check of every robot pair in one process, as the robots run it (robot_program.h): the
// higher robot's map sent to the lower one as encoded messages (counted), each pair's largest
// consistent set, then the pairs too small to confirm themselves judged by the groups the
// confirmed pairs link.
class CentralizedCheck {
 public:
  CentralizedCheck(const PoseGraph& graph, const SeparatorConsistencyOptions& options,
                   const std::vector<bool>& robust, const GncOptions& local)
      : graph_(graph), options_(options), robust_(robust), local_(local) {
    const std::size_t n = graph.factors().size();
    out_.kept.assign(n, true);
    out_.support.assign(n, -1);
    out_.runner_up.assign(n, false);
  }

  SeparatorConsistencyResult run() && {
    const auto pairs = SeparatorsByPair(graph_.factors(), robust_);
    for (const auto& [pair, list] : pairs) out_.separators += static_cast<int>(list.size());
    for (const auto& [pair, list] : pairs) checkPair(pair, list);
    std::vector<int> robots;
    for (const auto& [pair, list] : pairs) robots.insert(robots.end(), {pair.first, pair.second});
    judgeUnconfirmed(robots);
    return std::move(out_);
  }

 private:
  // A pair too small to confirm itself, judged once every pair is known.
  struct Unconfirmed {
    RobotPair pair;
    std::vector<std::size_t> list, kept;  // its separators; what it keeps if left to GNC
    std::vector<int> support;             // per separator: the members of kept it agrees with
    std::vector<std::size_t> runner_up;   // the runner-up set (PairConsistency::runner_up)
    int largest = 0;                      // its largest consistent set
  };

  const SeparatorCheckMap& mapOf(int robot) {
    auto it = maps_.find(robot);
    if (it == maps_.end()) {
      it = maps_
               .emplace(robot, std::make_unique<SeparatorCheckMap>(graph_, robot, robust_, local_,
                                                                   options_.map_uncertainty))
               .first;
    }
    return *it->second;
  }

  void checkPair(const RobotPair& pair, const std::vector<std::size_t>& list) {
    ++out_.robot_pairs;
    const auto [ra, rb] = pair;
    std::vector<RelativePoseFactor> separators;
    for (std::size_t i : list) separators.push_back(graph_.factors()[i]);
    const SeparatorCheckMap& A = mapOf(ra);
    const SeparatorCheckMap& B = mapOf(rb);
    const std::vector<Key> kb = SeparatorVariables(separators, rb);
    // A variable the robot's own factors do not reach: nothing to check with.
    if (!A.hasAll(SeparatorVariables(separators, ra)) || !B.hasAll(kb)) return;
    // What robot b sends robot a: the local estimates of its separator variables and their joint
    // covariance in its map.
    const std::vector<std::uint8_t> wire = EncodeMessage(B.estimates(kb));
    out_.bytes += static_cast<std::int64_t>(wire.size());
    ++out_.messages;
    Eigen::MatrixXd SB;
    if (options_.map_uncertainty) {
      CovarianceMessage cm;
      cm.sender = rb;
      cm.receiver = ra;
      cm.covariance = B.covariance(kb);
      const std::vector<std::uint8_t> wire_cov = EncodeCovarianceMessage(cm);
      out_.bytes += static_cast<std::int64_t>(wire_cov.size());
      ++out_.messages;
      SB = DecodeCovarianceMessage(wire_cov).covariance;
    }
    const PairConsistency check =
        ConsistentSeparators(separators, A, DecodeMessage(wire), SB, options_);
    std::vector<std::size_t> kept;
    for (std::size_t p : check.kept) kept.push_back(list[p]);
    if (check.largest >= options_.min_support) {
      keepOnly(list, kept);
      setSupport(list, check.support, check.runner_up, true);
      confirmed_.push_back(pair);
    } else {
      unconfirmed_.push_back({pair, list, kept, check.support, check.runner_up, check.largest});
    }
  }

  // The pairs too small to confirm themselves keep their largest sets when the confirmed pairs
  // link their two robots (and the set holds linked_min_support), else none.
  void judgeUnconfirmed(const std::vector<int>& robots) {
    std::map<int, std::size_t> group_of;
    const std::vector<std::vector<int>> groups = ConnectedRobots(robots, confirmed_);
    for (std::size_t g = 0; g < groups.size(); ++g) {
      for (int r : groups[g]) group_of[r] = g;
    }
    for (const Unconfirmed& u : unconfirmed_) {
      if (group_of.at(u.pair.first) == group_of.at(u.pair.second) &&
          u.largest >= options_.linked_min_support) {
        ++out_.robot_pairs_deferred;
        out_.deferred += static_cast<int>(u.kept.size());
        keepOnly(u.list, u.kept);
        setSupport(u.list, u.support, u.runner_up, true);
      } else {
        ++out_.robot_pairs_rejected;
        keepOnly(u.list, {});
        setSupport(u.list, u.support, u.runner_up, false);
      }
    }
  }

  // Leaves out the separators of `list` not in `keep`.
  void keepOnly(const std::vector<std::size_t>& list, const std::vector<std::size_t>& keep) {
    for (std::size_t i : list) {
      if (std::find(keep.begin(), keep.end(), i) != keep.end()) continue;
      out_.kept[i] = false;
      ++out_.rejected;
    }
  }

  // The support of a pair's separators: against what it keeps if it is kept, else none. And of
  // a kept pair, its runner-up set.
  void setSupport(const std::vector<std::size_t>& list, const std::vector<int>& support,
                  const std::vector<std::size_t>& runner_up, bool kept) {
    for (std::size_t p = 0; p < list.size(); ++p) out_.support[list[p]] = kept ? support[p] : 0;
    if (!kept) return;
    for (std::size_t p : runner_up) out_.runner_up[list[p]] = true;
  }

  const PoseGraph& graph_;
  const SeparatorConsistencyOptions& options_;
  const std::vector<bool>& robust_;
  const GncOptions& local_;
  SeparatorConsistencyResult out_;
  std::map<int, std::unique_ptr<SeparatorCheckMap>> maps_;  // built when a pair needs them
  std::vector<RobotPair> confirmed_;
  std::vector<Unconfirmed> unconfirmed_;
};

}  // namespace

SeparatorConsistencyResult CheckSeparatorConsistency(const PoseGraph& graph,
                                                     const SeparatorConsistencyOptions& options,
                                                     const std::vector<bool>& robust,
                                                     const GncOptions& local) {
  options.validate();
  local.validate();
  if (!robust.empty() && robust.size() != graph.factors().size()) {
    throw InvalidInputError("separator consistency: " + std::to_string(robust.size()) +
                            " robust flags for " + std::to_string(graph.factors().size()) +
                            " factors");
  }
  return CentralizedCheck(graph, options, robust, local).run();
}

namespace {

bool PairsObjectsOfTwoRobots(const RelativePoseFactor& f) {
  return f.a().isObject() && f.b().isObject() && f.a().robot != f.b().robot;
}

void CheckMembers(const char* what, std::size_t n, const std::vector<std::size_t>& members,
                  std::size_t r2_size, std::size_t weights_size) {
  for (std::size_t i : members) {
    if (i >= n || i >= r2_size || i >= weights_size) {
      throw InvalidInputError(std::string(what) + ": member " + std::to_string(i) +
                              " out of range (" + std::to_string(n) + " factors, " +
                              std::to_string(r2_size) + " residuals, " +
                              std::to_string(weights_size) + " weights)");
    }
  }
}

}  // namespace

int KeepOneToOne(const std::vector<RelativePoseFactor>& factors,
                 const std::vector<std::size_t>& members, const std::vector<double>& r2,
                 std::vector<double>* weights) {
  CheckMembers("KeepOneToOne", factors.size(), members, r2.size(), weights->size());
  std::vector<std::pair<double, std::size_t>> order;
  for (std::size_t i : members) {
    if ((*weights)[i] >= 0.5 && PairsObjectsOfTwoRobots(factors[i])) order.emplace_back(r2[i], i);
  }
  std::sort(order.begin(), order.end());
  // (landmark, other robot) -> the landmark of that robot it is paired with.
  std::map<std::pair<Key, int>, Key> partner;
  int dropped = 0;
  for (const auto& [e, i] : order) {
    const Key a = factors[i].a(), b = factors[i].b();
    const auto pa = partner.find({a, b.robot});
    const auto pb = partner.find({b, a.robot});
    if ((pa != partner.end() && pa->second != b) || (pb != partner.end() && pb->second != a)) {
      (*weights)[i] = 0.0;
      ++dropped;
      continue;
    }
    partner.emplace(std::pair{a, b.robot}, b);
    partner.emplace(std::pair{b, a.robot}, a);
  }
  return dropped;
}

bool BreaksOneToOne(const std::vector<RelativePoseFactor>& factors,
                    const std::vector<std::size_t>& members, const std::vector<double>& weights,
                    std::size_t i) {
  CheckMembers("BreaksOneToOne", factors.size(), members, factors.size(), weights.size());
  if (i >= factors.size()) {
    throw InvalidInputError("BreaksOneToOne: factor " + std::to_string(i) + " of " +
                            std::to_string(factors.size()));
  }
  const RelativePoseFactor& f = factors[i];
  if (!PairsObjectsOfTwoRobots(f)) return false;
  for (std::size_t j : members) {
    const RelativePoseFactor& g = factors[j];
    if (j == i || weights[j] < 0.5 || !PairsObjectsOfTwoRobots(g)) continue;
    for (const auto& [mine, other] : {std::pair{f.a(), f.b()}, std::pair{f.b(), f.a()}}) {
      if (g.a() == mine && g.b().robot == other.robot && g.b() != other) return true;
      if (g.b() == mine && g.a().robot == other.robot && g.a() != other) return true;
    }
  }
  return false;
}

}  // namespace moslam
