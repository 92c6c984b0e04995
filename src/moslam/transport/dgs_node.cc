#include "moslam/transport/dgs_node.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <tuple>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/distributed/robot_agent.h"
#include "moslam/io/g2o.h"
#include "moslam/transport/group_formation.h"
#include "moslam/transport/node_journal.h"
#include "moslam/transport/record_bytes.h"
#include "moslam/transport/step_inbox.h"
#include "moslam/transport/step_record.h"

namespace moslam {

void DgsNodeOptions::validate() const {
  DriverOptions(*this).validate();
  auto positive = [](std::chrono::milliseconds v, const char* name) {
    if (v.count() <= 0) {
      throw InvalidInputError(std::string("DGS node options: ") + name + " must be positive");
    }
  };
  positive(join_timeout, "join_timeout");
  positive(leave_timeout, "leave_timeout");
  positive(stall_timeout, "stall_timeout");
  positive(finish_timeout, "finish_timeout");
  if (gnc) gnc->validate();
  if (!gnc && !robust.empty()) {
    throw InvalidInputError("DGS node options: a robust mask without gnc options");
  }
  if (!std::is_sorted(team.begin(), team.end()) ||
      std::adjacent_find(team.begin(), team.end()) != team.end() ||
      (!team.empty() && team.front() < 0)) {
    throw InvalidInputError("DGS node options: the team's robot ids must be distinct, "
                            "non-negative and increasing");
  }
  if (!gnc && separator_check) {
    throw InvalidInputError("DGS node options: a separator check without gnc options");
  }
  if (!separator_check && !checked.empty()) {
    throw InvalidInputError("DGS node options: a checked mask without a separator check");
  }
  if (separator_check) {
    RobustProgramOptions p;  // validates the check as the program will run it
    p.solver = DriverOptions(*this);
    p.gnc = *gnc;
    p.consistency = *separator_check;
    p.validate();
  }
}

DgsOptions DriverOptions(const DgsNodeOptions& o) {
  DgsOptions d = o.solver;
  d.order = SweepOrder::kJacobi;
  return d;
}

namespace {

using Clock = std::chrono::steady_clock;
using transport_detail::Fingerprint;

std::uint64_t RunFingerprint(int robot, const PoseGraph& g, const Values& initial,
                             const DgsOptions& o, const std::optional<GncOptions>& gnc,
                             const std::vector<bool>& robust,
                             const std::optional<SeparatorConsistencyOptions>& check,
                             const std::vector<bool>& checked, bool retest_left_out,
                             bool retest_groups, bool one_to_one_after_gnc) {
  Fingerprint f;
  f.add(static_cast<std::uint64_t>(robot));
  transport_detail::AddRobustOptions(f, gnc, check, retest_left_out, retest_groups,
                                     one_to_one_after_gnc);
  if (gnc) {
    for (bool b : robust) f.add(static_cast<std::uint64_t>(b));
    if (check) {
      f.add(static_cast<std::uint64_t>(checked.size()));
      for (bool b : checked) f.add(static_cast<std::uint64_t>(b));
    }
  }
  transport_detail::AddSolverOptions(f, o);
  for (const RelativePoseFactor& factor : g.factors()) {
    f.add(factor.a());
    f.add(factor.b());
    f.add(factor.measured());
    f.add(factor.information());
  }
  for (const PriorFactor& p : g.priors()) {
    f.add(p.key());
    f.add(p.prior());
    f.add(p.information());
  }
  for (const auto& [k, x] : initial) {
    if (k.robot != robot) continue;
    f.add(k);
    f.add(x);
  }
  return f.value();
}

RobotState StateOf(DgsStage stage) {
  switch (stage) {
    case DgsStage::kRotation:
      return RobotState::kRotation;
    case DgsStage::kPose:
      return RobotState::kPose;
    case DgsStage::kRefine:
      return RobotState::kRefine;
  }
  return RobotState::kFailed;
}

}  // namespace

class DgsNode::Impl final : public TeamChannel {
 public:
  Impl(int robot, PoseGraph subgraph, Values initial, Transport& transport,
       DgsNodeOptions options)
      : robot_(robot),
        subgraph_(std::move(subgraph)),
        initial_(std::move(initial)),
        transport_(transport),
        options_(std::move(options)) {
    options_.validate();
    solver_ = DriverOptions(options_);
    if (transport_.self() != robot_) {
      throw InvalidInputError(fmt::format("DGS node: robot {} given the transport of robot {}",
                                          robot_, transport_.self()));
    }
    // The anchor (first pose of robot 0) matters only to its owner; the others pass a key of
    // robot 0 they do not own.
    const Key anchor = robot_ == 0 ? GaugeAnchor(subgraph_) : Key::Pose(0, 0);
    AgentOptions ao;
    ao.gamma = solver_.gamma;
    ao.refine_gamma = solver_.refinement.gamma;
    ao.flagged_initialisation = solver_.flagged_initialisation;
    ao.weight_by_information = solver_.weight_by_information;
    anchor_ = anchor;
    agent_options_ = ao;
    agent_ = std::make_unique<RobotAgent>(robot_, subgraph_, initial_, anchor, ao);
    neighbours_ = agent_->neighbourRobots();
    for (const auto& [k, x] : initial_) {
      if (k.robot == robot_) own_[k] = x;
    }
    if (options_.gnc) {
      robust_ = options_.robust.empty() ? SeparatorFactors(subgraph_) : options_.robust;
      if (robust_.size() != subgraph_.factors().size()) {
        throw InvalidInputError(fmt::format("DGS node: the robust mask has {} entries for {} "
                                            "factors",
                                            robust_.size(), subgraph_.factors().size()));
      }
      if (!options_.checked.empty() && options_.checked.size() != subgraph_.factors().size()) {
        throw InvalidInputError(fmt::format("DGS node: the checked mask has {} entries for {} "
                                            "factors",
                                            options_.checked.size(), subgraph_.factors().size()));
      }
    }
    received_.emplace(robot_, options_.solve, neighbours_, agent_->neighbourVariables());
    // Snapshots of a graph with object landmarks use the g2o key scheme with objects.
    g2o_options_.atomic = true;
    for (const Key& k : subgraph_.keys()) {
      if (k.isObject()) g2o_options_.scheme = KeyScheme::kWithObjects;
    }
    if (!options_.state_dir.empty()) {
      CreateFolder(options_.state_dir, "DGS node state");
      const std::uint64_t fingerprint =
          RunFingerprint(robot_, subgraph_, initial_, solver_, options_.gnc, robust_,
                         options_.separator_check, options_.checked, options_.retest_left_out,
                         options_.retest_groups, options_.one_to_one_after_gnc) ^
          options_.solve;
      journal_ = std::make_unique<transport_detail::NodeJournal>(
          (std::filesystem::path(options_.state_dir) / "journal.bin").string(), robot_,
          fingerprint, options_.state_dir);
      result_.journal_truncated_bytes = journal_->truncatedBytes();
      result_.incarnation = journal_->starts();
      team_ = journal_->team();
    }
  }

  DgsNodeResult run() {
    if (ran_) throw InvalidInputError("DGS node: run() is called once");
    ran_ = true;
    const auto t0 = Clock::now();
    try {
      if (journal_) journal_->recordStart();
      if (team_.empty()) formTeam();
      transport_.setKnownRobots(team_);
      transport_.publish(baseStatus());  // alive for the others while it replays
      if (options_.on_round) {
        options_.on_round({DgsStage::kRotation, 0, 0, false,
                           std::numeric_limits<double>::infinity(), false});
      }
      if (options_.gnc) {
        runRobust();
      } else {
        result_.program = RunRobotProgram(*agent_, solver_, *this);
      }
      finishReplay();
      const RobotProgramResult& p = result_.program;
      result_.rotation_rounds = p.rotation.iterations;
      result_.pose_rounds = p.pose.iterations;
      result_.rotation_converged = p.rotation.status == StageStatus::kConverged;
      result_.pose_converged = p.pose.status == StageStatus::kConverged;
      if (journal_ && !journal_done_) journal_->recordDone();
      done_ = true;
      saveResult();
      transport_.publish(baseStatus());
      waitForPeers();
    } catch (const std::exception&) {
      StatusPacket st = baseStatus();
      st.state = RobotState::kFailed;
      try {
        transport_.publish(st);
      } catch (const std::exception&) {
      }
      throw;
    }
    if (result_.robust) {
      result_.estimate = result_.robust->estimate;
      result_.neighbours = result_.robust->neighbours;
    } else {
      result_.estimate = agent_->estimate();
      result_.neighbours = agent_->neighbourEstimates();
    }
    result_.team.assign(team_.begin(), team_.end());
    result_.left.assign(left_.begin(), left_.end());
    result_.transport = transport_.stats();
    result_.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return result_;
  }

  // ---- TeamChannel --------------------------------------------------------------------------
  TeamStep step(DgsStage stage, const std::vector<OutgoingMessage>& estimates,
                const TeamReport& report, const CoarseMessage* share,
                const std::vector<WeightMessage>& weights,
                const std::vector<CovarianceMessage>& covariances) override {
    const std::uint32_t s = ++step_;
    Sent sent{stage, estimates, report, share ? std::optional<CoarseMessage>(*share) : std::nullopt,
              weights, covariances};
    if (std::optional<TeamStep> replayed = replayStep(s, stage)) {
      last_sent_ = std::move(sent);
      ++result_.replayed_rounds;
      notify(stage, s, report, true);
      return std::move(*replayed);
    }
    if (last_sent_) {  // the last replayed step's packets, in case they were lost in the crash
      send(step_ - 1, *last_sent_);
      last_sent_.reset();
    }
    send(s, sent);
    waitFor(s);
    TeamStep got = received_->collect(s, live(), report, share);
    recordStep(s, stage, got);
    notify(stage, s, report, false);
    snapshot(stage != snapshot_stage_);
    snapshot_stage_ = stage;
    received_->prune(s);
    return got;
  }

  std::set<int> absent() const override { return left_; }

 private:
  struct Sent {
    DgsStage stage;
    std::vector<OutgoingMessage> estimates;
    TeamReport report;
    std::optional<CoarseMessage> share;
    std::vector<WeightMessage> weights;
    std::vector<CovarianceMessage> covariances;
  };

  // The robust program (options_.gnc): one agent per solve, made here so that the status and the
  // snapshots follow the agent at work.
  void runRobust() {
    RobustRobotProblem problem;
    problem.robot = robot_;
    problem.subgraph = subgraph_;
    problem.initial = initial_;
    problem.robust = robust_;
    problem.checked = options_.checked;
    RobustProgramOptions options;
    options.solver = solver_;
    options.gnc = *options_.gnc;
    options.check_separators = options_.separator_check.has_value();
    if (options_.separator_check) options.consistency = *options_.separator_check;
    options.retest_left_out = options_.retest_left_out;
    options.retest_groups = options_.retest_groups;
    options.one_to_one_after_gnc = options_.one_to_one_after_gnc;
    bool first = true;
    const AgentFactory make = [&](const PoseGraph& graph, const Values& start) -> RobotAgent& {
      for (const auto& [k, x] : agent_->estimate()) own_[k] = x;
      if (first) {
        first = false;  // the agent of the subgraph from the initial estimate: the constructor's
      } else {
        agent_ = std::make_unique<RobotAgent>(robot_, graph, start, anchor_, agent_options_);
      }
      received_->setStepNeighbours(agent_->neighbourRobots());
      return *agent_;
    };
    result_.robust = RunRobustRobotProgram(problem, options, make, *this);
    if (!result_.robust->unlinked) result_.program = result_.robust->solves.front();
  }

  // The robot's variables now: the agent's, and the others as the last solve that held them.
  Values currentEstimate() const {
    Values v = own_;
    for (const auto& [k, x] : agent_->estimate()) v[k] = x;
    return v;
  }

  void log(const std::string& text) const {
    if (options_.log) return options_.log(text);
    fmt::print(stderr, "moslam robot {}: {}\n", robot_, text);
    std::fflush(stderr);
  }

  void notify(DgsStage stage, std::uint32_t s, const TeamReport& report, bool replayed) {
    if (stage != round_stage_) stage_round_ = 0;
    round_stage_ = stage;
    ++stage_round_;
    if (options_.on_round) {
      options_.on_round({stage, s, stage_round_, report.sent, report.change, replayed});
    }
  }

  // ---- persistence ----------------------------------------------------------------------
  // Step s as the journal holds it (after the departures and the end journaled before it), if it
  // does: a restarted node replays what it computed before.
  std::optional<TeamStep> replayStep(std::uint32_t s, DgsStage stage) {
    if (!journal_) return std::nullopt;
    return journal_->replay(s, stage, left_, journal_done_);
  }

  void finishReplay() {
    if (!journal_ || !journal_->replaying()) return;
    replayStep(step_ + 1, DgsStage::kRotation);  // leaves and the end only; a step throws
  }

  void recordStep(std::uint32_t s, DgsStage stage, const TeamStep& got) {
    if (journal_) journal_->recordStep(s, stage, got);
  }

  void snapshot(bool force) {
    if (options_.state_dir.empty()) return;
    const auto now = Clock::now();
    if (!force && now - last_snapshot_ < std::chrono::seconds(1)) return;
    last_snapshot_ = now;
    write("estimate.g2o", currentEstimate());
  }

  // The robot's final variables: the robust program's estimate, which need not be its last
  // solve's (a refused inliers' solve, a rejected re-test: the agent holds what was turned
  // down), else the agent's.
  Values finalEstimate() const {
    Values v = currentEstimate();
    if (result_.robust) {
      for (const auto& [k, x] : result_.robust->estimate) v[k] = x;
    }
    return v;
  }

  void saveResult() {
    if (options_.state_dir.empty()) return;
    last_snapshot_ = Clock::now();
    const Values final_estimate = finalEstimate();
    write("estimate.g2o", final_estimate);
    write("result.g2o", final_estimate);
  }

  // `name` in the state directory, written whole or not at all.
  void write(const std::string& name, const Values& values) const {
    WriteG2oFile((std::filesystem::path(options_.state_dir) / name).string(), subgraph_, values,
                 g2o_options_);
  }

  // ---- protocol ---------------------------------------------------------------------------
  StatusPacket baseStatus() const {
    StatusPacket st;
    st.robot = robot_;
    st.solve = options_.solve;
    st.incarnation = result_.incarnation;
    const std::set<int>& neighbours = received_->stepNeighbours();
    st.neighbours.assign(neighbours.begin(), neighbours.end());
    st.round = step_;
    if (done_) {
      st.state = RobotState::kDone;
      st.done = true;
    }
    return st;
  }

  void send(std::uint32_t s, const Sent& what) {
    for (const OutgoingMessage& o : what.estimates) {
      EstimatesPacket p;
      p.receiver = o.to;
      p.solve = options_.solve;
      p.round = s;
      p.message = o.message;
      transport_.send(p);
      ++result_.estimate_messages;
      result_.estimate_binary_bytes += static_cast<std::int64_t>(EncodeMessage(p.message).size());
    }
    for (const WeightMessage& m : what.weights) {
      WeightsPacket w;
      w.solve = options_.solve;
      w.round = s;
      w.message = m;
      transport_.send(w);
      ++result_.weight_messages;
      result_.weight_binary_bytes += static_cast<std::int64_t>(EncodeWeightMessage(m).size());
    }
    for (const CovarianceMessage& m : what.covariances) {
      CovariancePacket c;
      c.solve = options_.solve;
      c.round = s;
      c.message = m;
      transport_.send(c);
      ++result_.covariance_messages;
      result_.covariance_binary_bytes +=
          static_cast<std::int64_t>(EncodeCovarianceMessage(m).size());
    }
    if (what.share) {
      CoarsePacket c;
      c.solve = options_.solve;
      c.round = s;
      c.message = *what.share;
      transport_.publish(c);
      ++result_.coarse_messages;
      result_.coarse_binary_bytes +=
          static_cast<std::int64_t>(EncodeCoarseMessage(c.message).size());
    }
    StatusPacket st = baseStatus();
    st.round = s;
    st.state = StateOf(what.stage);
    st.stage = static_cast<std::uint8_t>(what.stage);
    st.iteration = static_cast<std::uint32_t>(std::max(agent_->iteration(), 0));
    transport_detail::SetReport(what.report, st);
    transport_.publish(st);
  }

  void formTeam() {
    const auto deadline = Clock::now() + options_.join_timeout;
    transport_.publish(baseStatus());
    if (!options_.team.empty()) {
      setTeam(std::set<int>(options_.team.begin(), options_.team.end()));
      return;
    }
    std::set<int> known = neighbours_;
    known.insert(robot_);
    while (true) {
      ingest(transport_.poll(std::chrono::milliseconds(50)));
      // The closure: robots heard from add their neighbours, until nothing changes.
      std::map<int, std::vector<int>> lists;
      for (const auto& [r, status] : received_->latest()) lists.emplace(r, status.neighbours);
      transport_detail::GrowClosure(known, lists);
      std::vector<int> missing;
      for (int r : known) {
        if (r != robot_ && !received_->heard().count(r)) missing.push_back(r);
      }
      if (missing.empty()) break;
      if (Clock::now() > deadline) {
        throw Error(fmt::format("robot {}: the team did not form within {} ms: no status from "
                                "robot(s) {} (not started, or not reachable over the network)",
                                robot_, options_.join_timeout.count(), fmt::join(missing, ", ")));
      }
    }
    setTeam(known);
  }

  void setTeam(const std::set<int>& known) {
    if (!known.count(0)) {
      throw UnderdeterminedError(fmt::format(
          "robot {}: its team {} has no robot 0, whose first pose fixes the gauge", robot_,
          fmt::join(known, ", ")));
    }
    if (!known.count(robot_) ||
        !std::includes(known.begin(), known.end(), neighbours_.begin(), neighbours_.end())) {
      throw InvalidInputError(fmt::format("robot {}: the team given, {}, lacks the robot or one "
                                          "of its neighbours {}",
                                          robot_, fmt::join(known, ", "),
                                          fmt::join(neighbours_, ", ")));
    }
    team_ = known;
    if (journal_) journal_->recordTeam(team_);
    log(fmt::format("team of {}: robots {}", team_.size(), fmt::join(team_, ", ")));
  }

  // Files the packets in the inbox; counts and logs what it turned away.
  void ingest(std::vector<Received> packets) {
    const transport_detail::IngestNotes notes = received_->ingest(std::move(packets));
    result_.rejected_estimates += notes.rejected;
    for (const std::string& line : notes.lines) log(line);
  }

  std::vector<int> live() const {
    std::vector<int> out;
    for (int r : team_) {
      if (r != robot_ && !left_.count(r)) out.push_back(r);
    }
    return out;
  }

  // The robots step s still waits for.
  std::vector<int> waitingFor(std::uint32_t s) const {
    std::vector<int> out;
    for (int r : live()) {
      if (!received_->missing(r, s).empty()) out.push_back(r);
    }
    return out;
  }

  void waitFor(std::uint32_t s) {
    const auto start = Clock::now();
    std::map<int, Clock::time_point> not_alive_since;
    while (true) {
      const std::vector<int> waiting = waitingFor(s);
      if (waiting.empty()) return;
      ingest(transport_.poll(std::chrono::milliseconds(100)));
      const auto now = Clock::now();
      const std::set<int> alive = transport_.alive();
      std::vector<int> never_stepped;  // of a team given: gone before they took a step
      for (int r : waiting) {
        if (alive.count(r) && !received_->failed(r)) {
          not_alive_since.erase(r);
          continue;
        }
        const auto [it, inserted] = not_alive_since.emplace(r, now);
        if (now - it->second >= options_.leave_timeout) {
          // Only at the first step: a node restarted later replays the steps without their
          // statuses, and a robot that died since sent it no history to count as stepped.
          if (!options_.team.empty() && s == 1 && !received_->stepped(r)) {
            never_stepped.push_back(r);
            continue;
          }
          log(fmt::format("robot {} left (step {}): continuing without it", r, s));
          left_.insert(r);
          if (journal_) journal_->recordLeft(r, s);
        }
      }
      if (!never_stepped.empty()) {
        throw TeamChangedError(
            never_stepped,
            fmt::format("robot {}: robot(s) {} of the team given left before their first step "
                        "(not alive for {} ms at step {}): the solve stops, to be formed again "
                        "without them",
                        robot_, fmt::join(never_stepped, ", "), options_.leave_timeout.count(), s));
      }
      if (now - start > options_.stall_timeout) {
        std::vector<std::string> what;
        for (int r : waiting) what.push_back(fmt::format("{} ({})", r, received_->missing(r, s)));
        throw Error(fmt::format("robot {}: no progress for {} ms at step {}, waiting for "
                                "robot(s) {}",
                                robot_, options_.stall_timeout.count(), s,
                                fmt::join(what, ", ")));
      }
    }
  }

  void waitForPeers() {
    const auto deadline = Clock::now() + options_.finish_timeout;
    std::map<int, Clock::time_point> not_alive_since;
    while (Clock::now() < deadline) {
      std::vector<int> pending;
      const std::set<int> alive = transport_.alive();
      const auto now = Clock::now();
      for (int r : live()) {
        if (received_->done(r)) continue;
        if (!alive.count(r) || received_->failed(r)) {
          const auto [jt, inserted] = not_alive_since.emplace(r, now);
          if (now - jt->second >= options_.leave_timeout) continue;  // gone
        } else {
          not_alive_since.erase(r);
        }
        pending.push_back(r);
      }
      if (pending.empty()) return;
      ingest(transport_.poll(std::chrono::milliseconds(100)));
    }
    log("finish: not every robot reported done before the finish timeout");
  }

  int robot_;
  PoseGraph subgraph_;
  Values initial_;
  Transport& transport_;
  DgsNodeOptions options_;
  DgsOptions solver_;
  Key anchor_;
  AgentOptions agent_options_;
  std::unique_ptr<RobotAgent> agent_;  // the agent at work (robust: of the current solve)
  Values own_;                         // the robot's variables as the last solves left them
  std::vector<bool> robust_;           // with options_.gnc: per subgraph factor
  std::set<int> neighbours_;           // of the subgraph (the team's; the packets it accepts)
  std::unique_ptr<transport_detail::NodeJournal> journal_;  // none without a state_dir
  G2oWriteOptions g2o_options_;  // snapshots: written whole or not at all (atomic)

  std::set<int> team_, left_;
  std::uint32_t step_ = 0;
  bool done_ = false;
  bool journal_done_ = false;
  bool ran_ = false;
  std::optional<Sent> last_sent_;    // the last replayed step's packets, re-sent once live
  std::optional<DgsStage> snapshot_stage_;
  std::optional<DgsStage> round_stage_;  // on_round: the stage of the last step, steps in it
  int stage_round_ = 0;

  std::optional<transport_detail::StepInbox> received_;  // what the steps received
  Clock::time_point last_snapshot_{};
  DgsNodeResult result_;
};

DgsNode::DgsNode(int robot, PoseGraph subgraph, Values initial, Transport& transport,
                 DgsNodeOptions options)
    : impl_(std::make_unique<Impl>(robot, std::move(subgraph), std::move(initial), transport,
                                   std::move(options))) {}

DgsNode::~DgsNode() = default;

DgsNodeResult DgsNode::run() { return impl_->run(); }

}  // namespace moslam
