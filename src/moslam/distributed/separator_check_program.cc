#include "moslam/distributed/separator_check_program.h"

#include <algorithm>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"

namespace moslam {
namespace {

std::vector<RelativePoseFactor> SeparatorsWith(const RobustRobotProblem& problem,
                                               const std::map<int, std::vector<std::size_t>>& pairs,
                                               int other) {
  std::vector<RelativePoseFactor> out;
  for (std::size_t i : pairs.at(other)) out.push_back(problem.subgraph.factors()[i]);
  return out;
}

}  // namespace

SeparatorCheckVerdict RunSeparatorCheck(const RobustRobotProblem& problem,
                                        const std::map<int, std::vector<std::size_t>>& pairs,
                                        const SeparatorConsistencyOptions& consistency,
                                        const GncOptions& gnc, ProgramLink& link) {
  SeparatorCheckVerdict result;

  std::vector<std::size_t> seen;
  const PoseGraph checked_graph = problem.checked.empty()
                                      ? problem.subgraph
                                      : SubGraph(problem.subgraph, problem.checked, &seen);
  std::vector<bool> checked_robust = problem.robust;
  if (!problem.checked.empty()) {
    checked_robust.clear();
    for (std::size_t i : seen) checked_robust.push_back(problem.robust[i]);
  }
  const SeparatorCheckMap map(checked_graph, problem.robot, checked_robust, gnc,
                              consistency.map_uncertainty);
  // C1: the map's estimates and covariances toward lower neighbours.
  std::vector<OutgoingMessage> estimates;
  std::vector<CovarianceMessage> covariances;
  for (const auto& [other, list] : pairs) {
    OutgoingMessage o = link.emptyMessageTo(other);
    CovarianceMessage c;
    c.sender = problem.robot;
    c.receiver = other;
    const std::vector<Key> mine =
        SeparatorVariables(SeparatorsWith(problem, pairs, other), problem.robot);
    // (No checked separator with it: a neighbour only through factors the check does not see.)
    if (other < problem.robot && !list.empty() && map.hasAll(mine)) {
      o.message = map.estimates(mine);
      c.covariance = map.covariance(mine);
      link.countCheck(EncodeMessage(o.message).size());
      if (consistency.map_uncertainty) link.countCheck(EncodeCovarianceMessage(c).size());
    }
    estimates.push_back(std::move(o));
    if (consistency.map_uncertainty) covariances.push_back(std::move(c));
  }
  TeamReport report;
  report.sent = true;
  report.covariance = consistency.map_uncertainty;
  const TeamStep c1 = link.step(report, {}, estimates, covariances);
  // C2: the largest consistent set of each pair it checks (toward higher neighbours).
  struct Verdict {
    bool checked = false, confirmed = false;
    int largest = 0;                     // its largest consistent set
    std::vector<std::size_t> kept;       // PairConsistency::kept: positions in pairs[other]
    std::vector<int> support;            // per position: the members of kept it agrees with
    std::vector<std::size_t> runner_up;  // PairConsistency::runner_up
  };
  std::map<int, Verdict> verdicts;
  for (const auto& [other, list] : pairs) {
    if (other < problem.robot) continue;
    Verdict& v = verdicts[other];
    const Message* theirs = nullptr;
    for (const Message& m : c1.estimates) {
      if (m.sender == other) theirs = &m;
    }
    const std::vector<RelativePoseFactor> separators = SeparatorsWith(problem, pairs, other);
    // A variable a robot's own factors do not reach: nothing to check with (all kept).
    if (!theirs || theirs->keys.empty() ||
        !map.hasAll(SeparatorVariables(separators, problem.robot))) {
      continue;
    }
    Eigen::MatrixXd covariance;
    if (consistency.map_uncertainty) {
      const auto it = c1.covariances.find(other);
      if (it == c1.covariances.end()) {
        throw InvalidInputError("robust program: robot " + std::to_string(other) +
                                " sent its map's estimates without their covariance");
      }
      covariance = it->second.covariance;
    }
    v.checked = true;
    PairConsistency check = ConsistentSeparators(separators, map, *theirs, covariance, consistency);
    v.largest = check.largest;
    v.kept = std::move(check.kept);
    v.support = std::move(check.support);
    v.runner_up = std::move(check.runner_up);
    v.confirmed = v.largest >= consistency.min_support;
  }
  const auto verdictWeights = [&](int other, bool final) {
    std::vector<double> out;
    const Verdict& v = verdicts.at(other);
    for (std::size_t j = 0; j < pairs.at(other).size(); ++j) {
      const bool in_kept = std::binary_search(v.kept.begin(), v.kept.end(), j);
      out.push_back(!v.checked || ((v.confirmed || final) && in_kept) ? 1.0 : 0.0);
    }
    out.push_back(v.confirmed ? 1.0 : 0.0);
    return out;
  };
  std::map<int, bool> confirmed;                     // per neighbour: their pair confirms itself
  std::map<int, std::vector<double>> kept_by_other;  // verdicts received from lower neighbours
  const auto exchangeVerdicts = [&](bool final, double label, double rejected) {
    std::vector<WeightMessage> send;
    for (const auto& [other, list] : pairs) {
      send.push_back(link.weightMessage(
          other, 0, other > problem.robot ? verdictWeights(other, final) : std::vector<double>()));
    }
    TeamReport r;
    r.weights = true;
    r.value[0] = label;
    r.value[1] = rejected;
    TeamStep got = link.step(r, send);
    for (const auto& [other, m] : got.weights) {
      if (other > problem.robot || !pairs.count(other)) continue;
      if (m.weights.size() != pairs.at(other).size() + 1) {
        throw InvalidInputError(
            "robust program: robot " + std::to_string(other) +
            " sent a separator check verdict of " + std::to_string(m.weights.size()) +
            " entries for the " + std::to_string(pairs.at(other).size()) + " separators robot " +
            std::to_string(problem.robot) + " shares with it (their subgraphs disagree)");
      }
      confirmed[other] = m.weights.back() == 1.0;
      kept_by_other[other] = m.weights;
    }
    return got;
  };
  for (const auto& [other, v] : verdicts) confirmed[other] = v.confirmed;
  double label = problem.robot;
  TeamStep got = exchangeVerdicts(false, label, 0.0);
  // C3: the lowest robot id linked through confirmed pairs, flooded until no report changes.
  std::map<int, double> previous = TeamValues(got, 0);
  while (true) {
    for (const auto& [other, yes] : confirmed) {
      const auto it = previous.find(other);
      if (yes && it != previous.end()) label = std::min(label, it->second);
    }
    const std::map<int, double> labels = TeamValues(link.reduce(label), 0);
    if (labels == previous) break;
    previous = labels;
  }
  // C4: pairs below min_support keep their largest sets when linked through confirmed pairs.
  for (auto& [other, v] : verdicts) {
    if (!v.checked || v.confirmed) continue;
    const auto it = previous.find(other);
    const bool linked = it != previous.end() && it->second == label;
    if (!linked || v.largest < consistency.linked_min_support) {
      v.kept.clear();
    } else {
      result.deferred += static_cast<int>(v.kept.size());
    }
  }
  // The separators it leaves out (of the pairs it checks), summed over the team in that step.
  double rejected = 0.0;
  for (const auto& [other, v] : verdicts) {
    if (v.checked) rejected += static_cast<double>(pairs.at(other).size() - v.kept.size());
  }
  result.rejected_by_team = TeamSum(exchangeVerdicts(true, label, rejected), 1);
  // The support of the separators it checked (against what the pair keeps, when it is kept).
  for (const auto& [other, v] : verdicts) {
    if (!v.checked) continue;
    const std::vector<std::size_t>& list = pairs.at(other);
    for (std::size_t j = 0; j < list.size(); ++j) {
      result.support[list[j]] = v.kept.empty() ? 0 : v.support[j];
    }
    if (!v.kept.empty()) {
      for (std::size_t j : v.runner_up) result.runner_up.insert(list[j]);
    }
  }
  std::vector<bool> kept(problem.subgraph.factors().size(), true);
  for (const auto& [other, list] : pairs) {
    const auto theirs = kept_by_other.find(other);
    if (other < problem.robot && theirs == kept_by_other.end()) continue;
    const std::vector<double> verdict =
        other > problem.robot ? verdictWeights(other, true) : theirs->second;
    for (std::size_t j = 0; j < list.size(); ++j) {
      kept[list[j]] = verdict[j] == 1.0;
      if (other > problem.robot && !kept[list[j]]) ++result.rejected;
    }
  }
  result.kept = std::move(kept);
  return result;
}

}  // namespace moslam
