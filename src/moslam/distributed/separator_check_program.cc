#include "moslam/distributed/separator_check_program.h"

#include <algorithm>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/robust_robot.h"

namespace moslam {
namespace {

std::vector<RelativePoseFactor> SeparatorsWith(const RobustRobotProblem& problem,
                                               const std::map<int, std::vector<std::size_t>>& pairs,
                                               int other) {
  std::vector<RelativePoseFactor> out;
  for (std::size_t i : pairs.at(other)) out.push_back(problem.subgraph.factors()[i]);
  return out;
}

// One pair's verdict at C2, by the robot that checks it (the lower one).
struct PairVerdict {
  bool checked = false, confirmed = false;
  int largest = 0;                     // its largest consistent set
  std::vector<std::size_t> kept;       // PairConsistency::kept: positions in pairs[other]
  std::vector<int> support;            // per position: the members of kept it agrees with
  std::vector<std::size_t> runner_up;  // PairConsistency::runner_up
};

// The check's steps C1-C4 for one robot, on the state they pass on.
class SeparatorCheck {
 public:
  SeparatorCheck(const RobustRobotProblem& problem,
                 const std::map<int, std::vector<std::size_t>>& pairs,
                 const SeparatorConsistencyOptions& consistency, const GncOptions& gnc,
                 ProgramLink& link)
      : problem_(problem),
        pairs_(pairs),
        consistency_(consistency),
        link_(link),
        graph_(problem.checked.empty() ? problem.subgraph
                                       : SubGraph(problem.subgraph, problem.checked, &seen_)),
        map_(graph_, problem.robot, CheckedRobust(problem, seen_), gnc,
             consistency.map_uncertainty) {}

  SeparatorCheckVerdict run() {
    judgePairs(sendMap());
    for (const auto& [other, v] : verdicts_) confirmed_[other] = v.confirmed;
    double label = problem_.robot;
    const std::map<int, double> labels =
        floodLowestLinked(exchangeVerdicts(false, label, 0.0), label);
    SeparatorCheckVerdict result;
    result.deferred = dropUnlinked(labels, label);
    result.rejected_by_team = TeamSum(exchangeVerdicts(true, label, rejectedHere()), 1);
    collect(result);
    return result;
  }

 private:
  // The robustness flags of the checked subgraph's factors (`seen`: their subgraph indices).
  static std::vector<bool> CheckedRobust(const RobustRobotProblem& problem,
                                         const std::vector<std::size_t>& seen) {
    if (problem.checked.empty()) return problem.robust;
    std::vector<bool> out;
    for (std::size_t i : seen) out.push_back(problem.robust[i]);
    return out;
  }

  std::vector<RelativePoseFactor> separatorsWith(int other) const {
    return SeparatorsWith(problem_, pairs_, other);
  }

  // C1: the map's estimates and covariances toward lower neighbours.
  TeamStep sendMap() {
    std::vector<OutgoingMessage> estimates;
    std::vector<CovarianceMessage> covariances;
    for (const auto& [other, list] : pairs_) {
      OutgoingMessage o = link_.emptyMessageTo(other);
      CovarianceMessage c;
      c.sender = problem_.robot;
      c.receiver = other;
      const std::vector<Key> mine = SeparatorVariables(separatorsWith(other), problem_.robot);
      // (No checked separator with it: a neighbour only through factors the check does not see.)
      if (other < problem_.robot && !list.empty() && map_.hasAll(mine)) {
        o.message = map_.estimates(mine);
        c.covariance = map_.covariance(mine);
        link_.countCheck(EncodeMessage(o.message).size());
        if (consistency_.map_uncertainty) link_.countCheck(EncodeCovarianceMessage(c).size());
      }
      estimates.push_back(std::move(o));
      if (consistency_.map_uncertainty) covariances.push_back(std::move(c));
    }
    TeamReport report;
    report.sent = true;
    report.covariance = consistency_.map_uncertainty;
    return link_.step(report, {}, estimates, covariances);
  }

  // C2: the largest consistent set of each pair it checks (toward higher neighbours).
  void judgePairs(const TeamStep& c1) {
    for (const auto& [other, list] : pairs_) {
      if (other < problem_.robot) continue;
      PairVerdict& v = verdicts_[other];
      const Message* theirs = nullptr;
      for (const Message& m : c1.estimates) {
        if (m.sender == other) theirs = &m;
      }
      const std::vector<RelativePoseFactor> separators = separatorsWith(other);
      // A variable a robot's own factors do not reach: nothing to check with (all kept).
      if (!theirs || theirs->keys.empty() ||
          !map_.hasAll(SeparatorVariables(separators, problem_.robot))) {
        continue;
      }
      Eigen::MatrixXd covariance;
      if (consistency_.map_uncertainty) {
        const auto it = c1.covariances.find(other);
        if (it == c1.covariances.end()) {
          throw InvalidInputError("robust program: robot " + std::to_string(other) +
                                  " sent its map's estimates without their covariance");
        }
        covariance = it->second.covariance;
      }
      v.checked = true;
      PairConsistency check =
          ConsistentSeparators(separators, map_, *theirs, covariance, consistency_);
      v.largest = check.largest;
      v.kept = std::move(check.kept);
      v.support = std::move(check.support);
      v.runner_up = std::move(check.runner_up);
      v.confirmed = v.largest >= consistency_.min_support;
    }
  }

  // The verdict on the pair with a higher neighbour as sent: per separator 1 (kept) or 0, then
  // whether the pair confirms itself. Before the final exchange only confirmed pairs keep any.
  std::vector<double> verdictWeights(int other, bool final) const {
    std::vector<double> out;
    const PairVerdict& v = verdicts_.at(other);
    for (std::size_t j = 0; j < pairs_.at(other).size(); ++j) {
      const bool in_kept = std::binary_search(v.kept.begin(), v.kept.end(), j);
      out.push_back(!v.checked || ((v.confirmed || final) && in_kept) ? 1.0 : 0.0);
    }
    out.push_back(v.confirmed ? 1.0 : 0.0);
    return out;
  }

  // The verdicts to higher neighbours, and from lower ones (checked against the pair's size),
  // their separators in wire order (WireOrder), the pair's flag last.
  TeamStep exchangeVerdicts(bool final, double label, double rejected) {
    std::vector<WeightMessage> send;
    for (const auto& [other, list] : pairs_) {
      std::vector<double> wire;
      if (other > problem_.robot) {
        const std::vector<double> verdict = verdictWeights(other, final);
        for (std::size_t j : WireOrder(problem_.subgraph, list)) wire.push_back(verdict[j]);
        wire.push_back(verdict.back());
      }
      send.push_back(link_.weightMessage(other, 0, std::move(wire)));
    }
    TeamReport r;
    r.weights = true;
    r.value[0] = label;
    r.value[1] = rejected;
    TeamStep got = link_.step(r, send);
    for (const auto& [other, m] : got.weights) {
      if (other > problem_.robot || !pairs_.count(other)) continue;
      if (m.weights.size() != pairs_.at(other).size() + 1) {
        throw InvalidInputError("robust program: robot " + std::to_string(other) +
                                " sent a separator check verdict of " +
                                std::to_string(m.weights.size()) + " entries where the " +
                                std::to_string(pairs_.at(other).size()) + " separators robot " +
                                std::to_string(problem_.robot) + " shares with it need " +
                                std::to_string(pairs_.at(other).size() + 1) +
                                " (one each, then the pair's flag): their subgraphs disagree");
      }
      confirmed_[other] = m.weights.back() == 1.0;
      std::vector<double>& verdict = kept_by_other_[other];
      verdict = m.weights;
      const std::vector<std::size_t> wire = WireOrder(problem_.subgraph, pairs_.at(other));
      for (std::size_t k = 0; k < wire.size(); ++k) verdict[wire[k]] = m.weights[k];
    }
    return got;
  }

  // C3: the lowest robot id linked through confirmed pairs, flooded until no report changes.
  // Returns every robot's label; `label` ends as this robot's.
  std::map<int, double> floodLowestLinked(const TeamStep& first, double& label) {
    std::map<int, double> previous = TeamValues(first, 0);
    while (true) {
      for (const auto& [other, yes] : confirmed_) {
        const auto it = previous.find(other);
        if (yes && it != previous.end()) label = std::min(label, it->second);
      }
      const std::map<int, double> labels = TeamValues(link_.reduce(label), 0);
      if (labels == previous) return labels;
      previous = labels;
    }
  }

  // C4: pairs below min_support keep their largest sets when linked through confirmed pairs
  // (and at least linked_min_support); the others keep none. Returns the separators so kept.
  int dropUnlinked(const std::map<int, double>& labels, double label) {
    int deferred = 0;
    for (auto& [other, v] : verdicts_) {
      if (!v.checked || v.confirmed) continue;
      const auto it = labels.find(other);
      const bool linked = it != labels.end() && it->second == label;
      if (!linked || v.largest < consistency_.linked_min_support) {
        v.kept.clear();
      } else {
        deferred += static_cast<int>(v.kept.size());
      }
    }
    return deferred;
  }

  // The separators it leaves out of the pairs it checks.
  double rejectedHere() const {
    double rejected = 0.0;
    for (const auto& [other, v] : verdicts_) {
      if (v.checked) rejected += static_cast<double>(pairs_.at(other).size() - v.kept.size());
    }
    return rejected;
  }

  // The supports, runner-up sets and final kept flags (its own verdicts and the lower
  // neighbours').
  void collect(SeparatorCheckVerdict& result) const {
    for (const auto& [other, v] : verdicts_) {
      if (!v.checked) continue;
      const std::vector<std::size_t>& list = pairs_.at(other);
      for (std::size_t j = 0; j < list.size(); ++j) {
        result.support[list[j]] = v.kept.empty() ? 0 : v.support[j];
      }
      if (!v.kept.empty()) {
        for (std::size_t j : v.runner_up) result.runner_up.insert(list[j]);
      }
    }
    std::vector<bool> kept(problem_.subgraph.factors().size(), true);
    for (const auto& [other, list] : pairs_) {
      const auto theirs = kept_by_other_.find(other);
      if (other < problem_.robot && theirs == kept_by_other_.end()) continue;
      const std::vector<double> verdict =
          other > problem_.robot ? verdictWeights(other, true) : theirs->second;
      for (std::size_t j = 0; j < list.size(); ++j) {
        kept[list[j]] = verdict[j] == 1.0;
        if (other > problem_.robot && !kept[list[j]]) ++result.rejected;
      }
    }
    result.kept = std::move(kept);
  }

  const RobustRobotProblem& problem_;
  const std::map<int, std::vector<std::size_t>>& pairs_;
  const SeparatorConsistencyOptions& consistency_;
  ProgramLink& link_;
  std::vector<std::size_t> seen_;  // the checked subgraph's factors, as subgraph indices
  const PoseGraph graph_;          // the subgraph the check sees
  const SeparatorCheckMap map_;
  std::map<int, PairVerdict> verdicts_;               // the pairs it checks
  std::map<int, bool> confirmed_;                     // per neighbour: the pair confirms itself
  std::map<int, std::vector<double>> kept_by_other_;  // verdicts received from lower neighbours
};

}  // namespace

SeparatorCheckVerdict RunSeparatorCheck(const RobustRobotProblem& problem,
                                        const std::map<int, std::vector<std::size_t>>& pairs,
                                        const SeparatorConsistencyOptions& consistency,
                                        const GncOptions& gnc, ProgramLink& link) {
  return SeparatorCheck(problem, pairs, consistency, gnc, link).run();
}

}  // namespace moslam
