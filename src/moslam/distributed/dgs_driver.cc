#include "moslam/distributed/dgs_driver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robot_agent.h"

namespace moslam {

void DgsOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw InvalidInputError(std::string("DGS options: ") + name +
                              " must be positive and finite, got " + std::to_string(v));
    }
  };
  positive(eta_rotation, "eta_rotation");
  positive(eta_pose, "eta_pose");
  if (!(gamma > 0.0 && gamma < 2.0)) {
    throw InvalidInputError("DGS options: gamma must be in (0, 2), got " + std::to_string(gamma));
  }
  if (max_iterations < 1) {
    throw InvalidInputError("DGS options: max_iterations must be at least 1, got " +
                            std::to_string(max_iterations));
  }
}

std::string ToString(StageStatus status) {
  switch (status) {
    case StageStatus::kNotRun:
      return "not run";
    case StageStatus::kConverged:
      return "converged";
    case StageStatus::kMaxIterations:
      return "max iterations";
  }
  return "unknown";
}

std::vector<int> FlaggedRobotOrder(const std::vector<int>& robots,
                                   const std::vector<std::map<int, int>>& links) {
  if (links.size() != robots.size()) {
    throw InvalidInputError("robot order: one link table per robot expected");
  }
  std::vector<int> order;
  if (robots.empty()) return order;
  std::set<int> ordered;
  const int first = std::count(robots.begin(), robots.end(), 0) ? 0 : robots.front();
  order.push_back(first);
  ordered.insert(first);
  while (true) {
    std::vector<std::pair<int, int>> candidates;  // (-links to the ordered set, robot)
    for (std::size_t i = 0; i < robots.size(); ++i) {
      if (ordered.count(robots[i])) continue;
      int count = 0;
      for (const auto& [j, n] : links[i]) {
        if (ordered.count(j)) count += n;
      }
      if (count > 0) candidates.emplace_back(-count, robots[i]);
    }
    if (candidates.empty()) break;
    std::sort(candidates.begin(), candidates.end());
    for (const auto& [neg, robot] : candidates) {
      order.push_back(robot);
      ordered.insert(robot);
    }
  }
  for (int r : robots) {
    if (!ordered.count(r)) order.push_back(r);  // not linked to robot 0's part of the graph
  }
  return order;
}

DgsDriver::DgsDriver(const PoseGraph& graph, const Values& initial, const DgsOptions& options,
                     const FaultInjection& faults)
    : options_(options), faults_(faults), rng_state_(faults.seed * 2654435761ull + 1) {
  options_.validate();
  const Key anchor = GaugeAnchor(graph);
  const std::vector<Key> unreachable = UnreachableFrom(graph, anchor);
  if (!unreachable.empty()) {
    throw UnderdeterminedError("DGS: " + std::to_string(unreachable.size()) +
                               " variables (first " + ToString(unreachable.front()) +
                               ") are not connected to the anchor " + ToString(anchor));
  }
  AgentOptions agent_options;
  agent_options.gamma = options_.gamma;
  agent_options.flagged_initialisation = options_.flagged_initialisation;
  agent_options.weight_by_information = options_.weight_by_information;
  std::vector<int> robots;
  std::vector<std::map<int, int>> links;
  for (const RobotSubgraph& sub : PartitionByRobot(graph)) {
    if (sub.robot > kMaxMessageRobot) {
      throw InvalidInputError("DGS: robot id " + std::to_string(sub.robot) +
                              " does not fit in a message (at most 65535)");
    }
    auto agent = std::make_unique<RobotAgent>(sub.robot, sub.graph, initial, anchor, agent_options);
    robots.push_back(sub.robot);
    links.push_back(agent->neighbourLinks());
    agents_.emplace(sub.robot, std::move(agent));
  }
  if (options_.flagged_initialisation) {
    order_ = FlaggedRobotOrder(robots, links);
  } else {
    order_ = robots;
  }
  for (const SilentRobot& s : faults_.silent) {
    if (agents_.count(s.robot) == 0) {
      throw InvalidInputError("DGS faults: robot " + std::to_string(s.robot) +
                              " owns no variable, it cannot stop answering");
    }
    if (s.iteration < 1 || s.stage == DgsStage::kRefine) {
      throw InvalidInputError("DGS faults: a robot stops answering at a sweep >= 1 of the "
                              "rotation or pose stage");
    }
  }
  result_.order = order_;
}

DgsDriver::~DgsDriver() = default;

RobotAgent& DgsDriver::agent(int robot) {
  const auto it = agents_.find(robot);
  if (it == agents_.end()) {
    throw InvalidInputError("DGS: no agent for robot " + std::to_string(robot));
  }
  return *it->second;
}

bool DgsDriver::live(int robot) const { return silent_.count(robot) == 0; }

void DgsDriver::updateSilence(DgsStage stage, int iteration) {
  for (const SilentRobot& s : faults_.silent) {
    if (!live(s.robot)) continue;
    const bool reached = s.stage < stage || (s.stage == stage && s.iteration <= iteration);
    if (reached) silent_[s.robot] = {s.robot, stage, iteration};
  }
}

std::vector<DgsDriver::Wire> DgsDriver::encodeOutgoing(int robot) const {
  std::vector<Wire> wires;
  for (const OutgoingMessage& o : agents_.at(robot)->outgoing()) {
    wires.push_back({robot, o.to, EncodeMessage(o.message)});
  }
  return wires;
}

void DgsDriver::transmit(std::vector<Wire> batch, DgsIterationStats& stats) {
  auto next_random = [this]() {
    rng_state_ ^= rng_state_ << 13;
    rng_state_ ^= rng_state_ >> 7;
    rng_state_ ^= rng_state_ << 17;
    return rng_state_;
  };
  std::vector<const Wire*> sends;
  for (const Wire& w : batch) {
    sends.push_back(&w);
    if (faults_.duplicate) sends.push_back(&w);
  }
  if (faults_.shuffle) {
    for (std::size_t i = sends.size(); i > 1; --i) {
      std::swap(sends[i - 1], sends[next_random() % i]);
    }
  }
  std::vector<Wire> replay;
  if (faults_.replay_stale) {
    std::set<int> senders;
    for (const Wire& w : batch) senders.insert(w.from);
    for (int s : senders) {
      const auto it = previous_.find(s);
      if (it != previous_.end()) replay.insert(replay.end(), it->second.begin(), it->second.end());
    }
  }
  for (const Wire& w : replay) sends.push_back(&w);
  for (const Wire* w : sends) {
    ++stats.messages;
    stats.bytes += static_cast<std::int64_t>(w->bytes.size());
    if (!live(w->to)) continue;  // sent, but nobody answers there any more
    const auto it = agents_.find(w->to);
    if (it == agents_.end()) continue;
    it->second->receive(DecodeMessage(w->bytes));
  }
  if (faults_.replay_stale) {
    std::map<int, std::vector<Wire>> current;
    for (Wire& w : batch) current[w.from].push_back(std::move(w));
    for (auto& [s, wires] : current) previous_[s] = std::move(wires);
  }
}

void DgsDriver::runStage(DgsStage stage, DgsStageReport& report) {
  using Clock = std::chrono::steady_clock;
  const double eta = stage == DgsStage::kRotation ? options_.eta_rotation : options_.eta_pose;
  previous_.clear();
  updateSilence(stage, 0);  // silences scheduled in an earlier stage that ended before them
  for (int r : order_) {
    if (!live(r)) continue;
    RobotAgent& a = *agents_.at(r);
    if (stage == DgsStage::kRotation) {
      a.startRotation();
    } else {
      a.startPose();
    }
  }
  auto record = [&](DgsIterationStats& stats) {
    report.messages += stats.messages;
    report.bytes += stats.bytes;
    result_.messages += stats.messages;
    result_.bytes += stats.bytes;
    result_.history.push_back(stats);
  };
  if (!options_.flagged_initialisation) {
    // Every robot starts knowing its neighbours' initial estimates (not initialised).
    const auto start = Clock::now();
    DgsIterationStats stats;
    stats.stage = stage;
    stats.iteration = 0;
    std::vector<Wire> batch;
    for (int r : order_) {
      if (!live(r)) continue;
      std::vector<Wire> wires = encodeOutgoing(r);
      batch.insert(batch.end(), std::make_move_iterator(wires.begin()),
                   std::make_move_iterator(wires.end()));
    }
    transmit(std::move(batch), stats);
    stats.max_change = std::numeric_limits<double>::infinity();
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    record(stats);
  }
  report.status = StageStatus::kMaxIterations;
  for (int it = 1; it <= options_.max_iterations; ++it) {
    const auto start = Clock::now();
    updateSilence(stage, it);
    DgsIterationStats stats;
    stats.stage = stage;
    stats.iteration = it;
    std::vector<Wire> pending;
    for (int r : order_) {
      if (!live(r)) continue;
      RobotAgent& a = *agents_.at(r);
      if (!a.iterate()) continue;  // waiting (flagged initialisation): nothing new to send
      ++stats.robots_solved;
      std::vector<Wire> wires = encodeOutgoing(r);
      if (options_.order == SweepOrder::kGaussSeidel) {
        transmit(std::move(wires), stats);
      } else {
        pending.insert(pending.end(), std::make_move_iterator(wires.begin()),
                       std::make_move_iterator(wires.end()));
      }
    }
    if (options_.order == SweepOrder::kJacobi) transmit(std::move(pending), stats);
    bool converged = true;
    int live_robots = 0;
    for (int r : order_) {
      if (!live(r)) continue;
      ++live_robots;
      const RobotAgent& a = *agents_.at(r);
      const double change =
          a.initialised() ? a.lastChange() : std::numeric_limits<double>::infinity();
      stats.max_change = std::max(stats.max_change, change);
      converged = converged && a.initialised() && change <= eta;
    }
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    record(stats);
    report.iterations = it;
    report.final_change = stats.max_change;
    if (converged && live_robots > 0) {
      report.status = StageStatus::kConverged;
      break;
    }
  }
}

const DgsStageReport& DgsDriver::runRotationStage() {
  if (result_.rotation.status != StageStatus::kNotRun) {
    throw InvalidInputError("DGS: the rotation stage already ran");
  }
  const auto start = std::chrono::steady_clock::now();
  runStage(DgsStage::kRotation, result_.rotation);
  result_.seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result_.rotation;
}

const DgsStageReport& DgsDriver::runPoseStage() {
  if (result_.rotation.status == StageStatus::kNotRun ||
      result_.pose.status != StageStatus::kNotRun) {
    throw InvalidInputError("DGS: the pose stage runs once, after the rotation stage");
  }
  const auto start = std::chrono::steady_clock::now();
  runStage(DgsStage::kPose, result_.pose);
  for (int r : order_) {
    if (live(r)) agents_.at(r)->finish();
  }
  result_.seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result_.pose;
}

DgsResult DgsDriver::result() const {
  DgsResult out = result_;
  out.values.clear();
  out.duplicates_ignored = 0;
  out.stale_ignored = 0;
  for (const auto& [robot, agent] : agents_) {
    const Values v = agent->estimate();
    out.values.insert(v.begin(), v.end());
    out.duplicates_ignored += agent->duplicatesIgnored();
    out.stale_ignored += agent->staleIgnored();
  }
  out.silent.clear();
  for (const auto& [robot, report] : silent_) out.silent.push_back(report);
  return out;
}

DgsResult RunDgs(const PoseGraph& graph, const Values& initial, const DgsOptions& options,
                 const FaultInjection& faults) {
  DgsDriver driver(graph, initial, options, faults);
  driver.runRotationStage();
  driver.runPoseStage();
  return driver.result();
}

}  // namespace moslam
