#include "moslam/distributed/dgs_driver.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/coarse_system.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robot_agent.h"
#include "moslam/geometry/so3.h"

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
  if (error_bound_window < 1 || error_bound_window > 64) {
    throw InvalidInputError("DGS options: error_bound_window must be in [1, 64], got " +
                            std::to_string(error_bound_window));
  }
  if (max_iterations < 1) {
    throw InvalidInputError("DGS options: max_iterations must be at least 1, got " +
                            std::to_string(max_iterations));
  }
  const Refinement& f = refinement;
  if (f.max_iterations < 1) {
    throw InvalidInputError("DGS options: refinement.max_iterations must be at least 1, got " +
                            std::to_string(f.max_iterations));
  }
  if (f.max_sweeps < 1) {
    throw InvalidInputError("DGS options: refinement.max_sweeps must be at least 1, got " +
                            std::to_string(f.max_sweeps));
  }
  auto non_negative = [](double v, const char* name) {
    if (!(v >= 0.0) || !std::isfinite(v)) {
      throw InvalidInputError(std::string("DGS options: refinement.") + name +
                              " must be finite and >= 0, got " + std::to_string(v));
    }
  };
  non_negative(f.relative_cost_tolerance, "relative_cost_tolerance");
  non_negative(f.absolute_cost_tolerance, "absolute_cost_tolerance");
  non_negative(f.sweep_tolerance, "sweep_tolerance");
  non_negative(f.cg_tolerance, "cg_tolerance");
  positive(f.initial_lambda, "refinement.initial_lambda");
  positive(f.min_lambda, "refinement.min_lambda");
  if (f.min_lambda > f.initial_lambda) {
    throw InvalidInputError("DGS options: refinement.min_lambda must be at most initial_lambda (" +
                            std::to_string(f.initial_lambda) + "), got " +
                            std::to_string(f.min_lambda));
  }
  positive(f.max_lambda, "refinement.max_lambda");
  if (f.coarse_piece_poses > 0 && (f.preconditioner != RefinePreconditioner::kTwoLevel ||
                                   f.solver != RefineSolver::kConjugateGradient)) {
    throw InvalidInputError(
        "DGS options: refinement.coarse_piece_poses > 0 needs the conjugate-gradient solver with "
        "the two-level preconditioner (the pieces are its coarse space)");
  }
  if (f.max_backtracks < 0 || f.max_backtracks > 30) {
    throw InvalidInputError("DGS options: refinement.max_backtracks must be in [0, 30], got " +
                            std::to_string(f.max_backtracks));
  }
  if (!(f.gamma > 0.0 && f.gamma < 2.0)) {
    throw InvalidInputError("DGS options: refinement.gamma must be in (0, 2), got " +
                            std::to_string(f.gamma));
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
    case StageStatus::kNoDecreasingStep:
      return "no decreasing step";
  }
  return "unknown";
}

std::string ToString(RefineSolver solver) {
  return solver == RefineSolver::kSweeps ? "sweeps" : "cg";
}

std::string ToString(RefinePreconditioner preconditioner) {
  return preconditioner == RefinePreconditioner::kSweeps ? "sweeps" : "two-level";
}

RefinePreconditioner RefinePreconditionerFromString(const std::string& text) {
  if (text == "sweeps") return RefinePreconditioner::kSweeps;
  if (text == "two-level") return RefinePreconditioner::kTwoLevel;
  throw InvalidInputError("refinement preconditioner must be sweeps or two-level, got '" + text +
                          "'");
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
  agent_options.refine_gamma = options_.refinement.gamma;
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
    if (s.iteration < 1) {
      throw InvalidInputError("DGS faults: a robot stops answering at a sweep (refinement: a "
                              "step) >= 1");
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

void DgsDriver::runSweeps(DgsStage /*stage*/, DgsIterationStats& stats, bool reverse) {
  std::vector<Wire> pending;
  std::vector<int> order = order_;
  if (reverse) std::reverse(order.begin(), order.end());
  for (int r : order) {
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
}

ControlMessage DgsDriver::sendControl(const ControlMessage& m, int /*to*/,
                                      DgsIterationStats& stats) {
  const std::vector<std::uint8_t> bytes = EncodeControlMessage(m);
  ++stats.messages;
  ++stats.control_messages;
  stats.bytes += static_cast<std::int64_t>(bytes.size());
  stats.control_bytes += static_cast<std::int64_t>(bytes.size());
  return DecodeControlMessage(bytes);
}

void DgsDriver::runStage(DgsStage stage, DgsStageReport& report) {
  using Clock = std::chrono::steady_clock;
  const double eta = stage == DgsStage::kRotation ? options_.eta_rotation : options_.eta_pose;
  startStage(stage);
  const bool by_cg = stage == DgsStage::kPose &&
                     options_.pose_solver == DgsOptions::PoseSolver::kConjugateGradient;
  // Sweep 0: every robot starts knowing its neighbours' initial estimates (not initialised).
  if (!options_.flagged_initialisation) recordSweep(sendInitialEstimates(stage), report);
  report.status = StageStatus::kMaxIterations;
  // Conjugate gradients: with flagged initialisation the flagged sweeps first, until no robot is
  // left to initialise, then the conjugate gradients from their values (DgsOptions::pose_solver).
  if (by_cg && !options_.flagged_initialisation) {
    runPoseByConjugateGradients(report, 0);
    return;
  }
  int initialised = 0;
  for (int it = 1; it <= options_.max_iterations; ++it) {
    const auto start = Clock::now();
    updateSilence(stage, it);
    DgsIterationStats stats;
    stats.stage = stage;
    stats.iteration = it;
    runSweeps(stage, stats, false);
    const StageStopRule rule = stopRule(eta);
    stats.max_change = rule.maxChange();
    const bool stop = !by_cg && rule.converged();
    // Two-level: the correction belongs to this sweep (its messages, bytes and time).
    if (!by_cg && !stop && options_.coarse_correction && coarseCorrection(stage, it, stats)) {
      ++report.coarse_corrections;
    }
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    recordSweep(stats, report);
    if (progress_.on_sweep) progress_.on_sweep(stats);
    report.iterations = it;
    report.final_change = stats.max_change;
    if (by_cg) {
      if (!FlaggedSweepsDone(rule, initialised)) {
        initialised = rule.initialisedRobots();
        continue;
      }
      if (it < options_.max_iterations) runPoseByConjugateGradients(report, it);
      return;
    }
    report.final_error_bound = rule.maxBound();
    if (stop) {
      report.status = StageStatus::kConverged;
      break;
    }
  }
}

void DgsDriver::startStage(DgsStage stage) {
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
}

DgsIterationStats DgsDriver::sendInitialEstimates(DgsStage stage) {
  const auto start = std::chrono::steady_clock::now();
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
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

StageStopRule DgsDriver::stopRule(double eta) const {
  StageStopRule rule(options_.stopping, eta);
  for (int r : order_) {
    if (!live(r)) continue;
    const RobotAgent& a = *agents_.at(r);
    constexpr double kInf = std::numeric_limits<double>::infinity();
    rule.add(a.initialised(), a.initialised() ? a.lastChange() : kInf,
             a.initialised() ? a.errorBound(options_.error_bound_window) : kInf);
  }
  return rule;
}

void DgsDriver::recordSweep(const DgsIterationStats& stats, DgsStageReport& report) {
  report.messages += stats.messages;
  report.bytes += stats.bytes;
  result_.messages += stats.messages;
  result_.bytes += stats.bytes;
  result_.history.push_back(stats);
}

CoarseMessage DgsDriver::sendCoarse(const CoarseMessage& m, int to, DgsIterationStats& stats) {
  const std::vector<std::uint8_t> bytes = EncodeCoarseMessage(m);
  if (m.sender == to) return m;  // the coordinator's own share: no network
  ++stats.messages;
  stats.bytes += static_cast<std::int64_t>(bytes.size());
  ++stats.coarse_messages;
  stats.coarse_bytes += static_cast<std::int64_t>(bytes.size());
  return DecodeCoarseMessage(bytes);
}

bool DgsDriver::coarseCorrection(DgsStage stage, int iteration, DgsIterationStats& stats) {
  std::vector<int> robots;
  std::set<int> absent;
  for (const auto& [r, agent] : agents_) {
    if (!live(r)) absent.insert(r);
  }
  for (int r : order_) {
    if (!live(r)) continue;
    if (!agents_.at(r)->coarseReady(absent)) return false;
    robots.push_back(r);
  }
  if (robots.empty()) return false;
  // The coarse unknowns in robot id order: the order every robot of a network team assembles
  // them in (robot_program.h), so both reach the same numbers.
  std::sort(robots.begin(), robots.end());
  const int k = stage == DgsStage::kRotation ? 3 : 6;
  const int ncols = stage == DgsStage::kRotation ? 3 : 1;
  CoarseSystem coarse(robots, k);
  Eigen::MatrixXd B(coarse.rows(), ncols);
  const int c = coordinator();
  // Every robot sends its rows to the coordinator.
  for (int r : robots) {
    const CoarseMessage m = ShareMessage(CoarseKind::kShare, stage, r,
                                         static_cast<std::uint32_t>(iteration),
                                         agents_.at(r)->coarseShare());
    B.middleRows(coarse.index(r), k) = coarse.addShare(sendCoarse(m, c, stats));
  }
  Eigen::MatrixXd Y;
  if (!coarse.factorize() || !coarse.solve(B, &Y)) return false;
  // The coordinator sends every robot its own y and its neighbouring robots'.
  for (int r : robots) {
    RobotAgent& a = *agents_.at(r);
    const CoarseMessage got = sendCoarse(
        coarse.solutionFor(r, a.neighbourRobots(), Y, stage, c,
                           static_cast<std::uint32_t>(iteration)),
        r, stats);
    std::map<int, Eigen::MatrixXd> y;
    for (const auto& [s, block] : got.blocks) y[s] = UnflattenMatrix(block, k, ncols);
    a.applyCoarse(y);
  }
  return true;
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

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

int DgsDriver::coordinator() const {
  for (int r : order_) {
    if (live(r)) return r;
  }
  return -1;
}

void DgsDriver::openSweep(RefineRun& run) {
  closeSweep(run);
  run.current = run.pending;
  run.pending = DgsIterationStats();
  run.current.stage = run.stage;
  run.current.iteration =
      run.stage == DgsStage::kRefine ? ++result_.refine.sweeps : ++result_.pose.iterations;
  run.current.refine_step = run.step;
  run.open = true;
  run.sweep_start = Clock::now();
}

void DgsDriver::closeSweep(RefineRun& run) {
  if (!run.open) return;
  DgsIterationStats& stats = run.current;
  stats.seconds += Since(run.sweep_start);
  if (run.stage == DgsStage::kRefine) {
    RefineReport& report = result_.refine;
    report.messages += stats.messages;
    report.bytes += stats.bytes;
    report.control_messages += stats.control_messages;
    report.control_bytes += stats.control_bytes;
    report.coarse_messages += stats.coarse_messages;
    report.coarse_bytes += stats.coarse_bytes;
  } else {
    result_.pose.messages += stats.messages;
    result_.pose.bytes += stats.bytes;
  }
  result_.messages += stats.messages;
  result_.bytes += stats.bytes;
  result_.history.push_back(stats);
  if (progress_.on_sweep) progress_.on_sweep(stats);
  run.open = false;
}

DgsIterationStats& DgsDriver::traffic(RefineRun& run) {
  return run.open ? run.current : run.pending;
}

double DgsDriver::gather(RefineRun& run, ControlKind kind, std::uint32_t sweep,
                         const std::function<double(RobotAgent&)>& share, Reduce reduce,
                         double* max_second, const std::function<double(RobotAgent&)>& second) {
  const int c = coordinator();
  double total = 0.0;
  if (max_second) *max_second = 0.0;
  // Summed in robot id order, so the result does not depend on the order of arrival.
  for (auto& [r, agent] : agents_) {
    if (!live(r)) continue;
    ControlMessage m;
    m.kind = kind;
    m.sender = r;
    m.round = static_cast<std::uint32_t>(run.step);
    m.sweep = sweep;
    m.value[0] = share(*agent);
    if (second) m.value[1] = second(*agent);
    const ControlMessage got = r == c ? m : sendControl(m, c, traffic(run));
    total = reduce == Reduce::kMax ? std::max(total, got.value[0]) : total + got.value[0];
    if (max_second) *max_second = std::max(*max_second, got.value[1]);
  }
  return total;
}

void DgsDriver::broadcast(RefineRun& run, std::uint32_t sweep, bool stop, double coefficient) {
  const int c = coordinator();
  for (int r : order_) {
    if (!live(r) || r == c) continue;
    ControlMessage d;
    d.kind = ControlKind::kBroadcast;
    d.sender = c;
    d.round = static_cast<std::uint32_t>(run.step);
    d.sweep = sweep;
    d.flags = stop ? kStopLinearSolve : 0;
    d.value[0] = coefficient;
    sendControl(d, r, traffic(run));
  }
}

double DgsDriver::observedChange() const {
  double change = 0.0;
  for (int r : order_) {
    if (!live(r)) continue;
    const RobotAgent& a = *agents_.at(r);
    if (a.initialised()) change = std::max(change, a.lastChange());
  }
  return change;
}

void DgsDriver::solveBySweeps(RefineRun& run, RefineStepSummary& summary) {
  const DgsOptions::Refinement& opt = options_.refinement;
  for (int sweep = 1; sweep <= opt.max_sweeps; ++sweep) {
    openSweep(run);
    runSweeps(DgsStage::kRefine, run.current, false);
    // Every robot reports (its change, ||delta_r||); the coordinator decides and broadcasts.
    double max_increment = 0.0;
    const double max_change = gather(
        run, ControlKind::kReport, static_cast<std::uint32_t>(sweep),
        [](RobotAgent& a) { return a.initialised() ? a.lastChange() : 0.0; }, Reduce::kMax,
        &max_increment, [](RobotAgent& a) { return a.incrementNorm(); });
    const bool stop = max_change <= opt.sweep_tolerance * max_increment;
    broadcast(run, static_cast<std::uint32_t>(sweep), stop, 0.0);
    run.current.max_change = max_change;
    run.current.max_increment = max_increment;
    summary.sweeps = sweep;
    summary.linear_converged = stop;
    if (stop) break;
  }
}

std::vector<int> DgsDriver::refineCoarseRobots() const {
  std::vector<int> robots;
  for (int r : order_) {
    if (!live(r)) continue;
    if (!agents_.at(r)->refineCoarseReady()) return {};
    robots.push_back(r);
  }
  std::sort(robots.begin(), robots.end());  // robot id order, as coarseCorrection()
  return robots;
}

std::unique_ptr<CoarseSystem> DgsDriver::refineCoarseSystem(DgsStage stage,
                                                            DgsIterationStats& stats,
                                                            std::uint32_t sweep) {
  const std::vector<int> robots = refineCoarseRobots();
  if (robots.empty()) return nullptr;
  auto coarse = std::make_unique<CoarseSystem>(robots, 6);
  const int c = coordinator();
  for (int r : robots) {
    const CoarseMessage m =
        ShareMessage(CoarseKind::kMatrix, stage, r, sweep, agents_.at(r)->refineCoarseMatrix());
    coarse->addShare(sendCoarse(m, c, stats));
  }
  if (!coarse->factorize()) return nullptr;
  return coarse;
}

std::unique_ptr<PieceCoarseSystem> DgsDriver::refinePieceSystem(DgsIterationStats& stats,
                                                                std::uint32_t sweep) {
  const std::vector<int> robots = refineCoarseRobots();
  if (robots.empty()) return nullptr;
  auto coarse = std::make_unique<PieceCoarseSystem>();
  const int c = coordinator();
  for (int r : robots) {
    coarse->addMatrix(sendCoarse(
        agents_.at(r)->refinePieceMatrix(options_.refinement.coarse_piece_poses, sweep), c, stats));
  }
  if (!coarse->factorize()) return nullptr;
  return coarse;
}

void DgsDriver::refinePieceCorrection(const PieceCoarseSystem& coarse, DgsIterationStats& stats,
                                      std::uint32_t sweep) {
  const int c = coordinator();
  std::vector<CoarseMessage> residuals;
  for (int r : order_) {
    if (!live(r) || !coarse.has(r)) continue;
    residuals.push_back(sendCoarse(agents_.at(r)->refinePieceResidual(sweep), c, stats));
  }
  Eigen::VectorXd Y;
  if (!coarse.solve(residuals, &Y)) return;
  for (int r : order_) {
    if (!live(r) || !coarse.has(r)) continue;
    RobotAgent& a = *agents_.at(r);
    a.applyRefinePieces(
        sendCoarse(coarse.solutionFor(r, a.neighbourRobots(), Y, c, sweep), r, stats));
  }
  ++result_.refine.coarse_corrections;
}

void DgsDriver::refineCoarseCorrection(DgsStage stage, const CoarseSystem& coarse,
                                       DgsIterationStats& stats, std::uint32_t sweep) {
  const int c = coordinator();
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(coarse.rows(), 1);
  for (int r : order_) {
    if (!live(r) || coarse.index(r) < 0) continue;
    CoarseMessage m;
    m.kind = CoarseKind::kResidual;
    m.stage = stage;
    m.sender = r;
    m.iteration = sweep;
    m.k = 6;
    m.ncols = 1;
    m.residual = FlattenMatrix(agents_.at(r)->refineCoarseResidual());
    const CoarseMessage got = sendCoarse(m, c, stats);
    B.middleRows(coarse.index(r), 6) = UnflattenMatrix(got.residual, 6, 1);
  }
  Eigen::MatrixXd Y;
  if (!coarse.solve(B, &Y)) return;
  for (int r : order_) {
    if (!live(r) || coarse.index(r) < 0) continue;
    RobotAgent& a = *agents_.at(r);
    const CoarseMessage got = sendCoarse(
        coarse.solutionFor(r, a.neighbourRobots(), Y, stage, c, sweep), r, stats);
    std::map<int, Eigen::MatrixXd> y;
    for (const auto& [s, block] : got.blocks) y[s] = UnflattenMatrix(block, 6, 1);
    a.applyRefineCoarse(y);
  }
  ++(stage == DgsStage::kRefine ? result_.refine.coarse_corrections
                                 : result_.pose.coarse_corrections);
}

CgOutcome DgsDriver::solveByConjugateGradients(RefineRun& run, const CgGoal& goal) {
  const DgsOptions::Refinement& opt = options_.refinement;
  const DgsStage stage = run.stage;
  CgOutcome outcome;
  int& sweeps = outcome.sweeps;
  // The coarse system of the two-level preconditioner, set up at its first use.
  std::unique_ptr<CoarseSystem> coarse;
  std::unique_ptr<PieceCoarseSystem> pieces;  // by pieces (refinement.coarse_piece_poses)
  const bool by_pieces = stage == DgsStage::kRefine && opt.coarse_piece_poses > 0;
  bool coarse_tried = false;
  // z = M^-1 res from z = 0: symmetric block Gauss-Seidel (a forward and a backward sweep) or
  // one block Jacobi sweep; two-level: a coarse correction after the first sweep (and, with
  // Jacobi, a second sweep after it, so that M stays symmetric).
  auto precondition = [&]() {
    for (int r : order_) {
      if (live(r)) agents_.at(r)->startPreconditioner();
    }
    if (opt.preconditioner == RefinePreconditioner::kTwoLevel && !coarse_tried) {
      coarse_tried = true;
      const auto sweep = static_cast<std::uint32_t>(sweeps);
      if (by_pieces) {
        pieces = refinePieceSystem(traffic(run), sweep);
      } else {
        coarse = refineCoarseSystem(stage, traffic(run), sweep);
      }
    }
    const bool gauss_seidel = options_.order == SweepOrder::kGaussSeidel;
    const bool two_level = coarse || pieces;
    const int passes = gauss_seidel || two_level ? 2 : 1;
    for (int pass = 0; pass < passes; ++pass) {
      openSweep(run);
      runSweeps(stage, run.current, gauss_seidel && pass == 1);
      ++sweeps;
      if (pass == 0 && coarse) {
        refineCoarseCorrection(stage, *coarse, run.current, static_cast<std::uint32_t>(sweeps));
      }
      if (pass == 0 && pieces) {
        refinePieceCorrection(*pieces, run.current, static_cast<std::uint32_t>(sweeps));
      }
      run.current.max_change = observedChange();
    }
  };
  auto all = [&](const std::function<void(RobotAgent&)>& f) {
    for (int r : order_) {
      if (live(r)) f(*agents_.at(r));
    }
  };
  CgDecisions cg(goal);  // the coordinator's decisions (cg_decisions.h), broadcast
  precondition();
  const bool started =
      cg.start(gather(run, ControlKind::kReport, static_cast<std::uint32_t>(sweeps),
                      [](RobotAgent& a) { return a.residualDot(); }, Reduce::kSum));
  broadcast(run, static_cast<std::uint32_t>(sweeps), !started, 0.0);
  if (started) {
    all([](RobotAgent& a) { a.firstDirection(); });
    while (true) {
      // p.Hp summed, and the largest ||p_r|| (a robot's change is |alpha| ||p_r||).
      double max_direction = 0.0;
      const double pq = gather(
          run, ControlKind::kReport, static_cast<std::uint32_t>(sweeps),
          [](RobotAgent& a) { return a.curvature(); }, Reduce::kSum, &max_direction,
          [](RobotAgent& a) { return a.directionNorm(); });
      const std::optional<double> alpha = cg.stepLength(pq, max_direction);
      broadcast(run, static_cast<std::uint32_t>(sweeps), !alpha, alpha.value_or(0.0));
      if (!alpha) break;
      all([a = *alpha](RobotAgent& agent) { agent.advance(a); });
      run.current.max_change = cg.change();
      precondition();
      const CgDecisions::Next next =
          cg.next(gather(run, ControlKind::kReport, static_cast<std::uint32_t>(sweeps),
                         [](RobotAgent& a) { return a.residualDot(); }, Reduce::kSum),
                  sweeps);
      run.current.residual = next.relative;
      broadcast(run, static_cast<std::uint32_t>(sweeps), next.stop, next.beta);
      if (next.stop) break;
      all([beta = next.beta](RobotAgent& a) { a.nextDirection(beta); });
    }
  }
  outcome.converged = cg.converged();
  outcome.model_decrease = cg.modelDecrease();
  return outcome;
}

void DgsDriver::runPoseByConjugateGradients(DgsStageReport& report, int sweeps_before) {
  RefineRun run;
  run.stage = DgsStage::kPose;
  CgGoal goal;
  goal.eta_change = options_.eta_pose;
  goal.max_sweeps = options_.max_iterations - sweeps_before;
  const CgOutcome outcome = solveByConjugateGradients(run, goal);
  if (run.pending.messages > 0) {  // traffic after the last sweep (the final decision)
    openSweep(run);
  }
  closeSweep(run);
  report.status = outcome.converged ? StageStatus::kConverged : StageStatus::kMaxIterations;
  report.iterations = result_.pose.iterations;
  report.final_change = result_.history.empty() ? 0.0 : result_.history.back().max_change;
}

const RefineReport& DgsDriver::runRefineStage() {
  RefineReport& report = result_.refine;
  if (result_.pose.status == StageStatus::kNotRun || report.status != StageStatus::kNotRun) {
    throw InvalidInputError("DGS: the refinement runs once, after the pose stage");
  }
  const auto stage_start = Clock::now();
  previous_.clear();
  RefineRun run;
  updateSilence(DgsStage::kRefine, 0);
  for (int r : order_) {
    if (live(r)) agents_.at(r)->startRefine();
  }
  tellSilence(run);

  report.status = StageStatus::kMaxIterations;
  if (coordinator() < 0) {
    report.status = StageStatus::kConverged;  // nobody left to refine
  } else {
    report.coordinator = coordinator();
    double cost = refineCost(run, false);
    report.initial_cost = cost;
    report.final_cost = cost;
    double lambda = 0.0;
    for (int step = 1; step <= options_.refinement.max_iterations; ++step) {
      run.step = step;
      updateSilence(DgsStage::kRefine, step);
      if (tellSilence(run)) {
        if (coordinator() < 0) {
          report.status = StageStatus::kConverged;
          break;
        }
        report.coordinator = coordinator();
        cost = refineCost(run, false);  // the shares changed
      }
      if (refineStep(run, cost, lambda)) break;
    }
  }
  // Traffic after the last sweep (none unless the refinement ended before sweeping).
  if (run.pending.messages > 0) {
    openSweep(run);
    closeSweep(run);
  }
  for (int r : order_) {
    if (live(r)) agents_.at(r)->finishRefine();
  }
  report.seconds = Since(stage_start);
  result_.seconds += report.seconds;
  return report;
}

bool DgsDriver::tellSilence(RefineRun& run) {
  bool changed = false;
  for (const auto& [robot, silence] : silent_) {
    if (!run.told_silent.insert(robot).second) continue;
    changed = true;
    for (auto& [r, agent] : agents_) {
      if (live(r)) agent->setUnresponsive(robot);
    }
  }
  return changed;
}

double DgsDriver::refineCost(RefineRun& run, bool candidate) {
  return gather(
      run, ControlKind::kCostReport, 0,
      [candidate](RobotAgent& a) { return a.costShare(candidate); }, Reduce::kSum);
}

bool DgsDriver::refineStep(RefineRun& run, double& cost, double& lambda) {
  const auto step_start = Clock::now();
  const DgsOptions::Refinement& opt = options_.refinement;
  RefineReport& report = result_.refine;
  RefineStepSummary summary;
  summary.iteration = run.step;
  summary.lambda = lambda;
  summary.cost_before = cost;
  for (int r : order_) {
    if (live(r)) agents_.at(r)->beginStep(lambda);
  }
  if (opt.solver == RefineSolver::kConjugateGradient) {
    CgGoal goal;
    goal.tolerance = opt.cg_tolerance;
    goal.max_sweeps = opt.max_sweeps;
    const CgOutcome outcome = solveByConjugateGradients(run, goal);
    summary.sweeps = outcome.sweeps;
    summary.linear_converged = outcome.converged;
    summary.predicted_decrease = outcome.model_decrease;
  } else {
    solveBySweeps(run, summary);
  }
  // The step's cost; the coordinator's decision, broadcast: halve the step (and report the cost
  // there), or accept / reject it.
  const int c = coordinator();
  auto broadcastDecision = [&](std::uint8_t flags, double value) {
    for (int r : order_) {
      if (!live(r)) continue;
      ControlMessage d;
      d.kind = ControlKind::kStepDecision;
      d.sender = c;
      d.round = static_cast<std::uint32_t>(run.step);
      d.sweep = static_cast<std::uint32_t>(summary.backtracks);
      d.flags = flags;
      d.value[0] = value;
      d.value[1] = lambda;
      const ControlMessage got = r == c ? d : sendControl(d, r, traffic(run));
      if ((got.flags & kHalveStep) != 0) agents_.at(r)->scaleStep(0.5);
      if ((got.flags & kAcceptStep) != 0) agents_.at(r)->acceptStep();
    }
  };
  summary.cost_candidate = refineCost(run, true);
  RefineDecision decision;
  while ((decision = DecideRefineStep(summary, opt, lambda, report)).backtrack) {
    broadcastDecision(kHalveStep, summary.cost_candidate);
    ++summary.backtracks;
    summary.step_scale *= 0.5;
    summary.cost_candidate = refineCost(run, true);
  }
  const double candidate = summary.cost_candidate;
  const bool accept = decision.accept;
  const bool finished = decision.finished;
  broadcastDecision(
      static_cast<std::uint8_t>((accept ? kAcceptStep : 0) | (finished ? kRefineFinished : 0)),
      accept ? candidate : cost);
  closeSweep(run);
  if (accept) cost = candidate;
  summary.accepted = accept;
  summary.bytes = report.bytes;
  report.iterations = run.step;
  report.final_cost = cost;
  summary.seconds = Since(step_start);
  report.steps.push_back(summary);
  if (progress_.on_refine_step) progress_.on_refine_step(summary);
  return finished;
}

RefineDecision DecideRefineStep(const RefineStepSummary& s, const DgsOptions::Refinement& opt,
                                double& lambda, RefineReport& report) {
  const double cost = s.cost_before;
  const double candidate = s.cost_candidate;
  const double tolerance = opt.relative_cost_tolerance * cost;
  const bool halved = s.backtracks > 0;
  RefineDecision d;
  // A halved step must lower F by a fraction of what the model predicts for it (Armijo, with
  // the model's decrease of the whole step scaled by the step's length); whether the refinement
  // has converged is judged on whole steps only.
  const bool lowers =
      halved ? cost - candidate >= kArmijoFraction * s.step_scale * s.predicted_decrease
             : candidate <= cost;
  if (lowers) {
    d.accept = true;
    d.finished =
        (!halved && cost - candidate <= tolerance) || candidate <= opt.absolute_cost_tolerance;
    if (lambda > 0.0) {
      lambda /= 10.0;
      if (lambda < opt.min_lambda) lambda = 0.0;
    }
  } else if (!halved && (candidate - cost <= tolerance || cost <= opt.absolute_cost_tolerance)) {
    d.finished = true;  // rounding at the optimum: nothing left to gain
  } else if (s.backtracks < opt.max_backtracks) {
    ++report.backtracks;
    d.backtrack = true;
    return d;
  } else {
    ++report.rejected;
    lambda = lambda == 0.0 ? opt.initial_lambda : 10.0 * lambda;
    if (lambda > opt.max_lambda) {
      d.finished = true;
      report.status = StageStatus::kNoDecreasingStep;
    }
  }
  if (d.finished && report.status != StageStatus::kNoDecreasingStep) {
    report.status = StageStatus::kConverged;
  }
  if (s.iteration == opt.max_iterations) d.finished = true;
  return d;
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
  if (options.refine) driver.runRefineStage();
  return driver.result();
}

}  // namespace moslam
