#include "moslam/distributed/retest_program.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "moslam/distributed/separator_consistency.h"

namespace moslam {
namespace {

class Retests {
 public:
  Retests(RobustRobot& robot, const SeparatorCheckVerdict& check)
      : robot_(robot), p_(robot.problem()), options_(robot.options()), check_(check) {}

  void run(double inlier_cost, std::uint32_t round) {
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    const std::vector<double>& weights = robot_.weights();
    const auto left_out = [&](std::size_t i) {
      return p_.robust[i] && !check_.kept[i] && weights[i] < 0.5;
    };
    const std::set<Key> held_there = robot_.sendEstimates(
        [&](std::size_t i, const Key& mine) { return left_out(i) && robot_.held(mine); });
    std::vector<std::pair<double, std::size_t>> mine;
    std::vector<std::vector<std::size_t>> groups;
    const int min_support = options_.consistency.min_support;
    for (const auto& [other, list] : robot_.checkedPairs()) {
      if (other < p_.robot) continue;
      groups.emplace_back();
      for (std::size_t i : list) {
        const RelativePoseFactor& f = factors[i];
        const bool a_mine = f.a().robot == p_.robot;
        if (!left_out(i) || !robot_.held(a_mine ? f.a() : f.b()) ||
            !held_there.count(a_mine ? f.b() : f.a())) {
          continue;
        }
        if (check_.runner_up.count(i)) groups.back().push_back(i);
        const auto it = check_.support.find(i);
        if (it != check_.support.end() && it->second >= min_support) {
          const Values& values = robot_.values();
          mine.emplace_back(2.0 * f.cost(values.at(f.a()), values.at(f.b())), i);
        }
      }
    }
    std::sort(mine.begin(), mine.end());
    RobustProgramResult& out = robot_.result();
    std::size_t next = 0;
    double f0 = inlier_cost;
    std::uint32_t k = round;
    for (;; ++k) {
      // A candidate that would pair a landmark twice is not tried (RunRobustDgs's Retest): the
      // weights of its pair change only with this robot's own trials.
      while (options_.one_to_one_after_gnc && next < mine.size() &&
             BreaksOneToOne(factors, robot_.index().owned, weights, mine[next].second)) {
        ++next;
      }
      TeamReport offer;
      offer.value[0] = next < mine.size() ? 1.0 : 0.0;
      offer.value[1] = next < mine.size() ? mine[next].first : 0.0;
      const TeamStep offers = robot_.link().step(offer);
      int chosen = -1;
      double best = 0.0;
      for (const auto& [r, o] : offers.reports) {  // robot id order: ties to the lower
        if (o.value[0] == 1.0 && (chosen < 0 || o.value[1] < best)) {
          chosen = r;
          best = o.value[1];
        }
      }
      if (chosen < 0) break;
      ++out.retests;
      std::vector<std::size_t> candidate;
      if (chosen == p_.robot) candidate = {mine[next++].second};
      out.retest_readmitted += tryCandidate(candidate, k, &f0);
    }
    if (!options_.retest_groups) return;
    std::size_t group = 0;
    for (++k;; ++k) {
      std::vector<std::size_t> left;
      for (; group < groups.size() && left.empty(); ++group) {
        for (std::size_t i : groups[group]) {
          if (weights[i] < 0.5) left.push_back(i);
        }
        if (left.size() < GroupMinimum(min_support)) left.clear();
      }
      TeamReport offer;
      offer.value[0] = static_cast<double>(left.size());
      const TeamStep offers = robot_.link().step(offer);
      int chosen = -1;
      for (const auto& [r, o] : offers.reports) {  // robot id order: the lowest offering
        if (o.value[0] > 0.0) {
          chosen = r;
          break;
        }
      }
      if (chosen < 0) return;
      if (chosen != p_.robot && !left.empty()) --group;  // offered again in the next step
      ++out.group_retests;
      if (chosen != p_.robot) left.clear();
      if (tryGroup(left, &k)) {
        for (std::size_t i : left) out.group_readmitted += weights[i] >= 0.5 ? 1 : 0;
      }
    }
  }

 private:
  // One trial, in step k: the separators of `candidate` (its own; empty on the other robots) get
  // weight 1, the weight step, the inliers' solve, a step reducing their cost F1; they stay when
  // 2 (F1 - F0) <= c2, F0 then F1; else every robot puts its weights and estimate back. Returns
  // how many of its own came back.
  int tryCandidate(const std::vector<std::size_t>& candidate, std::uint32_t k, double* f0) {
    std::vector<double>& weights = robot_.weights();
    const std::vector<double> before = weights;
    const Values values = robot_.values();
    for (std::size_t i : candidate) weights[i] = 1.0;
    // The candidate's robots need not be neighbours in the last solve: an agent of the whole
    // subgraph for the weight step.
    robot_.reachEveryNeighbour();
    robot_.exchangeWeights(robot_.index(), weights, k, 0.0);
    const PoseGraph trial = SubGraph(p_.subgraph, Inliers(weights));
    robot_.solve(trial);
    TeamReport cost;
    cost.value[0] = robot_.ownedCost(trial);
    const double f1 = TeamSum(robot_.link().step(cost), 0);
    if (std::isfinite(f1) && 2.0 * (f1 - *f0) <= robot_.c2()) {
      *f0 = f1;
      return static_cast<int>(candidate.size());
    }
    weights = before;
    robot_.values() = values;
    return 0;
  }

  // The trial of a group (RunRobustDgs's RetestGroup), from step *k on: the weights of its
  // robust factors to the truncated cost's (1 for an inlier, 0 else), the group's (its own;
  // empty on the other robots) 1, a weight step; the factors it may use (all but the check's
  // rejects still left out), a step in which the higher robot of each pair sends the lower its
  // estimates of its variables in them (for the truncated cost before); then solves of the
  // weighted factors it may use, each followed by a weight step with the weights it owns at the
  // result (1 within c2, else 0) and the team's count of changed ones, until none changed or
  // after retest_group_solves; a step reducing the truncated cost before and after. Kept when it
  // fell, else every robot puts its weights and estimate back.
  bool tryGroup(const std::vector<std::size_t>& group, std::uint32_t* k) {
    const std::size_t n = p_.subgraph.factors().size();
    const double c2 = robot_.c2();
    std::vector<double>& weights = robot_.weights();
    const std::vector<double> saved = weights;
    const Values values = robot_.values();
    for (std::size_t i = 0; i < n; ++i) {
      if (p_.robust[i]) weights[i] = weights[i] >= 0.5 ? 1.0 : 0.0;
    }
    for (std::size_t i : group) weights[i] = 1.0;
    robot_.reachEveryNeighbour();
    robot_.exchangeWeights(robot_.index(), weights, *k, 0.0);
    std::vector<bool> usable(n);
    for (std::size_t i = 0; i < n; ++i) {
      usable[i] = !(p_.robust[i] && !check_.kept[i] && weights[i] < 0.5);
    }
    robot_.sendEstimates([&](std::size_t i, const Key&) { return usable[i]; });
    std::vector<std::size_t> index;
    const PoseGraph sub = SubGraph(p_.subgraph, usable, &index);
    std::vector<bool> sub_robust;
    for (std::size_t i : index) sub_robust.push_back(p_.robust[i]);
    const double before = robot_.ownedTruncatedCost(sub, sub_robust);
    for (int s = 0; s < options_.retest_group_solves; ++s) {
      std::vector<double> w;
      for (std::size_t i : index) w.push_back(weights[i]);
      robot_.solve(WeightedGraph(sub, w, options_.gnc.min_weight));
      const Values& now = robot_.values();
      const std::vector<double> previous = weights;
      std::vector<double> r2(n, 0.0);
      std::vector<std::size_t> members;
      for (std::size_t i : robot_.index().owned) {
        if (!usable[i]) continue;
        const RelativePoseFactor& f = p_.subgraph.factors()[i];
        r2[i] = 2.0 * f.cost(now.at(f.a()), now.at(f.b()));
        weights[i] = r2[i] <= c2 ? 1.0 : 0.0;
        members.push_back(i);
      }
      if (options_.one_to_one_after_gnc) {
        KeepOneToOne(p_.subgraph.factors(), members, r2, &weights);
      }
      double changed = 0.0;
      for (std::size_t i : members) changed += weights[i] != previous[i] ? 1.0 : 0.0;
      robot_.reachEveryNeighbour();
      if (TeamSum(robot_.exchangeWeights(robot_.index(), weights, ++*k, changed), 0) == 0.0) {
        break;
      }
    }
    TeamReport cost;
    cost.value[0] = before;
    cost.value[1] = robot_.ownedTruncatedCost(sub, sub_robust);
    const TeamStep got = robot_.link().step(cost);
    const double after = TeamSum(got, 1);
    if (std::isfinite(after) && after < TeamSum(got, 0)) return true;
    weights = saved;
    robot_.values() = values;
    return false;
  }

  RobustRobot& robot_;
  const RobustRobotProblem& p_;
  const RobustProgramOptions& options_;
  const SeparatorCheckVerdict& check_;
};

}  // namespace

void RunRetests(RobustRobot& robot, const SeparatorCheckVerdict& check, double inlier_cost,
                std::uint32_t round) {
  Retests(robot, check).run(inlier_cost, round);
}

}  // namespace moslam
