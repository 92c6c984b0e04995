#include "moslam/transport/robot_session.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <filesystem>
#include <iterator>
#include <map>
#include <optional>
#include <set>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/graph/robot_groups.h"
#include "moslam/io/g2o.h"
#include "moslam/io/tum.h"
#include "moslam/online/group_solve.h"
#include "moslam/online/online_team.h"
#include "moslam/robust/gnc.h"
#include "moslam/sim/world.h"
#include "moslam/slam/rendezvous.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/group_formation.h"
#include "moslam/transport/group_transport.h"
#include "moslam/transport/record_bytes.h"
#include "moslam/transport/session_inbox.h"
#include "moslam/transport/session_journal.h"
#include "moslam/transport/session_fingerprint.h"
#include "moslam/transport/session_pairs.h"
#include "moslam/transport/solve_record.h"
#include "moslam/transport/team_membership.h"

namespace moslam {

void ScenarioSpec::validate() const {
  auto bad = [](const std::string& msg) { throw InvalidInputError("scenario: " + msg); };
  if (scenario != "chairs25" && scenario != "house" && scenario != "generated") {
    bad("scenario must be chairs25, house or generated, got '" + scenario + "'");
  }
  if (robots < 1 || robots > kMaxTransportRobot) {
    bad("robots must be in [1, 65535], got " + std::to_string(robots));
  }
  if (!(sigma_rotation_deg >= 0.0) || !std::isfinite(sigma_rotation_deg)) {
    bad("sigma_rotation_deg must be finite and >= 0");
  }
  if (!(sigma_translation >= 0.0) || !std::isfinite(sigma_translation)) {
    bad("sigma_translation must be finite and >= 0");
  }
  if (poses_per_robot < 2) {
    bad("poses_per_robot must be at least 2, got " + std::to_string(poses_per_robot));
  }
  if (!(exclusion_radius >= 0.0) || !std::isfinite(exclusion_radius)) {
    bad("exclusion_radius must be finite and >= 0");
  }
}

namespace {

SimulationConfig ScenarioSimulationConfig(const ScenarioSpec& spec) {
  return NoiseSimulationConfig(spec.robots, spec.poses_per_robot, spec.seed,
                               spec.sigma_rotation_deg, spec.sigma_translation);
}

}  // namespace

SimulationData SimulateScenario(const ScenarioSpec& spec) {
  spec.validate();
  return Simulate(MakeScenarioWorld(spec.scenario, spec.seed, spec.robots),
                  ScenarioSimulationConfig(spec));
}

MultiRobotSlamConfig ScenarioSlamConfig(const ScenarioSpec& spec) {
  spec.validate();
  MultiRobotSlamConfig config =
      MultiRobotSlamConfigForNoise(ScenarioSimulationConfig(spec).sensing);
  config.known_initial_poses = spec.known_initial_poses;
  config.slam.exclusion_radius = spec.exclusion_radius;
  config.slam.leave_one_out_check = spec.leave_one_out_check;
  config.slam.loop_closure = spec.loop_closure;
  config.rendezvous.refine_by_constellation = spec.rendezvous_constellation;
  return config;
}

RobotScenarioData SliceForRobot(const SimulationData& data, int robot, bool known_initial_poses) {
  if (robot < 0 || robot >= data.numRobots() ||
      data.measurements.size() != data.trajectories.size()) {
    throw InvalidInputError(fmt::format("SliceForRobot: robot {} is not one of the {} robots of "
                                        "the simulation",
                                        robot, data.numRobots()));
  }
  RobotScenarioData d;
  d.robot = robot;
  d.num_robots = data.numRobots();
  d.measurements = data.measurements[static_cast<std::size_t>(robot)];
  for (const Trajectory& t : data.trajectories) {
    if (t.empty()) throw InvalidInputError("SliceForRobot: a robot has no pose");
    if (known_initial_poses) d.initial_poses.push_back(t.front());
  }
  d.events = data.rendezvous;
  return d;
}

void RobotSessionOptions::validate() const {
  slam.validate();
  dgs.validate();
  if (slam.slam.ground_truth_association || slam.rendezvous.ground_truth_association) {
    throw InvalidInputError(
        "robot session: ground_truth_association is not available between processes (it reads "
        "the other robot's landmarks)");
  }
  if (rendezvous_timeout.count() <= 0) {
    throw InvalidInputError("robot session: rendezvous_timeout must be positive");
  }
  if (online && (!dgs.robust.empty() || !dgs.checked.empty())) {
    throw InvalidInputError("robot session: online, the robust and checked masks are the group "
                            "solve's (online_team.h: RobustGroupFactors), not given");
  }
  if (online && !dgs.solver.refine) {
    throw InvalidInputError(
        "robot session: online mapping needs the refinement (dgs.solver.refine): a robot holds "
        "its partners' landmarks as its refined copies of them");
  }
}

PoseGraph SessionSubgraph(const ObjectSlam& slam, const std::vector<SharedObject>& shared,
                          const Matrix6& lambda) {
  PoseGraph g = slam.graph();
  for (const SharedObject& s : shared) g.add(ObjectObjectFactor(s, lambda));
  return g;
}

namespace {

using Clock = std::chrono::steady_clock;
using transport_detail::GroupRecord;
using transport_detail::LeftRecord;
using transport_detail::SolveRecord;

// Hands the packets received during the rendezvous phase (DGS statuses and estimates of robots
// that finished it first) to the DGS node before anything new.
class PrefetchedTransport final : public Transport {
 public:
  PrefetchedTransport(Transport& inner, std::vector<Received> pending)
      : inner_(inner), pending_(std::move(pending)) {}
  int self() const override { return inner_.self(); }
  void send(const EstimatesPacket& p) override { inner_.send(p); }
  void send(const SharedObjectsPacket& p) override { inner_.send(p); }
  void send(const WeightsPacket& p) override { inner_.send(p); }
  void send(const CovariancePacket& p) override { inner_.send(p); }
  void publish(const StatusPacket& p) override { inner_.publish(p); }
  void publish(const ObjectListPacket& p) override { inner_.publish(p); }
  void publish(const CoarsePacket& p) override { inner_.publish(p); }
  std::vector<Received> poll(std::chrono::milliseconds timeout) override {
    if (pending_.empty()) return inner_.poll(timeout);
    std::vector<Received> out = std::move(pending_);
    pending_.clear();
    for (Received& r : inner_.poll(std::chrono::milliseconds(0))) out.push_back(std::move(r));
    return out;
  }
  std::set<int> alive() const override { return inner_.alive(); }
  void setKnownRobots(const std::set<int>& robots) override { inner_.setKnownRobots(robots); }
  TransportStats stats() const override { return inner_.stats(); }

 private:
  Transport& inner_;
  std::vector<Received> pending_;
};

using transport_detail::EventRecord;
using Pairs = transport_detail::ObjectPairs;

// What an event changed: the pairs added and the pairs shared before that it removed, (alpha
// landmark, beta landmark) each.
struct EventPairs {
  Pairs pairs;
  Pairs removed;
};

// A solve formed again without robots that left before its first step (DgsNode's
// TeamChangedError): attempt a of solve s is s + a * 2^24 (solves of steps < 2^24).
constexpr std::uint32_t kAttemptShift = 24;
std::uint32_t AttemptSolve(std::uint32_t solve, int attempt) {
  return solve + (static_cast<std::uint32_t>(attempt) << kAttemptShift);
}
// Whether packets of solve `a` are of a solve before `b` (of an earlier step, or an earlier
// attempt of the same step); presence statuses are of none.
bool SolveBefore(std::uint32_t a, std::uint32_t b) {
  if (a == kPresenceSolve) return false;
  constexpr std::uint32_t step_mask = (1u << kAttemptShift) - 1;
  const std::uint32_t sa = a & step_mask, sb = b & step_mask;
  return sa < sb || (sa == sb && (a >> kAttemptShift) < (b >> kAttemptShift));
}

// The ids 0..n-1 of a group's robots as its DgsNode sees them (GroupTransport).
std::vector<int> GroupIds(std::size_t n) {
  std::vector<int> ids(n);
  for (std::size_t i = 0; i < n; ++i) ids[i] = static_cast<int>(i);
  return ids;
}

}  // namespace

class RobotSession::Impl {
 public:
  Impl(RobotScenarioData data, Transport& transport, RobotSessionOptions options)
      : data_(std::move(data)),
        transport_(transport),
        options_(std::move(options)),
        pairs_(data_.robot) {
    options_.validate();
    robot_ = data_.robot;
    if (transport_.self() != robot_) {
      throw InvalidInputError(fmt::format("robot session: robot {} given the transport of robot {}",
                                          robot_, transport_.self()));
    }
    const int n = data_.num_robots, steps = data_.numSteps();
    // Unknown initial poses: whatever the data holds is never read.
    const bool poses_ok = !options_.slam.known_initial_poses ||
                          static_cast<int>(data_.initial_poses.size()) == n;
    if (robot_ < 0 || robot_ >= n || !poses_ok || steps < 1 ||
        static_cast<int>(data_.measurements.odometry.size()) != steps - 1) {
      throw InvalidInputError(fmt::format("robot session: inconsistent data for robot {} of {}",
                                          robot_, n));
    }
    for (std::size_t i = 0; i < data_.events.size(); ++i) {
      const RendezvousEvent& e = data_.events[i];
      if (e.alpha < 0 || e.alpha >= n || e.beta < 0 || e.beta >= n || e.alpha == e.beta ||
          e.step < 0 || e.step >= steps || (i > 0 && e.step < data_.events[i - 1].step)) {
        throw InvalidInputError(fmt::format(
            "robot session: rendezvous event {} (step {}, robots {} and {}) does not fit the "
            "scenario or is out of order",
            i, e.step, e.alpha, e.beta));
      }
    }
    if (!options_.log) {
      const int r = robot_;
      options_.log = [r](const std::string& text) {
        fmt::print(stderr, "moslam robot {}: {}\n", r, text);
        std::fflush(stderr);
      };
    }
    TeamMembership::Options membership;
    membership.leave_timeout = options_.dgs.leave_timeout;
    membership.log = options_.log;
    membership.journal = [this](int robot, int step) {
      record(LeftRecord{static_cast<std::uint16_t>(robot), static_cast<std::uint32_t>(step)});
    };
    membership_ = std::make_unique<TeamMembership>(robot_, n, transport_, std::move(membership));
    if (!options_.dgs.state_dir.empty())
      std::filesystem::create_directories(options_.dgs.state_dir);
    if (!options_.dgs.state_dir.empty()) {
      transport_detail::SessionJournalRun run;
      run.robot = robot_;
      run.fingerprint = transport_detail::SessionFingerprint(data_, options_);
      run.num_robots = data_.num_robots;
      run.num_steps = static_cast<std::uint32_t>(data_.numSteps());
      run.num_events = data_.events.size();
      run.online = options_.online;
      journal_ = std::make_unique<transport_detail::SessionJournal>(
          (std::filesystem::path(options_.dgs.state_dir) / "rendezvous.bin").string(), run,
          options_.dgs.state_dir);
      restore();
    }
  }

  RobotSessionResult run() {
    if (ran_) throw InvalidInputError("robot session: run() is called once");
    ran_ = true;
    const auto t0 = Clock::now();
    std::set<int> everyone;
    for (int r = 0; r < data_.num_robots; ++r) everyone.insert(r);
    transport_.setKnownRobots(everyone);
    membership_->publishPresence();  // liveliness before the first solve

    ObjectSlam slam(robot_, options_.slam.slam);
    const RobotMeasurements& m = data_.measurements;
    std::size_t next = 0;
    for (int t = 0; t < data_.numSteps(); ++t) {
      const auto ti = static_cast<std::size_t>(t);
      if (t == 0) {
        slam.addFirstPose(m.detections[0]);
      } else {
        slam.addPose(m.odometry[ti - 1], m.detections[ti]);
      }
      std::vector<std::size_t> mine;
      for (; next < data_.events.size() && data_.events[next].step == t; ++next) {
        const RendezvousEvent& e = data_.events[next];
        if (e.alpha == robot_ || e.beta == robot_) mine.push_back(next);
      }
      if (mine.empty()) continue;
      membership_->noteAlive();
      // As RunMultiRobotObjectSlam: both robots refresh before an event (the later events of
      // the same step find nothing new).
      slam.refresh(options_.slam.slam.iterations_per_update);
      bool list_published = false;
      for (std::size_t index : mine) {
        const RendezvousEvent& e = data_.events[index];
        SessionRendezvous rec;
        rec.event = e;
        rec.alpha = e.alpha == robot_;
        const auto te = Clock::now();
        const int peer = rec.alpha ? e.beta : e.alpha;
        EventPairs pairs;
        const auto journaled = journaled_.find(index);
        const bool peer_left = journaled == journaled_.end() && hasLeft(peer, t);
        if (rec.alpha && !peer_left) {
          const ObjectMapMessage map = MakeObjectMapMessage(slam);
          rec.objects_sent = static_cast<int>(map.objects.size());
          rec.binary_bytes = static_cast<std::int64_t>(EncodeObjectMap(map).size());
        }
        if (journaled != journaled_.end()) {
          pairs = journaled->second;
          rec.replayed = true;
          if (!rec.alpha) sendAnswer(e, pairs);  // the old process may have died before it left
        } else if (peer_left) {
          rec.skipped = true;
        } else if (rec.alpha) {
          if (!list_published) {
            publishList(slam, t);
            list_published = true;
          }
          if (std::optional<EventPairs> answer = awaitAnswer(e, slam)) {
            pairs = std::move(*answer);
            record(EventRecord{static_cast<std::uint32_t>(index), pairs.pairs, pairs.removed});
          } else {
            rec.skipped = true;
          }
        } else if (const std::optional<ObjectMapMessage> received = awaitList(e)) {
          std::optional<SE3> beta_T_alpha;
          if (options_.slam.known_initial_poses) {
            beta_T_alpha = BetaTAlpha(data_.initial_poses[static_cast<std::size_t>(e.alpha)],
                                      data_.initial_poses[static_cast<std::size_t>(e.beta)]);
          }
          const SharedObjectsMessage answer = AnswerObjectMap(
              *received, slam, beta_T_alpha, pairs_.shared(), options_.slam.rendezvous);
          pairs = {answer.pairs, answer.removed};
          sendAnswer(e, pairs);
          record(EventRecord{static_cast<std::uint32_t>(index), pairs.pairs, pairs.removed});
        } else {
          rec.skipped = true;
        }
        if (!rec.skipped) applyPairs(e, pairs, rec);  // skipped: the peer left, nothing exchanged
        rec.seconds = std::chrono::duration<double>(Clock::now() - te).count();
        result_.rendezvous_binary_bytes += rec.binary_bytes;
        result_.rendezvous.push_back(rec);
        if (options_.on_rendezvous) options_.on_rendezvous(rec);
      }
      // Lists of this step or earlier are no longer needed (the others' events included).
      inbox_.dropListsUpTo(static_cast<std::uint32_t>(t));
      if (options_.online) groupSolve(slam, t);
    }
    slam.optimize(options_.slam.final_iterations);
    if (options_.online) {
      result_.slam_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      result_.rendezvous_transport = transport_.stats();
      result_.shared = pairs_.shared();
      result_.initial = slam.estimate();
      result_.final_estimate = slam.estimate();
      result_.set_aside = pairs_.setAside();
      result_.poses = slam.numPoses();
      result_.landmarks = static_cast<int>(slam.landmarks().size());
      saveMap(slam, "final");
      result_.seconds = result_.slam_seconds;
      noteLeftTeam();
      return result_;
    }
    result_.slam_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    result_.rendezvous_transport = transport_.stats();
    result_.shared = pairs_.shared();
    result_.initial = slam.estimate();
    result_.poses = slam.numPoses();
    result_.landmarks = static_cast<int>(slam.landmarks().size());
    // A robot of the team that leaves before its first step stops the solve (DgsNode's
    // TeamChangedError); the team is formed again without it, as when it had left before.
    const int end = data_.numSteps();
    for (int attempt = journaledAttempt(end);; ++attempt) {
      std::vector<int> closure, robots;
      const bool departures = batchGroup(closure, robots, attempt);
      try {
        if (departures) {
          solveWithoutTheRobotsThatLeft(slam, closure, robots, attempt);
        } else {
          result_.subgraph =
              SessionSubgraph(slam, pairs_.shared(), options_.slam.rendezvous.lambda());
          solveBatch(closure);
        }
        break;
      } catch (const TeamChangedError& e) {
        for (int r : e.robots()) {
          markLeft(departures ? robots.at(static_cast<std::size_t>(r)) : r, end,
                   "it joined the batch solve and left before its first step");
        }
        result_.subgraph = PoseGraph();
      }
    }
    result_.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    noteLeftTeam();
    return result_;
  }

 private:
  // The batch solve of the whole team (none of its robots left): DgsNode on the robot's subgraph;
  // its team the closure the joining statuses formed (empty, for a robot linked to none: the
  // node forms it).
  void solveBatch(const std::vector<int>& closure) {
    PrefetchedTransport dgs_transport(transport_, inbox_.takePending());
    DgsNodeOptions node_options = options_.dgs;
    node_options.team = closure;
    if (node_options.gnc && node_options.robust.empty()) {
      node_options.robust = ObjectFactors(result_.subgraph);
    }
    DgsNode node(robot_, result_.subgraph, result_.initial, dgs_transport, node_options);
    result_.dgs = node.run();
    RefuseUnlinked(result_.dgs, robot_);
  }

  // A batch robust solve whose separator check left a robot unlinked has no estimate of the
  // team: an error, as RunRobustDgs throws it in one process.
  static void RefuseUnlinked(const DgsNodeResult& solved, int robot) {
    if (!solved.robust || !solved.robust->unlinked) return;
    throw UnderdeterminedError(fmt::format(
        "robot {}: the separator check left some robot of the team without a pair it accepts "
        "(a robot pair with fewer than min_support pairwise-consistent shared objects keeps none "
        "unless its robots are linked through confirmed pairs): no team estimate",
        robot));
  }

  // ---- batch: robots that left for good ---------------------------------------------------
  // Before the batch solve every robot with shared pairs publishes a joining status of solve
  // 1 + T (T: its number of steps) listing every robot it shares pairs with, gone or not, and
  // waits for those of the closure (formGroup): a robot that left for good publishes none and is
  // found gone (or was, at a rendezvous), so every robot of the closure finds the same
  // departures. Returns whether some robot of `closure` (increasing, this robot among them) left;
  // `robots`: the closure without them. The closure is journaled (a group record of step T), so a
  // robot restarted in the solve takes the same way.
  // Attempt a > 0 (the team formed again: run()) uses solve AttemptSolve(1 + T, a).
  bool batchGroup(std::vector<int>& closure, std::vector<int>& robots, int attempt) {
    const int end = data_.numSteps();
    if (membership_->out()) {  // it left the team: its own map is its result
      closure = robots = {robot_};
      return true;
    }
    const auto solve = AttemptSolve(static_cast<std::uint32_t>(end + 1), attempt);
    if (const auto journaled = journaled_groups_.find(end);
        journaled != journaled_groups_.end() && attempt == journaledAttempt(end)) {
      closure = journaled->second.robots;
    } else {
      std::set<int> partners;
      for (const SharedObject& o : pairs_.shared()) {
        for (int r : {o.alpha_object.robot, o.beta_object.robot}) {
          if (r != robot_) partners.insert(r);
        }
      }
      if (partners.empty()) return false;  // linked to no robot: the batch solve as before
      StatusPacket join;
      join.robot = robot_;
      join.solve = solve;
      join.neighbours.assign(partners.begin(), partners.end());
      transport_.publish(join);
      std::set<int> everyone;
      for (int r = 0; r < data_.num_robots; ++r) everyone.insert(r);
      std::vector<TeamPair> none;
      formGroup(join, partners, everyone, solve, end, robots, none, &closure);
      record(GroupRecord{static_cast<std::uint32_t>(end), closure, {}});
      ++group_records_[end];
    }
    robots.clear();
    for (int r : closure) {
      if (r == robot_ || !hasLeft(r, end)) robots.push_back(r);
    }
    return robots.size() != closure.size();
  }

  // The batch solve of `robots`, the closure without the robots that left: their pairs dropped,
  // the robots re-labelled 0..k-1 (GroupTransport) so that the lowest of them holds the gauge
  // (robot 0 may have left), as the in-process twin solves the joint graph of the robots that
  // stay (BuildGroupProblem without held estimates). Its DgsNode journals in
  // <state_dir>/solves/batch; the result, in the robots' own ids, in <state_dir>/result.g2o.
  void solveWithoutTheRobotsThatLeft(const ObjectSlam& slam, const std::vector<int>& closure,
                                     const std::vector<int>& robots, int attempt) {
    std::vector<int> gone;
    std::set_difference(closure.begin(), closure.end(), robots.begin(), robots.end(),
                        std::back_inserter(gone));
    const auto real = [&](Key k) {
      return Key{robots[static_cast<std::size_t>(k.robot)], k.kind, k.index};
    };
    if (robots.size() < 2) {  // every partner left: its own map is its result
      for (const auto& [k, x] : slam.estimate()) result_.dgs.estimate.emplace(k, x);
      result_.dgs.team = robots;
      result_.subgraph = slam.graph();
      saveBatchResult();
      return;
    }
    const auto solve = AttemptSolve(static_cast<std::uint32_t>(data_.numSteps() + 1), attempt);
    RobotGroupPart part =
        BuildRobotGroupPart(slam, robots, pairs_.shared(), {}, options_.slam.rendezvous.lambda());
    GroupTransport group_transport(
        transport_, robots, solve, [this](Received r) { ingest({std::move(r)}); },
        inbox_.takePending(solve));
    DgsNodeOptions node_options = options_.dgs;
    node_options.solve = solve;
    node_options.team = GroupIds(robots.size());
    if (!options_.dgs.state_dir.empty()) {
      node_options.state_dir = (std::filesystem::path(options_.dgs.state_dir) / "solves" /
                                (attempt == 0 ? std::string("batch")
                                              : fmt::format("batch_attempt_{}", attempt)))
                                   .string();
    }
    if (node_options.gnc && node_options.robust.empty()) {
      node_options.robust = ObjectFactors(part.subgraph);
    }
    node_options.log = [this, gone, robots](const std::string& text) {
      options_.log(fmt::format("batch solve without robot(s) {} (robots {} as 0..{}): {}",
                               fmt::join(gone, ","), fmt::join(robots, ","), robots.size() - 1,
                               text));
    };
    DgsNode node(part.local, part.subgraph, std::move(part.initial), group_transport, node_options);
    DgsNodeResult solved = node.run();
    RefuseUnlinked(solved, robot_);
    for (const RelativePoseFactor& f : part.subgraph.factors()) {
      result_.subgraph.add(
          RelativePoseFactor(real(f.a()), real(f.b()), f.measured(), f.information()));
    }
    Values estimate, neighbours;
    for (const auto& [k, x] : solved.estimate) estimate.emplace(real(k), x);
    for (const auto& [k, x] : solved.neighbours) neighbours.emplace(real(k), x);
    solved.estimate = std::move(estimate);
    solved.neighbours = std::move(neighbours);
    for (std::vector<int>* ids : {&solved.team, &solved.left}) {
      for (int& r : *ids) r = robots[static_cast<std::size_t>(r)];
    }
    result_.dgs = std::move(solved);
    saveBatchResult();
  }

  // <state_dir>/result.g2o as the batch DgsNode writes it: the subgraph and the estimate.
  void saveBatchResult() const {
    if (options_.dgs.state_dir.empty()) return;
    const std::filesystem::path dir(options_.dgs.state_dir);
    G2oWriteOptions write;
    write.scheme = KeyScheme::kWithObjects;
    WriteG2oFile((dir / "result.g2o.tmp").string(), result_.subgraph, result_.dgs.estimate, write);
    std::filesystem::rename(dir / "result.g2o.tmp", dir / "result.g2o");
  }

  // What event e changed, applied to the shared pairs (SessionPairs::apply) and counted in
  // `rec`.
  void applyPairs(const RendezvousEvent& e, const EventPairs& pairs, SessionRendezvous& rec) {
    SharedObjectsMessage answer;
    answer.sender = e.beta;
    answer.receiver = e.alpha;
    answer.pairs = pairs.pairs;
    answer.removed = pairs.removed;
    if (!rec.alpha)
      rec.binary_bytes = static_cast<std::int64_t>(EncodeSharedObjects(answer).size());
    rec.new_shared = static_cast<int>(pairs_.apply(answer, e.step).size());
    rec.removed_shared = static_cast<int>(pairs.removed.size());
  }

  // ---- online mapping ---------------------------------------------------------------------
  // The group solve of step t (RobotSessionOptions::online; OnlineTeam::onRendezvous is the
  // in-process twin): the robots connected to this one through the step's events, split by the
  // shared pairs among them. Each robot knows only its own pairs, so the split is found as the
  // DgsNode forms a team: every robot publishes a joining status of solve 1 + t listing its
  // partners in range, and the group is the closure of those lists.
  void groupSolve(ObjectSlam& slam, int t) {
    const auto t0 = Clock::now();
    if (replaySolve(slam, t)) return;
    const TransportStats before = transport_.stats();
    std::vector<int> in_range;
    std::vector<std::pair<int, int>> links;
    for (const RendezvousEvent& e : data_.events) {
      if (e.step != t) continue;
      in_range.insert(in_range.end(), {e.alpha, e.beta});
      links.emplace_back(e.alpha, e.beta);
    }
    std::set<int> range;
    for (const std::vector<int>& g : ConnectedRobots(in_range, links)) {
      if (std::binary_search(g.begin(), g.end(), robot_)) range.insert(g.begin(), g.end());
    }
    // A member that leaves before its first step stops the solve (DgsNode's TeamChangedError):
    // found gone, the group is formed again without it, as if it had left before (attempt a of
    // the solve: AttemptSolve).
    std::vector<int> robots;
    std::optional<RobotGroupPart> part;
    std::optional<DgsNodeResult> result;
    std::filesystem::path solve_dir;
    for (int attempt = journaledAttempt(t); !result; ++attempt) {
      const auto solve = AttemptSolve(static_cast<std::uint32_t>(t + 1), attempt);
      std::vector<TeamPair> team;
      if (!joinGroup(t, range, solve, attempt, robots, team)) return;
      part = BuildRobotGroupPart(slam, robots, pairs_.shared(), team,
                                 options_.slam.rendezvous.lambda());
      GroupTransport group_transport(
          transport_, robots, solve, [this](Received r) { ingest({std::move(r)}); },
          inbox_.takePending(solve));
      DgsNodeOptions node_options = options_.dgs;
      node_options.solve = solve;
      node_options.team = GroupIds(robots.size());  // formed by the joining statuses
      // Its own journal, so that a robot restarted in the solve resumes it (dgs_node.h).
      solve_dir = options_.dgs.state_dir.empty()
                      ? std::filesystem::path()
                      : std::filesystem::path(options_.dgs.state_dir) / "solves" /
                            (attempt == 0 ? fmt::format("step_{:04d}", t)
                                          : fmt::format("step_{:04d}_attempt_{}", t, attempt));
      node_options.state_dir = solve_dir.string();
      if (node_options.gnc) {  // OnlineTeam's robust group solve
        RobustGroupMasks masks = RobustGroupFactors(part->subgraph, part->team);
        node_options.robust = std::move(masks.robust);
        if (node_options.separator_check) node_options.checked = std::move(masks.checked);
      }
      node_options.log = [this, t, robots](const std::string& text) {
        options_.log(fmt::format("group solve of step {} (robots {} as 0..{}): {}", t,
                                 fmt::join(robots, ","), robots.size() - 1, text));
      };
      DgsNode node(part->local, part->subgraph, part->initial, group_transport, node_options);
      try {
        result = node.run();
      } catch (const TeamChangedError& e) {
        for (int local : e.robots()) {
          markLeft(robots.at(static_cast<std::size_t>(local)), t,
                   fmt::format("it joined the group solve of step {} and left before its first "
                               "step",
                               t));
        }
        if (!solve_dir.empty()) std::filesystem::remove_all(solve_dir);
      }
    }
    const DgsNodeResult& solved = *result;
    SolveRecord done;
    done.step = static_cast<std::uint32_t>(t);
    done.object_object = static_cast<std::uint32_t>(part->object_object);
    done.team_factors = static_cast<std::uint32_t>(part->team_factors);
    if (solved.robust && solved.robust->unlinked) {
      // The check left some robot of the group unlinked: nothing changes (OnlineTeam alike).
      done.unlinked = true;
      done.estimate = slam.estimate();
      done.set_aside = pairs_.setAsideKeys();
      done.rejected = rejectedFactors(slam);
      record(done);
      if (!solve_dir.empty()) std::filesystem::remove_all(solve_dir);
      finishSolve(slam, t, robots, done, transport_.stats() - before, t0, false);
      return;
    }
    if (solved.robust) {  // the verdicts first: the held copies are of the accepted pairs
      judge(slam, robots, *part, *solved.robust, done);
      applyVerdicts(slam, done, t);
    }
    Values solution = solved.estimate;
    solution.insert(solved.neighbours.begin(), solved.neighbours.end());
    // Members that left during the solve (the node's rule) are gone for good for this robot too:
    // their later rendezvous skipped, no later solve includes them; of their landmarks it takes
    // what the solution holds (what they sent before they left), and keeps its copies of the rest.
    std::set<int> left_solve;
    for (int local : solved.left) {
      const int r = robots.at(static_cast<std::size_t>(local));
      left_solve.insert(r);
      if (hasLeft(r, t)) continue;
      markLeft(r, t, fmt::format("left during the group solve of step {}", t));
    }
    GroupUpdate update = RobotGroupUpdate(robots, robot_, solution, accepted(), t, left_solve);
    done.estimate = update.estimate;
    done.held = update.held;
    done.rotation_rounds = static_cast<std::uint32_t>(solved.rotation_rounds);
    done.pose_rounds = static_cast<std::uint32_t>(solved.pose_rounds);
    done.refine_steps = static_cast<std::uint32_t>(solved.program.refine.iterations);
    done.protocol_steps = static_cast<std::uint32_t>(solved.program.channel_steps);
    done.refine_status = solved.program.refine.status;
    record(done);
    if (!solve_dir.empty()) std::filesystem::remove_all(solve_dir);  // the record replaces it
    finishSolve(slam, t, robots, done, transport_.stats() - before, t0, false);
  }

  // Attempt `attempt` (solve `solve`) of the group solve of step t: publishes the robot's joining
  // status and forms the group with its partners in `range` (or takes the group journaled for
  // this attempt: restarted in the solve); false when it has no partner left to solve with.
  bool joinGroup(int t, const std::set<int>& range, std::uint32_t solve, int attempt,
                 std::vector<int>& robots, std::vector<TeamPair>& team) {
    robots.clear();
    team.clear();
    std::set<int> partners;
    for (const SharedObject& o : pairs_.shared()) {
      const int a = o.alpha_object.robot, b = o.beta_object.robot;
      const int other = a == robot_ ? b : (b == robot_ ? a : robot_);
      if (other != robot_ && range.count(other) && !hasLeft(other, t)) partners.insert(other);
    }
    if (partners.empty()) return false;  // linked to no robot in range: nothing to solve together
    StatusPacket join;
    join.robot = robot_;
    join.solve = solve;
    join.neighbours.assign(partners.begin(), partners.end());
    // All its pairs with other robots, and its copies of their landmarks: formGroup keeps those
    // with robots outside the group it forms (GroupTeamFactors picks among the members' copies),
    // so the pairs with a partner found gone while the group forms are held ones.
    for (const TeamPair& p : RobotTeamPairs(robot_, accepted(), held_, {robot_})) {
      TeamPairEntry e;
      e.mine = p.mine.index;
      e.other_robot = p.other.robot;
      e.other = p.other.index;
      e.mine_is_alpha = p.mine_is_alpha;
      if (p.held) {
        e.held = true;
        e.step = static_cast<std::uint32_t>(p.copy.step);
        e.pose = p.copy.pose;
      }
      join.team.push_back(e);
    }
    std::sort(join.team.begin(), join.team.end(), TeamPairBefore);
    transport_.publish(join);
    // Drop what earlier solves left; wait for the joining statuses of the closure.
    inbox_.dropPendingBefore(solve, SolveBefore);
    if (const auto journaled = journaled_groups_.find(t);
        journaled != journaled_groups_.end() && attempt == journaledAttempt(t)) {
      robots = journaled->second.robots;  // restarted in the solve: its partners formed it
      team = journaled->second.team;
      return true;
    }
    formGroup(join, partners, range, solve, t, robots, team);
    if (robots.size() < 2) return false;  // its partners in range have all left
    record(GroupRecord{static_cast<std::uint32_t>(t), robots, team});
    ++group_records_[t];
    return true;
  }

  // A group solve of step t taken from the journal (restart): the robot's map and held copies
  // after it, as computed then; nothing is sent. False when the journal does not hold it.
  bool replaySolve(ObjectSlam& slam, int t) {
    const auto solve = journaled_solves_.find(t);
    if (solve == journaled_solves_.end()) return false;
    finishSolve(slam, t, journaled_groups_.at(t).robots, solve->second, TransportStats{},
                Clock::now(), true);
    return true;
  }

  void finishSolve(ObjectSlam& slam, int t, const std::vector<int>& robots, const SolveRecord& done,
                   const TransportStats& sent, Clock::time_point t0, bool replayed) {
    if (!done.unlinked) {
      if (options_.dgs.gnc && replayed) applyVerdicts(slam, done, t);
      for (const auto& [k, x] : done.held) held_[k] = x;
      slam.setEstimate(done.estimate);
      slam.setTeamFactors(
          TeamFactors(robot_, accepted(), held_, options_.slam.rendezvous.lambda()));
    }
    SessionSolve rec;
    rec.step = t;
    rec.robots = robots;
    rec.object_object = static_cast<int>(done.object_object);
    rec.team_factors = static_cast<int>(done.team_factors);
    rec.rotation_rounds = static_cast<int>(done.rotation_rounds);
    rec.pose_rounds = static_cast<int>(done.pose_rounds);
    rec.refine_steps = static_cast<int>(done.refine_steps);
    rec.refine_status = done.refine_status;
    rec.protocol_steps = static_cast<int>(done.protocol_steps);
    rec.estimate = slam.estimate();
    rec.unlinked = done.unlinked;
    rec.set_aside = static_cast<int>(pairs_.setAside().size());
    rec.observation_outliers = static_cast<int>(done.rejected.size());
    rec.sent = sent;
    rec.replayed = replayed;
    rec.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    saveMap(slam, fmt::format("step_{:04d}", t));
    result_.solves.push_back(rec);
    if (options_.on_solve) options_.on_solve(result_.solves.back());
  }

  // ---- robust group solves (dgs.gnc; OnlineTeam's verdicts, each robot on its own pairs) ----
  // Its shared pairs not set aside.
  std::vector<SharedObject> accepted() const { return pairs_.accepted(); }

  // The factors of its own graph whose weight is not 1 (rejected by its last robust solve).
  static std::vector<std::uint32_t> rejectedFactors(const ObjectSlam& slam) {
    std::vector<std::uint32_t> out;
    const std::vector<double>& w = slam.factorWeights();
    for (std::size_t j = 0; j < w.size(); ++j) {
      if (w[j] != 1.0) out.push_back(static_cast<std::uint32_t>(j));
    }
    return out;
  }

  // The solve's verdicts into `done`: its pairs with the group's robots judged (a separator's
  // weight is its lower robot's, the same on both sides), the pairs set aside after it, and the
  // factors of its own graph rejected.
  void judge(const ObjectSlam& slam, const std::vector<int>& robots, const RobotGroupPart& part,
             const RobustProgramResult& solved, SolveRecord& done) const {
    const JudgedPairs pairs = PairsJudged(part.subgraph, solved.weights, robots);
    const PairVerdicts verdicts =
        JudgePairs(pairs_.shared(), pairs_.setAside(), pairs.judged, pairs.rejected);
    for (const SharedObject& s : verdicts.set_aside) {
      done.set_aside.emplace_back(s.alpha_object, s.beta_object);
    }
    done.rejected = RejectedOwnFactors(solved.weights, part.own_first, slam.numFactors());
  }

  // The verdicts of a solve record (computed now or journaled) into its state: the pairs set
  // aside, and its own factors' weights (GNC's min_weight for the rejected ones).
  void applyVerdicts(ObjectSlam& slam, const SolveRecord& done, int t) {
    std::vector<double> w(slam.numFactors(), 1.0);
    for (std::uint32_t j : done.rejected) {
      if (j >= w.size()) {
        throw InvalidInputError(fmt::format("robot {}: the solve of step {} rejects factor {} of "
                                            "its {} (journal of another run?)",
                                            robot_, t, j, w.size()));
      }
      w[j] = options_.dgs.gnc->min_weight;
    }
    pairs_.setAside(done.set_aside, t);
    slam.setFactorWeights(std::move(w));
  }

  // Waits for the joining statuses of the closure of `partners` within `range` (after publishing
  // `join`); the group's robots and its held factors from every member's status.
  // `closure` (optional): the robots of the closure, increasing, those that left included.
  void formGroup(const StatusPacket& join, const std::set<int>& partners,
                 const std::set<int>& range, std::uint32_t solve, int t, std::vector<int>& robots,
                 std::vector<TeamPair>& team, std::vector<int>* closure = nullptr) {
    std::set<int> group{robot_};
    group.insert(partners.begin(), partners.end());
    const auto deadline = Clock::now() + options_.dgs.join_timeout;
    std::map<int, Clock::time_point> not_alive_since;
    transport_detail::JoiningStatuses heard;
    while (true) {
      // The first status of each (not its DgsNode's later ones: a robot that read those formed
      // another closure, and took the batch solve of the whole team while the others left it).
      heard = transport_detail::ReadJoiningStatuses(inbox_.pending(), solve, range);
      transport_detail::GrowClosure(group, heard.neighbours, &range);
      std::vector<int> missing;
      for (int r : group) {
        if (r != robot_ && !heard.neighbours.count(r) && !hasLeft(r, t) &&
            !foundLeft(r, t, not_alive_since)) {
          missing.push_back(r);
        }
      }
      if (missing.empty()) break;
      if (Clock::now() > deadline) {
        throw Error(fmt::format("robot {}: the group solve of step {} did not form within {} ms: "
                                "no status from robot(s) {}",
                                robot_, t, options_.dgs.join_timeout.count(),
                                fmt::join(missing, ", ")));
      }
      ingest(transport_.poll(std::chrono::milliseconds(50)));
    }
    if (closure) closure->assign(group.begin(), group.end());
    std::vector<int> heard_members;
    for (int r : group) {
      if (heard.neighbours.count(r)) heard_members.push_back(r);
    }
    membership_->applyGoneLists(heard_members, t);  // gone for one, gone for all (self: it leaves)
    for (int r : group) {  // without the robots that left
      if (r == robot_ || (heard.neighbours.count(r) && !hasLeft(r, t))) robots.push_back(r);
    }
    heard.team[robot_] = join.team;
    team = transport_detail::GroupHeldPairs(robots, heard.team);
  }

  // The robot's map (its graph and estimate, g2o with objects, and TUM) in
  // <state_dir>/maps/<name>/, written to a temporary folder first.
  void saveMap(const ObjectSlam& slam, const std::string& name) const {
    if (options_.dgs.state_dir.empty()) return;
    const std::filesystem::path dir = std::filesystem::path(options_.dgs.state_dir) / "maps";
    const std::filesystem::path tmp = dir / (name + ".tmp"), final_dir = dir / name;
    std::filesystem::remove_all(tmp);
    std::filesystem::create_directories(tmp);
    G2oWriteOptions write;
    write.scheme = KeyScheme::kWithObjects;
    WriteG2oFile((tmp / "map.g2o").string(), slam.graph(), slam.estimate(), write);
    WriteTumTrajectories(tmp.string(), slam.estimate());
    std::filesystem::remove_all(final_dir);
    std::filesystem::rename(tmp, final_dir);
  }

  // ---- journal ------------------------------------------------------------------------------
  // Takes what the journal held when it was opened (session_journal.h): the answers, groups and
  // solves of a process before this one, and the partners it found gone.
  void restore() {
    const transport_detail::SessionJournalContents& held = journal_->contents();
    for (const auto& [index, event] : held.events) journaled_[index] = {event.pairs, event.removed};
    journaled_groups_ = held.groups;
    group_records_ = held.group_records;
    journaled_solves_ = held.solves;
    for (const LeftRecord& left : held.left) {
      membership_->restore(left.robot, static_cast<int>(left.step));  // self: left the team
    }
    if (!journaled_.empty()) {
      options_.log(fmt::format("restart: {} rendezvous taken from {}", journaled_.size(),
                               journal_->path()));
    }
    if (!journaled_solves_.empty()) {
      options_.log(fmt::format("restart: {} group solves taken from {}", journaled_solves_.size(),
                               journal_->path()));
    }
  }

  // Appends one record to the journal, if there is one.
  template <typename Record>
  void record(const Record& r) {
    if (journal_) journal_->append(r);
  }

  // ---- messages -----------------------------------------------------------------------------
  void publishList(const ObjectSlam& slam, int step) {
    ObjectListPacket p;
    p.robot = robot_;
    p.revision = ++revision_;
    p.step = static_cast<std::uint32_t>(step);
    for (const ObjectMapEntry& o : MakeObjectMapMessage(slam).objects) {
      p.objects.push_back({o.landmark, o.label, o.pose});
    }
    transport_.publish(p);
  }

  void sendAnswer(const RendezvousEvent& e, const EventPairs& pairs) {
    SharedObjectsPacket p;
    p.sender = robot_;
    p.receiver = e.alpha;
    p.step = static_cast<std::uint32_t>(e.step);
    for (const auto& [a, b] : pairs.pairs) p.pairs.emplace_back(a, b);
    for (const auto& [a, b] : pairs.removed) p.removed.emplace_back(a, b);
    transport_.send(p);
  }

  void ingest(std::vector<Received> packets) {
    for (Received& r : packets) {
      membership_->onPacket(r);
      inbox_.add(std::move(r));
    }
  }

  // Polls until `ready()` (true) or until the peer is found gone for good (false:
  // foundLeft); throws at the rendezvous timeout.
  template <typename Ready>
  bool waitFor(const RendezvousEvent& e, const char* what, Ready ready) {
    const int peer = e.alpha == robot_ ? e.beta : e.alpha;
    const auto deadline = Clock::now() + options_.rendezvous_timeout;
    std::map<int, Clock::time_point> not_alive_since;
    while (!ready()) {
      if (foundLeft(peer, e.step, not_alive_since)) return false;
      if (Clock::now() > deadline) {
        throw Error(fmt::format("robot {}: no {} from robot {} for the rendezvous of step {} "
                                "within {} ms (not started, gone, or out of reach)",
                                robot_, what, e.alpha == robot_ ? e.beta : e.alpha, e.step,
                                options_.rendezvous_timeout.count()));
      }
      ingest(transport_.poll(std::chrono::milliseconds(100)));
    }
    return true;
  }

  // The attempt of the solve of step t whose group the journal holds last (0: none).
  int journaledAttempt(int t) const {
    const auto it = group_records_.find(t);
    return it == group_records_.end() ? 0 : it->second - 1;
  }

  // ---- robots that leave for good (team_membership.h) ---------------------------------------
  void noteLeftTeam() {
    result_.left_team = membership_->out();
    result_.left_team_step = membership_->outStep();
  }
  bool hasLeft(int robot, int t) const { return membership_->hasLeft(robot, t); }
  bool foundLeft(int robot, int t, std::map<int, Clock::time_point>& not_alive_since) {
    return membership_->foundLeft(robot, t, not_alive_since);
  }
  void markLeft(int robot, int t, const std::string& why) { membership_->markLeft(robot, t, why); }

  // Alpha's list of the event's step, as the in-process beta decodes it (float32 poses).
  // None: alpha left for good.
  std::optional<ObjectMapMessage> awaitList(const RendezvousEvent& e) {
    std::deque<ObjectListPacket>& lists =
        inbox_.lists(e.alpha, static_cast<std::uint32_t>(e.step));
    ObjectMapMessage received;
    const bool ready = waitFor(e, "object list", [&]() {
      if (lists.empty()) return false;
      ObjectMapMessage m;
      m.sender = e.alpha;
      try {
        for (const ObjectObservation& o : lists.front().objects) {
          if (o.id > 0xFFFFFFFFu)
            throw InvalidInputError(fmt::format("object id {} exceeds 32 bits", o.id));
          m.objects.push_back({static_cast<std::uint32_t>(o.id), o.label, o.pose});
        }
        received = DecodeObjectMap(EncodeObjectMap(m));
        return true;
      } catch (const InvalidInputError& err) {
        options_.log(fmt::format("rejected: object list of robot {} for step {}: {}", e.alpha,
                                 e.step, err.what()));
        lists.pop_front();  // a duplicate (restart) may follow
        return false;
      }
    });
    if (!ready) return std::nullopt;
    return received;
  }

  // Beta's answer to this robot's list of the event's step; one SessionPairs::checkAnswer refuses
  // is logged and dropped (a later one may follow). None: beta left for good.
  std::optional<EventPairs> awaitAnswer(const RendezvousEvent& e, const ObjectSlam& slam) {
    std::deque<SharedObjectsPacket>& answers =
        inbox_.answers(e.beta, static_cast<std::uint32_t>(e.step));
    EventPairs pairs;
    const bool ready = waitFor(e, "shared-object answer", [&]() {
      if (answers.empty()) return false;
      const SharedObjectsPacket& answer = answers.front();
      const std::string why = pairs_.checkAnswer(answer, slam.landmarks().size(),
                                                 options_.slam.known_initial_poses);
      if (!why.empty()) {
        options_.log(fmt::format("rejected: shared objects of robot {} for step {}: {}", e.beta,
                                 e.step, why));
        answers.pop_front();
        return false;
      }
      for (const auto& [a, b] : answer.pairs) {
        pairs.pairs.emplace_back(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
      }
      for (const auto& [a, b] : answer.removed) {
        pairs.removed.emplace_back(static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
      }
      answers.clear();
      return true;
    });
    if (!ready) return std::nullopt;
    return pairs;
  }

  RobotScenarioData data_;
  Transport& transport_;
  RobotSessionOptions options_;
  int robot_ = 0;
  bool ran_ = false;
  std::unique_ptr<transport_detail::SessionJournal> journal_;
  std::map<std::size_t, EventPairs> journaled_;  // event index -> what it changed
  std::map<int, GroupRecord> journaled_groups_;  // by step: groups formed (batch: the end)
  std::map<int, int> group_records_;  // by step: group records journaled (one per attempt)
  std::map<int, SolveRecord> journaled_solves_;  // online, by step: group solves finished
  std::uint32_t revision_ = 0;
  transport_detail::SessionPairs pairs_;  // its shared pairs, and those set aside (online robust)
  transport_detail::SessionInbox inbox_;  // received, not used yet
  HeldEstimates held_;             // online: the partner landmarks it holds (online/group_solve.h)
  std::unique_ptr<TeamMembership> membership_;  // which robots it still counts on
  RobotSessionResult result_;
};

RobotSession::RobotSession(RobotScenarioData data, Transport& transport,
                           RobotSessionOptions options)
    : impl_(std::make_unique<Impl>(std::move(data), transport, std::move(options))) {}
RobotSession::~RobotSession() = default;
RobotSessionResult RobotSession::run() { return impl_->run(); }

}  // namespace moslam
