#include "moslam/distributed/robust_dgs.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/robust_program.h"
#include "moslam/robust/loop_consistency.h"

namespace moslam {

void RobustDgsOptions::validate() const {
  dgs.validate();
  gnc.validate();
  if (!(consistency.threshold >= 0.0)) {
    throw InvalidInputError("RobustDgsOptions: consistency.threshold must be >= 0");
  }
  if (retest_group_solves < 1) {
    throw InvalidInputError("RobustDgsOptions: retest_group_solves must be >= 1");
  }
  if (consistency.min_support < 1) {
    throw InvalidInputError("RobustDgsOptions: consistency.min_support must be >= 1");
  }
}

namespace {

// mask[i] for each i of index, in order.
std::vector<bool> Select(const std::vector<bool>& mask, const std::vector<std::size_t>& index) {
  std::vector<bool> out;
  for (std::size_t i : index) out.push_back(mask[i]);
  return out;
}

// `part`, a check of the subgraph made of the graph's factors `index` (SubGraph), as a check of
// the graph's n factors: those left out of the subgraph kept, with no support and in no runner-up
// set.
SeparatorConsistencyResult OnTheWholeGraph(const SeparatorConsistencyResult& part,
                                           const std::vector<std::size_t>& index, std::size_t n) {
  SeparatorConsistencyResult out = part;
  out.kept.assign(n, true);
  out.support.assign(n, -1);
  out.runner_up.assign(n, false);
  for (std::size_t j = 0; j < index.size(); ++j) {
    out.kept[index[j]] = part.kept[j];
    out.support[index[j]] = part.support[j];
    out.runner_up[index[j]] = part.runner_up[j];
  }
  return out;
}

}  // namespace

SeparatorConsistencyResult CheckSeparators(const PoseGraph& graph,
                                           const RobustDgsOptions& options,
                                           const std::vector<bool>& robust) {
  SeparatorConsistencyOptions c = options.consistency;
  if (c.threshold == 0.0) c.threshold = options.gnc.threshold2();
  std::set<int> robots;
  for (const Key& k : graph.keys()) {
    if (k.isPose()) robots.insert(k.robot);
  }
  OdometryCheckOptions o;
  o.threshold = c.threshold;
  o.min_support = c.min_support;
  o.odometry_uncertainty = c.map_uncertainty;
  if (robots.size() != 1 || robust.empty()) {
    if (robust.empty()) return CheckSeparatorConsistency(graph, c, robust, options.gnc);
    // Each robot's own loop closures first, through its own odometry (none in object SLAM, whose
    // robust factors touch objects; g2o folders mark only their separators).
    const OdometryCheckResult own = CheckEachRobotsLoopClosures(graph, robust, o);
    // The robots' maps leave out their own loop closures along their odometry (the loops of PCM
    // go through odometry alone): a wrong one in a map, even one its check confirmed (a robot
    // whose own are few and all wrong), bends it and turns right separators away (INTEL split
    // among 4 robots, docs/robustness-log.md); the maps' covariances carry the drift instead.
    std::vector<bool> in_maps(graph.factors().size());
    for (std::size_t i = 0; i < in_maps.size(); ++i) in_maps[i] = own.inMap(i);
    std::vector<std::size_t> index;
    const PoseGraph trusted = SubGraph(graph, in_maps, &index);
    SeparatorConsistencyResult out =
        OnTheWholeGraph(CheckSeparatorConsistency(trusted, c, Select(robust, index), options.gnc),
                        index, graph.factors().size());
    for (std::size_t i = 0; i < out.kept.size(); ++i) out.kept[i] = out.kept[i] && own.kept[i];
    out.separators += own.loop_closures;
    out.rejected += own.rejected;
    return out;
  }
  // One robot: no separator; its loop closures are checked through its odometry instead.
  const OdometryCheckResult odometry = CheckLoopClosuresByOdometry(graph, robust, o);
  SeparatorConsistencyResult out;
  out.kept = odometry.kept;
  out.separators = odometry.loop_closures;
  out.rejected = odometry.rejected;
  out.support.assign(graph.factors().size(), -1);  // nothing for the re-tests of robot pairs
  out.runner_up.assign(graph.factors().size(), false);
  return out;
}

namespace {

// The robust factors' positions.
std::vector<std::size_t> RobustMembers(const std::vector<bool>& robust) {
  std::vector<std::size_t> members;
  for (std::size_t i = 0; i < robust.size(); ++i) {
    if (robust[i]) members.push_back(i);
  }
  return members;
}

// Robust factors of weight < 0.5 whose squared residual at `values` is at most c2 get weight 1;
// with one_to_one, KeepOneToOne then settles the object pairs (RobustDgsOptions::
// one_to_one_after_gnc). Returns how many went from below 0.5 to 1.
int Readmit(const PoseGraph& graph, const Values& values, const std::vector<bool>& robust,
            double c2, bool one_to_one, std::vector<double>* weights) {
  const std::vector<double> r2 = SquaredResiduals(graph, values);
  const std::vector<double> before = *weights;
  for (std::size_t i = 0; i < r2.size(); ++i) {
    if (robust[i] && (*weights)[i] < 0.5 && r2[i] <= c2) (*weights)[i] = 1.0;
  }
  if (one_to_one) KeepOneToOne(graph.factors(), RobustMembers(robust), r2, weights);
  int count = 0;
  for (std::size_t i = 0; i < r2.size(); ++i) {
    if (before[i] < 0.5 && (*weights)[i] >= 0.5) ++count;
  }
  return count;
}

// The bytes of what the higher robot of each pair sends the lower (one message per pair with a
// variable to send; robust_program.cc sends the same): its estimates in `values` of its variables
// in the separators i with select(i, its variable).
template <class Select>
std::int64_t LeftOutEstimateBytes(const PoseGraph& graph, const Values& values,
                                  const Select& select) {
  std::map<std::pair<int, int>, std::set<Key>> sent;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    const int a = f.a().robot, b = f.b().robot;
    const Key& higher = a > b ? f.a() : f.b();
    if (a != b && select(i, higher)) sent[{std::min(a, b), std::max(a, b)}].insert(higher);
  }
  std::int64_t bytes = 0;
  for (const auto& [pair, keys] : sent) {
    Message m;
    m.stage = DgsStage::kPose;
    m.sender = pair.second;
    for (const Key& k : keys) m.appendPose(k, values.at(k));
    bytes += static_cast<std::int64_t>(EncodeMessage(m).size());
  }
  return bytes;
}

// The robots the graph's variables belong to, increasing.
std::vector<int> RobotsOf(const PoseGraph& graph) {
  std::set<int> robots;
  for (const Key& k : graph.keys()) robots.insert(k.robot);
  return {robots.begin(), robots.end()};
}

// The variables the factors of weight >= 0.5 touch.
std::set<Key> InlierKeys(const PoseGraph& graph, const std::vector<double>& weights) {
  std::set<Key> held;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    if (weights[i] < 0.5) continue;
    held.insert(graph.factors()[i].a());
    held.insert(graph.factors()[i].b());
  }
  return held;
}

// The check's rejects to re-test (RobustDgsOptions::retest_left_out) at the inliers' optimum
// `values`: robust separators left out by the check, still rejected, passing the pairwise test
// with at least min_support kept separators of their pair, both variables held by inliers (a
// variable only the candidate held would take any value: no cost to raise). By r^T Omega r at
// `values`, then factor order.
std::vector<std::size_t> RetestCandidates(const PoseGraph& graph,
                                          const SeparatorConsistencyResult& check,
                                          const std::vector<bool>& robust,
                                          const std::vector<double>& weights, const Values& values,
                                          int min_support) {
  const std::set<Key> held = InlierKeys(graph, weights);
  const std::vector<double> r2 = SquaredResiduals(graph, values);
  std::vector<std::pair<double, std::size_t>> order;
  if (check.support.size() != graph.factors().size()) return {};  // no check ran
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    if (robust[i] && !check.kept[i] && weights[i] < 0.5 && check.support[i] >= min_support &&
        held.count(f.a()) && held.count(f.b())) {
      order.emplace_back(r2[i], i);
    }
  }
  std::sort(order.begin(), order.end());
  std::vector<std::size_t> out;
  for (const auto& [e, i] : order) out.push_back(i);
  return out;
}

// Re-tests the candidates in turn from the inliers' optimum `values` (F0 its cost): the inliers
// and candidate i solved by solve(graph, start, i) from the current estimate, the candidate kept
// (weight 1, the new optimum the estimate) when 2 (F1 - F0) <= c2, F1 as cost(graph, estimate)
// reports it. With one_to_one (RobustDgsOptions::one_to_one_after_gnc), a candidate that would
// pair a landmark with a second landmark of a robot beside the factors `robust` marks of weight
// >= 0.5 is not tried. Returns how many came back; *tried: how many were tried.
template <class Solve, class Cost>
int Retest(const PoseGraph& graph, const std::vector<std::size_t>& candidates, double c2,
           const std::vector<bool>& robust, bool one_to_one, std::vector<double>* weights,
           Values* values, const Solve& solve, const Cost& cost, int* tried = nullptr) {
  int back = 0;
  double f0 = cost(SubGraph(graph, Inliers(*weights)), *values);
  const std::vector<std::size_t> members = RobustMembers(robust);
  for (std::size_t i : candidates) {
    if (one_to_one && BreaksOneToOne(graph.factors(), members, *weights, i)) continue;
    if (tried) ++*tried;
    std::vector<double> trial = *weights;
    trial[i] = 1.0;
    const PoseGraph g = SubGraph(graph, Inliers(trial));
    Values x = *values;
    try {
      for (const auto& [k, v] : solve(g, *values, i)) x[k] = v;
    } catch (const UnderdeterminedError&) {
      continue;
    }
    const double f1 = cost(g, x);
    if (std::isfinite(f1) && 2.0 * (f1 - f0) <= c2) {
      *weights = std::move(trial);
      *values = std::move(x);
      f0 = f1;
      ++back;
    }
  }
  return back;
}

// The groups of the check's rejects to re-test together (RobustDgsOptions::retest_groups), taken
// before the one-by-one re-test: per robot pair, in increasing (lower id, higher id), the
// separators of its runner-up set (SeparatorConsistencyResult::runner_up) still rejected whose
// two variables inliers hold.
std::vector<std::vector<std::size_t>> RetestGroups(const PoseGraph& graph,
                                                   const SeparatorConsistencyResult& check,
                                                   const std::vector<bool>& robust,
                                                   const std::vector<double>& weights) {
  if (check.runner_up.size() != graph.factors().size()) return {};  // no check ran
  const std::set<Key> held = InlierKeys(graph, weights);
  std::map<std::pair<int, int>, std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    const int a = f.a().robot, b = f.b().robot;
    if (a != b && robust[i] && !check.kept[i] && check.runner_up[i] && weights[i] < 0.5 &&
        held.count(f.a()) && held.count(f.b())) {
      groups[{std::min(a, b), std::max(a, b)}].push_back(i);
    }
  }
  std::vector<std::vector<std::size_t>> out;
  for (auto& [pair, members] : groups) out.push_back(std::move(members));
  return out;
}

// Of a group, the members still rejected (weight < 0.5); none when fewer than
// GroupMinimum(min_support) are left.
std::vector<std::size_t> StillRejected(const std::vector<std::size_t>& group,
                                       const std::vector<double>& weights, int min_support) {
  std::vector<std::size_t> out;
  for (std::size_t i : group) {
    if (weights[i] < 0.5) out.push_back(i);
  }
  if (out.size() < GroupMinimum(min_support)) out.clear();
  return out;
}

// The truncated least-squares cost of `values`: per factor r^T Omega r / 2, a robust one's at most
// c2 / 2, each robot's share (the factors it owns) reduced by total(shares).
template <class Total>
double TruncatedCost(const PoseGraph& graph, const std::vector<bool>& robust, const Values& values,
                     double c2, const Total& total) {
  std::map<int, double> share;
  for (const Key& k : graph.keys()) share[k.robot] = 0.0;
  const std::vector<double> r2 = SquaredResiduals(graph, values);
  for (std::size_t i = 0; i < r2.size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    share[std::min(f.a().robot, f.b().robot)] += 0.5 * (robust[i] ? std::min(r2[i], c2) : r2[i]);
  }
  return total(share);
}

// The group re-test (RobustDgsOptions::retest_groups) of `group` from the current weights and
// estimate: the factors it may use are all but the check's other rejects still left out; the
// group's separators join the inliers (weight 1, every other robust factor 1 if an inlier, else
// 0), the weighted graph of those factors (WeightedGraph: min_weight for weight 0) is solved by
// solve(graph, start, round), and the robust factors' weights become 1 where r^T Omega r <= c2
// at the result, 0 beyond, until no weight changes (changed(counts per robot, round): the
// team's count) or after max_solves. It is kept (those weights, that estimate) when the
// truncated cost of those factors falls (truncated(graph, robust, values)). Returns whether it
// was.
template <class Solve, class Changed, class Truncated>
bool RetestGroup(const PoseGraph& graph, const std::vector<bool>& robust,
                 const std::vector<bool>& left_out, const std::vector<std::size_t>& group,
                 const GncOptions& gnc, int max_solves, bool one_to_one,
                 std::vector<double>* weights, Values* values, const Solve& solve,
                 const Changed& changed, const Truncated& truncated) {
  std::vector<bool> usable(graph.factors().size());
  for (std::size_t i = 0; i < usable.size(); ++i) usable[i] = !left_out[i];
  for (std::size_t i : group) usable[i] = true;
  std::vector<std::size_t> index;
  const PoseGraph sub = SubGraph(graph, usable, &index);
  std::vector<double> w(index.size());
  for (std::size_t j = 0; j < index.size(); ++j) {
    w[j] = !robust[index[j]] || (*weights)[index[j]] >= 0.5 ? 1.0 : 0.0;
  }
  for (std::size_t i : group) {
    w[static_cast<std::size_t>(std::lower_bound(index.begin(), index.end(), i) - index.begin())] =
        1.0;
  }
  std::vector<std::size_t> sub_members;
  for (std::size_t j = 0; j < index.size(); ++j) {
    if (robust[index[j]]) sub_members.push_back(j);
  }
  Values x = *values;
  const double c2 = gnc.threshold2();
  for (int k = 0; k < max_solves; ++k) {
    try {
      for (const auto& [key, v] : solve(WeightedGraph(sub, w, gnc.min_weight), x, k)) x[key] = v;
    } catch (const UnderdeterminedError&) {
      return false;
    }
    const std::vector<double> r2 = SquaredResiduals(sub, x);
    const std::vector<double> previous = w;
    for (std::size_t j = 0; j < index.size(); ++j) {
      if (robust[index[j]]) w[j] = r2[j] <= c2 ? 1.0 : 0.0;
    }
    if (one_to_one) KeepOneToOne(sub.factors(), sub_members, r2, &w);
    std::map<int, double> count;
    for (std::size_t j = 0; j < index.size(); ++j) {
      if (!robust[index[j]]) continue;
      const RelativePoseFactor& f = sub.factors()[j];
      count[std::min(f.a().robot, f.b().robot)] += w[j] != previous[j] ? 1.0 : 0.0;
    }
    if (changed(count, k) == 0.0) break;
  }
  std::vector<bool> sub_robust;
  for (std::size_t i : index) sub_robust.push_back(robust[i]);
  const double before = truncated(sub, sub_robust, *values);
  const double after = truncated(sub, sub_robust, x);
  if (!(std::isfinite(after) && after < before)) return false;
  for (std::size_t j = 0; j < index.size(); ++j) (*weights)[index[j]] = w[j];
  *values = std::move(x);
  return true;
}

// The robust factors the check left out that are still rejected.
std::vector<bool> LeftOut(const SeparatorConsistencyResult& check, const std::vector<bool>& robust,
                          const std::vector<double>& weights) {
  std::vector<bool> out(weights.size(), false);
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = robust[i] && !check.kept[i] && weights[i] < 0.5;
  }
  return out;
}

}  // namespace

GncResult SolveRobustCentralized(const PoseGraph& graph,
                                 const std::function<Values(const PoseGraph&)>& initialize,
                                 const std::vector<bool>& robust, const RobustDgsOptions& options,
                                 const OptimizerOptions& solver,
                                 SeparatorConsistencyResult* check_out) {
  options.validate();
  if (!options.check_separators) {
    return SolveGnc(graph, initialize(graph), robust, options.gnc, solver);
  }
  const SeparatorConsistencyResult check = CheckSeparators(graph, options, robust);
  if (check_out) *check_out = check;
  std::vector<std::size_t> index;
  const PoseGraph kept = SubGraph(graph, check.kept, &index);
  GncResult r = SolveGnc(kept, initialize(kept), Select(robust, index), options.gnc, solver);
  std::vector<double> weights(graph.factors().size(), 0.0);
  for (std::size_t j = 0; j < index.size(); ++j) weights[index[j]] = r.weights[j];
  r.weights = std::move(weights);
  // As RunRobustDgs: the check's rejects that agree with the estimate come back, and the
  // inliers alone are solved.
  const int readmitted = Readmit(graph, r.values, robust, options.gnc.threshold2(),
                                 options.one_to_one_after_gnc, &r.weights);
  if (readmitted > 0 || !AllWeightsOne(r.weights)) {
    bool solved = false;
    try {
      // A variable only rejected factors touch is not in it: it keeps GNC's estimate.
      for (const auto& [k, x] :
           Optimize(SubGraph(graph, Inliers(r.weights)), r.values, solver).values) {
        r.values[k] = x;
      }
      solved = true;
    } catch (const UnderdeterminedError&) {
      // The inliers leave part of the graph unanchored: keep GNC's estimate.
    }
    if (solved && options.retest_left_out) {
      const auto groups = RetestGroups(graph, check, robust, r.weights);
      Retest(
          graph,
          RetestCandidates(graph, check, robust, r.weights, r.values,
                           options.consistency.min_support),
          options.gnc.threshold2(), robust, options.one_to_one_after_gnc, &r.weights, &r.values,
          [&](const PoseGraph& g, const Values& start, std::size_t) {
            return Optimize(g, start, solver).values;
          },
          [](const PoseGraph& g, const Values& x) { return g.cost(x); });
      for (const std::vector<std::size_t>& group : groups) {
        if (!options.retest_groups) break;
        const std::vector<std::size_t> members =
          StillRejected(group, r.weights, options.consistency.min_support);
        if (members.empty()) continue;
        const auto sum = [](const std::map<int, double>& share) {
          double total = 0.0;
          for (const auto& [robot, x] : share) total += x;
          return total;
        };
        RetestGroup(
            graph, robust, LeftOut(check, robust, r.weights), members, options.gnc,
            options.retest_group_solves, options.one_to_one_after_gnc, &r.weights, &r.values,
            [&](const PoseGraph& g, const Values& start, int) {
              return Optimize(g, start, solver).values;
            },
            [&](const std::map<int, double>& count, int) { return sum(count); },
            [&](const PoseGraph& g, const std::vector<bool>& g_robust, const Values& x) {
              return TruncatedCost(g, g_robust, x, options.gnc.threshold2(), sum);
            });
      }
    }
  }
  r.outliers = CountOutliers(robust, r.weights);
  return r;
}

namespace {

// The team's coordinator gathers one scalar per robot and broadcasts the reduction; every
// message serialized, counted and decoded (the coordinator's own report does not travel).
class Coordinator {
 public:
  Coordinator(std::vector<int> robots, std::int64_t* bytes)
      : robots_(std::move(robots)), bytes_(bytes) {}

  double reduce(const std::map<int, double>& share, std::uint32_t round, bool take_max) {
    const int coordinator = robots_.front();
    double acc = 0.0;
    bool first = true;
    for (int r : robots_) {
      ControlMessage m;
      m.kind = ControlKind::kReport;
      m.sender = r;
      m.round = round;
      m.value[0] = share.at(r);
      const double v = r == coordinator ? m.value[0] : send(m).value[0];
      acc = first ? v : (take_max ? std::max(acc, v) : acc + v);
      first = false;
    }
    ControlMessage b;
    b.kind = ControlKind::kBroadcast;
    b.sender = coordinator;
    b.round = round;
    b.value[0] = acc;
    double received = acc;
    for (int r : robots_) {
      if (r != coordinator) received = send(b).value[0];
    }
    return received;
  }

 private:
  ControlMessage send(const ControlMessage& m) {
    const std::vector<std::uint8_t> wire = EncodeControlMessage(m);
    *bytes_ += static_cast<std::int64_t>(wire.size());
    return DecodeControlMessage(wire);
  }
  std::vector<int> robots_;
  std::int64_t* bytes_;
};

}  // namespace

namespace {

RobustDgsResult RunGncByRobots(const PoseGraph& graph, const Values& initial,
                               const std::vector<bool>& robust, const RobustDgsOptions& options);

// The re-tests of the check's rejects by the team, counted as the robots send them: the
// candidates one at a time (Retest), then each pair's runner-up group (RetestGroup).
class ChecksRejectsRetest {
 public:
  ChecksRejectsRetest(const PoseGraph& graph, const std::vector<bool>& robust,
                      const SeparatorConsistencyResult& check, const RobustDgsOptions& options,
                      RobustDgsResult& r)
      : graph_(graph),
        robust_(robust),
        check_(check),
        options_(options),
        r_(r),
        robots_(RobotsOf(graph)),
        coordinator_(robots_, &r.control_bytes) {}

  void run() {
    // First the higher robot of each pair sends the lower its estimates of its variables, held
    // by inliers, in the separators the check left out that are still rejected (for their
    // residuals).
    const std::set<Key> held = InlierKeys(graph_, r_.weights);
    const std::vector<bool> rejected = LeftOut(check_, robust_, r_.weights);
    r_.consistency_bytes += LeftOutEstimateBytes(
        graph_, r_.values,
        [&](std::size_t i, const Key& k) { return rejected[i] && held.count(k) > 0; });
    const std::vector<std::size_t> candidates = RetestCandidates(
        graph_, check_, robust_, r_.weights, r_.values, options_.consistency.min_support);
    const std::vector<std::vector<std::size_t>> groups =
        RetestGroups(graph_, check_, robust_, r_.weights);
    r_.retest_readmitted = Retest(
        graph_, candidates, options_.gnc.threshold2(), robust_, options_.one_to_one_after_gnc,
        &r_.weights, &r_.values,
        [&](const PoseGraph& g, const Values& start, std::size_t i) {
          return trialSolve(g, start, i);
        },
        [&](const PoseGraph& g, const Values& x) { return teamCost(g, x); }, &r_.retests);
    if (!options_.retest_groups) return;
    for (const std::vector<std::size_t>& group : groups) retestGroup(group);
  }

 private:
  // F over the team: each robot the factors it owns (a separator: the lower robot), reduced.
  double teamCost(const PoseGraph& g, const Values& x) {
    std::map<int, double> share;
    for (int robot : robots_) share[robot] = 0.0;
    for (const RelativePoseFactor& f : g.factors()) {
      share[std::min(f.a().robot, f.b().robot)] += f.cost(x.at(f.a()), x.at(f.b()));
    }
    return coordinator_.reduce(share, ++step_, /*take_max=*/false);
  }

  // The team's sum of `share` (robots without a share: 0).
  double reduce(const std::map<int, double>& share) {
    std::map<int, double> all;
    for (int robot : robots_) all[robot] = 0.0;
    for (const auto& [robot, x] : share) all[robot] += x;
    return coordinator_.reduce(all, ++step_, /*take_max=*/false);
  }

  // A solve of the trials: RunDgs with the refinement, its traffic counted.
  Values refinedSolve(const PoseGraph& g, const Values& start) {
    DgsOptions dgs = options_.dgs;
    dgs.refine = true;
    const DgsResult trial = RunDgs(g, start, dgs);
    r_.solve_bytes += trial.bytes;
    r_.sweeps += trial.rotation.iterations + trial.pose.iterations + trial.refine.sweeps;
    return trial.values;
  }

  // A candidate's trial: its owner sends the other robot its trial weight, then the solve.
  Values trialSolve(const PoseGraph& g, const Values& start, std::size_t i) {
    const RelativePoseFactor& f = graph_.factors()[i];
    WeightMessage m;
    m.sender = std::min(f.a().robot, f.b().robot);
    m.receiver = std::max(f.a().robot, f.b().robot);
    m.round = step_;
    m.weights = {1.0};
    r_.weight_bytes += static_cast<std::int64_t>(EncodeWeightMessage(m).size());
    ++r_.weight_messages;
    return refinedSolve(g, start);
  }

  // A weight step: the owner of each robust separator the trial may use (`usable`) sends the
  // other robot its weight, one message per robot pair.
  void weightStep(const std::vector<bool>& usable) {
    std::map<std::pair<int, int>, WeightMessage> sent;
    for (std::size_t i = 0; i < graph_.factors().size(); ++i) {
      const int a = graph_.factors()[i].a().robot, b = graph_.factors()[i].b().robot;
      if (a == b || !robust_[i] || !usable[i]) continue;
      WeightMessage& m = sent[{std::min(a, b), std::max(a, b)}];
      m.sender = std::min(a, b);
      m.receiver = std::max(a, b);
      m.round = step_;
      m.weights.push_back(r_.weights[i]);
    }
    for (const auto& [pair, m] : sent) {
      r_.weight_bytes += static_cast<std::int64_t>(EncodeWeightMessage(m).size());
      ++r_.weight_messages;
    }
  }

  // One pair's runner-up group, those of it still rejected, tried together.
  void retestGroup(const std::vector<std::size_t>& group) {
    const std::vector<std::size_t> members =
        StillRejected(group, r_.weights, options_.consistency.min_support);
    if (members.empty()) return;
    // A step in which each robot offers the size of its next group: the lowest robot's is tried.
    std::map<int, double> offers;
    for (int robot : robots_) offers[robot] = 0.0;
    const RelativePoseFactor& first = graph_.factors()[members.front()];
    offers[std::min(first.a().robot, first.b().robot)] = static_cast<double>(members.size());
    coordinator_.reduce(offers, ++step_, /*take_max=*/true);
    ++r_.group_retests;
    const std::vector<bool> left_out = LeftOut(check_, robust_, r_.weights);
    std::vector<bool> usable(graph_.factors().size());
    for (std::size_t i = 0; i < usable.size(); ++i) usable[i] = !left_out[i];
    for (std::size_t i : members) usable[i] = true;
    // The weights to the truncated cost's and the group's in (a weight step), the estimates of
    // the factors the trial may use (for the truncated cost before).
    weightStep(usable);
    r_.consistency_bytes += LeftOutEstimateBytes(
        graph_, r_.values, [&](std::size_t i, const Key&) { return usable[i]; });
    const bool kept = RetestGroup(
        graph_, robust_, left_out, members, options_.gnc, options_.retest_group_solves,
        options_.one_to_one_after_gnc, &r_.weights, &r_.values,
        [&](const PoseGraph& g, const Values& start, int) { return refinedSolve(g, start); },
        [&](const std::map<int, double>& count, int) {
          weightStep(usable);
          return reduce(count);
        },
        [&](const PoseGraph& g, const std::vector<bool>& g_robust, const Values& x) {
          return TruncatedCost(g, g_robust, x, options_.gnc.threshold2(),
                               [&](const std::map<int, double>& share) { return reduce(share); });
        });
    if (kept) {
      for (std::size_t i : members) r_.group_readmitted += r_.weights[i] >= 0.5 ? 1 : 0;
    }
  }

  const PoseGraph& graph_;
  const std::vector<bool>& robust_;
  const SeparatorConsistencyResult& check_;
  const RobustDgsOptions& options_;
  RobustDgsResult& r_;
  const std::vector<int> robots_;
  Coordinator coordinator_;
  std::uint32_t step_ = 0;  // the team's protocol steps so far
};

// The re-tests of the check's rejects once the inliers' solve was kept (RunRobustDgs): one by one
// (retest_left_out), then the robot pairs' groups (retest_groups). Updates r's weights and
// estimate and counts into it (retests, group re-tests, sweeps and bytes).
void RetestChecksRejects(const PoseGraph& graph, const std::vector<bool>& robust,
                         const SeparatorConsistencyResult& check, const RobustDgsOptions& options,
                         RobustDgsResult& r) {
  ChecksRejectsRetest(graph, robust, check, options, r).run();
}

// The separator check of RunRobustDgs on the factors of `checked` (all when empty); the others
// are kept and tested by no loop. Everything kept when options.check_separators is off.
SeparatorConsistencyResult CheckOnMask(const PoseGraph& graph, const std::vector<bool>& robust,
                                       const std::vector<bool>& checked,
                                       const RobustDgsOptions& options) {
  const std::size_t n = graph.factors().size();
  SeparatorConsistencyResult check;
  check.kept.assign(n, true);
  if (!options.check_separators) return check;
  if (checked.empty()) return CheckSeparators(graph, options, robust);
  std::vector<std::size_t> seen;
  const PoseGraph sub = SubGraph(graph, checked, &seen);
  return OnTheWholeGraph(CheckSeparators(sub, options, Select(robust, seen)), seen, n);
}

// The inliers' solve from the rounds' estimate (DGS refined), kept when it lowers their cost
// (KeepInlierSolve): r.polished, else r.polish_refused; nothing when the inliers leave a robot
// unlinked. Counts its bytes and sweeps into r.
void PolishInliers(const PoseGraph& graph, const RobustDgsOptions& options, RobustDgsResult& r) {
  const PoseGraph final_graph = SubGraph(graph, Inliers(r.weights));
  try {
    DgsOptions dgs = options.dgs;
    dgs.refine = true;
    const DgsResult polish = RunDgs(final_graph, r.values, dgs);
    r.solve_bytes += polish.bytes;
    r.sweeps += polish.rotation.iterations + polish.pose.iterations + polish.refine.sweeps;
    if (KeepInlierSolve(final_graph.cost(r.values), final_graph.cost(polish.values))) {
      // A variable only rejected factors touch (a landmark whose observations and shared pairs
      // were all rejected) is not in it: it keeps the rounds' estimate.
      for (const auto& [k, x] : polish.values) r.values[k] = x;
      r.polished = true;
    } else {
      r.polish_refused = true;
    }
  } catch (const UnderdeterminedError&) {
    // The inliers leave a robot unlinked: keep the rounds' estimate.
  }
}

}  // namespace

RobustDgsResult RunRobustDgs(const PoseGraph& graph, const Values& initial,
                             const std::vector<bool>& robust, const RobustDgsOptions& options,
                             const std::vector<bool>& checked) {
  const auto t0 = std::chrono::steady_clock::now();
  options.validate();
  const std::size_t n = graph.factors().size();
  if (robust.size() != n) {
    throw InvalidInputError("RunRobustDgs: the robust mask has " + std::to_string(robust.size()) +
                            " entries for " + std::to_string(n) + " factors");
  }
  if (!checked.empty() && checked.size() != n) {
    throw InvalidInputError("RunRobustDgs: the checked mask has " + std::to_string(checked.size()) +
                            " entries for " + std::to_string(n) + " factors");
  }
  const SeparatorConsistencyResult check = CheckOnMask(graph, robust, checked, options);
  std::vector<std::size_t> index;
  const PoseGraph kept = SubGraph(graph, check.kept, &index);
  RobustDgsResult r;
  try {
    r = RunGncByRobots(kept, initial, Select(robust, index), options);
  } catch (const UnderdeterminedError& e) {
    if (check.rejected == 0) throw;
    throw UnderdeterminedError(
        "RunRobustDgs: the separator check left " + std::to_string(check.rejected) +
        " separator(s) out and with them every link of some robot (a robot pair with fewer "
        "than consistency.min_support pairwise-consistent separators keeps none unless its "
        "robots are linked through confirmed pairs): " + e.what());
  }
  std::vector<double> weights(n, 0.0);
  for (std::size_t j = 0; j < index.size(); ++j) weights[index[j]] = r.weights[j];
  r.weights = std::move(weights);
  r.consistency_bytes = check.bytes;
  r.consistency_rejected = check.rejected;
  r.consistency_deferred = check.deferred;
  // The separators the check left out that agree with the estimate come back: the robot of
  // higher id sends the other its estimates of their poses.
  r.consistency_bytes += LeftOutEstimateBytes(
      graph, r.values, [&](std::size_t i, const Key&) { return !check.kept[i] && robust[i]; });
  r.readmitted = Readmit(graph, r.values, robust, options.gnc.threshold2(),
                         options.one_to_one_after_gnc, &r.weights);
  // The estimate of the inliers alone, where some weight is not 1 (the rounds kept a sliver,
  // min_weight, of every rejected factor) or some separator came back.
  if (r.readmitted > 0 || !AllWeightsOne(r.weights)) PolishInliers(graph, options, r);
  if (options.retest_left_out && r.polished) RetestChecksRejects(graph, robust, check, options, r);
  r.outliers = CountOutliers(robust, r.weights);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

namespace {

// GNC-TLS by the robots: each owns the weights of its factors (a separator's: the lower robot's)
// and sends a separator's to the other robot; the team's largest residual and undecided count
// through the coordinator's reductions.
class GncByRobots {
 public:
  GncByRobots(const PoseGraph& graph, const std::vector<bool>& robust,
              const RobustDgsOptions& options)
      : graph_(graph),
        robust_(robust),
        options_(options),
        robots_(RobotsOf(graph)),
        owner_(graph.factors().size()),
        coordinator_(robots_, &out_.control_bytes) {
    dgs_ = options.dgs;
    dgs_.refine = true;
    // Who owns which weight; the separators each owner sends, per (owner, other robot).
    const std::vector<RelativePoseFactor>& factors = graph.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const int a = factors[i].a().robot, b = factors[i].b().robot;
      owner_[i] = std::min(a, b);
      if (robust[i] && a != b) separators_[{std::min(a, b), std::max(a, b)}].push_back(i);
    }
  }

  RobustDgsResult run(const Values& initial) && {
    const auto t0 = std::chrono::steady_clock::now();
    out_.weights.assign(graph_.factors().size(), 1.0);
    RobustDgsRound round0;
    out_.values = solve(graph_, initial, round0);
    round0.cost = graph_.cost(out_.values);
    out_.rounds.push_back(round0);
    GncSchedule schedule(options_.gnc);
    std::vector<double> r2 = SquaredResiduals(graph_, out_.values);
    const double max_r2 = coordinator_.reduce(perRobotMax(r2), 0, /*take_max=*/true);
    if (schedule.start(max_r2)) {
      for (std::uint32_t k = 1;; ++k) {
        if (schedule.next(round(k, schedule, r2))) break;
      }
    }
    out_.status = schedule.status();
    out_.iterations = schedule.iterations();
    out_.outliers = CountOutliers(robust_, out_.weights);
    out_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return std::move(out_);
  }

 private:
  Values solve(const PoseGraph& g, const Values& start, RobustDgsRound& round) {
    const DgsResult r = RunDgs(g, start, dgs_);
    round.solve_bytes = r.bytes;
    out_.solve_bytes += r.bytes;
    out_.sweeps += r.rotation.iterations + r.pose.iterations + r.refine.sweeps;
    return r.values;
  }

  // Each robot's largest squared residual among the factors it owns (robust ones).
  std::map<int, double> perRobotMax(const std::vector<double>& r2) const {
    std::map<int, double> m;
    for (int r : robots_) m[r] = 0.0;
    for (std::size_t i = 0; i < r2.size(); ++i) {
      if (robust_[i]) m[owner_[i]] = std::max(m[owner_[i]], r2[i]);
    }
    return m;
  }

  // GNC round k at the schedule's mu from the residuals r2 (updated to the round's estimate).
  // Returns whether every weight is decided.
  bool round(std::uint32_t k, const GncSchedule& schedule, std::vector<double>& r2) {
    const std::size_t n = graph_.factors().size();
    RobustDgsRound round;
    round.round = static_cast<int>(k);
    round.mu = schedule.mu();
    // Every robot sets the weights it owns and counts the undecided ones.
    std::map<int, double> undecided;
    for (int r : robots_) undecided[r] = 0.0;
    std::vector<double> owned(n, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
      if (!robust_[i]) continue;
      owned[i] = schedule.weight(r2[i]);
      if (!schedule.decided(owned[i])) undecided[owner_[i]] += 1.0;
    }
    // The separators' weights to the other robot; the solve uses what arrived.
    std::vector<double> used = owned;
    for (const auto& [pair, list] : separators_) {
      WeightMessage m;
      m.sender = pair.first;
      m.receiver = pair.second;
      m.round = k;
      for (std::size_t i : list) m.weights.push_back(owned[i]);
      const std::vector<std::uint8_t> wire = EncodeWeightMessage(m);
      out_.weight_bytes += static_cast<std::int64_t>(wire.size());
      ++out_.weight_messages;
      const WeightMessage received = DecodeWeightMessage(wire);
      for (std::size_t j = 0; j < list.size(); ++j) used[list[j]] = received.weights[j];
    }
    out_.weights = used;
    const PoseGraph weighted = WeightedGraph(graph_, used, options_.gnc.min_weight);
    out_.values = solve(weighted, out_.values, round);
    round.cost = weighted.cost(out_.values);
    r2 = SquaredResiduals(graph_, out_.values);
    const double left = coordinator_.reduce(undecided, k, /*take_max=*/false);
    round.undecided = static_cast<int>(left);
    round.outliers = CountOutliers(robust_, used);
    out_.rounds.push_back(round);
    return left == 0.0;
  }

  const PoseGraph& graph_;
  const std::vector<bool>& robust_;  // one per factor (RunRobustDgs checked it)
  const RobustDgsOptions& options_;
  DgsOptions dgs_;  // the solves': options.dgs with the refinement
  const std::vector<int> robots_;
  std::vector<int> owner_;  // per factor: the robot that owns its weight
  std::map<std::pair<int, int>, std::vector<std::size_t>> separators_;
  RobustDgsResult out_;
  Coordinator coordinator_;
};

RobustDgsResult RunGncByRobots(const PoseGraph& graph, const Values& initial,
                               const std::vector<bool>& robust, const RobustDgsOptions& options) {
  return GncByRobots(graph, robust, options).run(initial);
}

}  // namespace

}  // namespace moslam
