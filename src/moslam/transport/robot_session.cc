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
#include "moslam/io/g2o.h"
#include "moslam/online/group_solve.h"
#include "moslam/robust/gnc.h"
#include "moslam/sim/world.h"
#include "moslam/slam/rendezvous.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/group_transport.h"
#include "moslam/transport/online_group_solves.h"
#include "moslam/transport/session_channel.h"
#include "moslam/transport/session_fingerprint.h"
#include "moslam/transport/session_journal.h"
#include "moslam/transport/session_pairs.h"
#include "moslam/transport/solve_record.h"

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
using transport_detail::AttemptSolve;
using transport_detail::GroupIds;
using transport_detail::GroupRecord;

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
    std::unique_ptr<transport_detail::SessionJournal> journal;
    if (!options_.dgs.state_dir.empty()) {
      std::filesystem::create_directories(options_.dgs.state_dir);
      transport_detail::SessionJournalRun run;
      run.robot = robot_;
      run.fingerprint = transport_detail::SessionFingerprint(data_, options_);
      run.num_robots = data_.num_robots;
      run.num_steps = static_cast<std::uint32_t>(data_.numSteps());
      run.num_events = data_.events.size();
      run.online = options_.online;
      journal = std::make_unique<transport_detail::SessionJournal>(
          (std::filesystem::path(options_.dgs.state_dir) / "rendezvous.bin").string(), run,
          options_.dgs.state_dir);
    }
    transport_detail::SessionChannel::Options channel;
    channel.join_timeout = options_.dgs.join_timeout;
    channel.leave_timeout = options_.dgs.leave_timeout;
    channel.log = options_.log;
    channel_ = std::make_unique<transport_detail::SessionChannel>(
        robot_, n, transport_, std::move(channel), std::move(journal));
    for (const auto& [index, event] : channel_->journaled().events) {
      journaled_[index] = {event.pairs, event.removed};
    }
    if (options_.online) {
      online_ = std::make_unique<transport_detail::OnlineGroupSolves>(*channel_, pairs_,
                                                                      data_.events, options_);
    }
  }

  RobotSessionResult run() {
    if (ran_) throw InvalidInputError("robot session: run() is called once");
    ran_ = true;
    const auto t0 = Clock::now();
    std::set<int> everyone;
    for (int r = 0; r < data_.num_robots; ++r) everyone.insert(r);
    transport_.setKnownRobots(everyone);
    channel_->membership().publishPresence();  // liveliness before the first solve

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
      channel_->membership().noteAlive();
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
        const bool peer_left = journaled == journaled_.end() && channel_->hasLeft(peer, t);
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
            channel_->record(
                EventRecord{static_cast<std::uint32_t>(index), pairs.pairs, pairs.removed});
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
          channel_->record(
              EventRecord{static_cast<std::uint32_t>(index), pairs.pairs, pairs.removed});
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
      channel_->inbox().dropListsUpTo(static_cast<std::uint32_t>(t));
      if (online_) {
        if (std::optional<SessionSolve> solved = online_->solve(slam, t)) {
          result_.solves.push_back(std::move(*solved));
          if (options_.on_solve) options_.on_solve(result_.solves.back());
        }
      }
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
      transport_detail::SaveSessionMap(options_.dgs.state_dir, slam, "final");
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
    for (int attempt = channel_->journaledAttempt(end);; ++attempt) {
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
          channel_->markLeft(departures ? robots.at(static_cast<std::size_t>(r)) : r, end,
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
    PrefetchedTransport dgs_transport(transport_, channel_->inbox().takePending());
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
  // waits for those of the closure (SessionChannel::formGroup): a robot that left for good
  // publishes none and is found gone (or was, at a rendezvous), so every robot of the closure
  // finds the same departures. Returns whether some robot of `closure` (increasing, this robot
  // among them) left; `robots`: the closure without them. The closure is journaled (a group record of step T), so a
  // robot restarted in the solve takes the same way.
  // Attempt a > 0 (the team formed again: run()) uses solve AttemptSolve(1 + T, a).
  bool batchGroup(std::vector<int>& closure, std::vector<int>& robots, int attempt) {
    const int end = data_.numSteps();
    if (channel_->membership().out()) {  // it left the team: its own map is its result
      closure = robots = {robot_};
      return true;
    }
    const auto solve = AttemptSolve(static_cast<std::uint32_t>(end + 1), attempt);
    if (const transport_detail::GroupRecord* journaled = channel_->journaledGroup(end, attempt)) {
      closure = journaled->robots;
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
      channel_->formGroup(join, partners, everyone, solve, end, robots, none, &closure);
      channel_->recordGroup(GroupRecord{static_cast<std::uint32_t>(end), closure, {}});
    }
    robots.clear();
    for (int r : closure) {
      if (r == robot_ || !channel_->hasLeft(r, end)) robots.push_back(r);
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
        transport_, robots, solve, [this](Received r) { channel_->ingest({std::move(r)}); },
        channel_->inbox().takePending(solve));
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
    write.atomic = true;
    WriteG2oFile((dir / "result.g2o").string(), result_.subgraph, result_.dgs.estimate, write);
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

  // Polls until `ready()` (true) or until the peer is found gone for good (false:
  // foundLeft); throws at the rendezvous timeout.
  template <typename Ready>
  bool waitFor(const RendezvousEvent& e, const char* what, Ready ready) {
    const int peer = e.alpha == robot_ ? e.beta : e.alpha;
    const auto deadline = Clock::now() + options_.rendezvous_timeout;
    std::map<int, Clock::time_point> not_alive_since;
    while (!ready()) {
      if (channel_->foundLeft(peer, e.step, not_alive_since)) return false;
      if (Clock::now() > deadline) {
        throw Error(fmt::format("robot {}: no {} from robot {} for the rendezvous of step {} "
                                "within {} ms (not started, gone, or out of reach)",
                                robot_, what, e.alpha == robot_ ? e.beta : e.alpha, e.step,
                                options_.rendezvous_timeout.count()));
      }
      channel_->ingest(transport_.poll(std::chrono::milliseconds(100)));
    }
    return true;
  }

  // ---- robots that leave for good (team_membership.h) ---------------------------------------
  void noteLeftTeam() {
    result_.left_team = channel_->membership().out();
    result_.left_team_step = channel_->membership().outStep();
  }

  // Alpha's list of the event's step, as the in-process beta decodes it (float32 poses).
  // None: alpha left for good.
  std::optional<ObjectMapMessage> awaitList(const RendezvousEvent& e) {
    std::deque<ObjectListPacket>& lists =
        channel_->inbox().lists(e.alpha, static_cast<std::uint32_t>(e.step));
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
        channel_->inbox().answers(e.beta, static_cast<std::uint32_t>(e.step));
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
  std::map<std::size_t, EventPairs> journaled_;  // event index -> what it changed (restart)
  std::uint32_t revision_ = 0;
  transport_detail::SessionPairs pairs_;  // its shared pairs, and those set aside (online robust)
  std::unique_ptr<transport_detail::SessionChannel> channel_;  // transport, inbox, journal, team
  std::unique_ptr<transport_detail::OnlineGroupSolves> online_;  // online: the group solves
  RobotSessionResult result_;
};

RobotSession::RobotSession(RobotScenarioData data, Transport& transport,
                           RobotSessionOptions options)
    : impl_(std::make_unique<Impl>(std::move(data), transport, std::move(options))) {}
RobotSession::~RobotSession() = default;
RobotSessionResult RobotSession::run() { return impl_->run(); }

}  // namespace moslam
