#include "moslam/transport/robot_session.h"

#include <fmt/core.h>

#include <cmath>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/sim/world.h"
#include "moslam/slam/constellation.h"
#include "moslam/slam/rendezvous.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/online_group_solves.h"
#include "moslam/transport/session_batch.h"
#include "moslam/transport/session_channel.h"
#include "moslam/transport/session_fingerprint.h"
#include "moslam/transport/session_journal.h"
#include "moslam/transport/session_pairs.h"

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
  if (!(ambiguity_ratio >= 0.0 && ambiguity_ratio < 1.0)) {
    bad("ambiguity_ratio must be in [0, 1) (0: off)");
  }
  if (!(covariance_gate >= 0.0) || !std::isfinite(covariance_gate)) {
    bad("covariance_gate must be finite and >= 0 (0: off)");
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
  config.slam.ambiguity_ratio = spec.ambiguity_ratio;
  config.slam.covariance_gate = spec.covariance_gate;
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

using transport_detail::EventRecord;
using Pairs = transport_detail::ObjectPairs;

// What an event changed: the pairs added and the pairs shared before that it removed, (alpha
// landmark, beta landmark) each.
struct EventPairs {
  Pairs pairs;
  Pairs removed;
};

}  // namespace

// Throws InvalidInputError unless the data is one robot's of a team: its robot among num_robots,
// the initial poses of all when they are known (unknown: whatever the data holds is never read),
// one odometry reading between every two steps, and rendezvous events of two distinct robots of
// the team at steps of the scenario, in order.
void CheckSessionData(const RobotScenarioData& data, bool known_initial_poses) {
  const int n = data.num_robots, steps = data.numSteps(), robot = data.robot;
  const bool poses_ok = !known_initial_poses || static_cast<int>(data.initial_poses.size()) == n;
  if (robot < 0 || robot >= n || !poses_ok || steps < 1 ||
      static_cast<int>(data.measurements.odometry.size()) != steps - 1) {
    throw InvalidInputError(
        fmt::format("robot session: inconsistent data for robot {} of {}", robot, n));
  }
  for (std::size_t i = 0; i < data.events.size(); ++i) {
    const RendezvousEvent& e = data.events[i];
    if (e.alpha < 0 || e.alpha >= n || e.beta < 0 || e.beta >= n || e.alpha == e.beta ||
        e.step < 0 || e.step >= steps || (i > 0 && e.step < data.events[i - 1].step)) {
      throw InvalidInputError(fmt::format(
          "robot session: rendezvous event {} (step {}, robots {} and {}) does not fit the "
          "scenario or is out of order",
          i, e.step, e.alpha, e.beta));
    }
  }
}

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
    CheckSessionData(data_, options_.slam.known_initial_poses);
    if (!options_.log) {
      const int r = robot_;
      options_.log = [r](const std::string& text) {
        fmt::print(stderr, "moslam robot {}: {}\n", r, text);
        std::fflush(stderr);
      };
    }
    transport_detail::SessionChannel::Options channel;
    channel.join_timeout = options_.dgs.join_timeout;
    channel.leave_timeout = options_.dgs.leave_timeout;
    channel.log = options_.log;
    channel_ = std::make_unique<transport_detail::SessionChannel>(
        robot_, data_.num_robots, transport_, std::move(channel), openJournal());
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
      std::vector<std::size_t> mine;  // this robot's events of step t
      for (; next < data_.events.size() && data_.events[next].step == t; ++next) {
        const RendezvousEvent& e = data_.events[next];
        if (e.alpha == robot_ || e.beta == robot_) mine.push_back(next);
      }
      if (!mine.empty()) rendezvousAt(slam, t, mine);
    }
    finish(slam, t0);
    return result_;
  }

 private:
  // This robot's rendezvous events `mine` of step t, met in order; online, then the group solve.
  void rendezvousAt(ObjectSlam& slam, int t, const std::vector<std::size_t>& mine) {
    channel_->membership().noteAlive();
    // As RunMultiRobotObjectSlam: both robots refresh before an event (the later events of the
    // same step find nothing new).
    slam.refresh(options_.slam.slam.iterations_per_update);
    bool list_published = false;
    for (std::size_t index : mine) {
      result_.rendezvous.push_back(meet(slam, index, list_published));
      result_.rendezvous_binary_bytes += result_.rendezvous.back().binary_bytes;
      if (options_.on_rendezvous) options_.on_rendezvous(result_.rendezvous.back());
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

  // After the last step: the robot's own map optimized and recorded, then (batch) the team's
  // solve, or (online) its map as it stands.
  void finish(ObjectSlam& slam, Clock::time_point t0) {
    slam.optimize(options_.slam.final_iterations);
    result_.slam_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    result_.rendezvous_transport = transport_.stats();
    result_.shared = pairs_.shared();
    result_.initial = slam.estimate();
    result_.poses = slam.numPoses();
    result_.landmarks = static_cast<int>(slam.landmarks().size());
    if (options_.online) {  // its map is its result, solved at every rendezvous
      result_.final_estimate = slam.estimate();
      result_.set_aside = pairs_.setAside();
      transport_detail::SaveSessionMap(options_.dgs.state_dir, slam, "final");
      result_.seconds = result_.slam_seconds;
    } else {
      transport_detail::SessionBatchSolve(*channel_, pairs_, data_.num_robots, data_.numSteps(),
                                          options_)
          .run(slam, result_);
      result_.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    }
    result_.left_team = channel_->membership().out();
    result_.left_team_step = channel_->membership().outStep();
  }

  // The session's journal in state_dir (rendezvous.bin, keyed by the run's fingerprint), or none
  // without a state directory.
  std::unique_ptr<transport_detail::SessionJournal> openJournal() const {
    if (options_.dgs.state_dir.empty()) return nullptr;
    CreateFolder(options_.dgs.state_dir, "robot state");
    transport_detail::SessionJournalRun run;
    run.robot = robot_;
    run.fingerprint = transport_detail::SessionFingerprint(data_, options_);
    run.num_robots = data_.num_robots;
    run.num_steps = static_cast<std::uint32_t>(data_.numSteps());
    run.num_events = data_.events.size();
    run.online = options_.online;
    return std::make_unique<transport_detail::SessionJournal>(
        (std::filesystem::path(options_.dgs.state_dir) / "rendezvous.bin").string(), run,
        options_.dgs.state_dir);
  }

  // Rendezvous event `index` of the current step: alpha publishes its object list (once per
  // step) and waits for beta's answer; beta waits for the list and answers; a journaled event is
  // replayed (beta answers again: the old process may have died before alpha heard it), and an
  // event whose peer left for good is skipped. What it changed is applied to the shared pairs.
  SessionRendezvous meet(const ObjectSlam& slam, std::size_t index, bool& list_published) {
    const RendezvousEvent& e = data_.events[index];
    SessionRendezvous rec;
    rec.event = e;
    rec.alpha = e.alpha == robot_;
    const auto te = Clock::now();
    const int peer = rec.alpha ? e.beta : e.alpha;
    EventPairs pairs;
    const auto journaled = journaled_.find(index);
    const bool peer_left = journaled == journaled_.end() && channel_->hasLeft(peer, e.step);
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
        publishList(slam, e.step);
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
      ConstellationAlignment alignment;
      const SharedObjectsMessage answer = AnswerObjectMap(
          *received, slam, beta_T_alpha, pairs_.shared(), options_.slam.rendezvous, &alignment);
      if (!beta_T_alpha && alignment.status != AlignmentStatus::kAligned) {
        options_.log(fmt::format(
            "rendezvous with robot {} at step {}: alignment refused, {} (largest consistent set "
            "{} objects, rival {}, of {} label-consistent pairs): no new pairs",
            e.alpha, e.step, ToString(alignment.status), alignment.support, alignment.rival,
            alignment.candidates));
      }
      pairs = {answer.pairs, answer.removed};
      sendAnswer(e, pairs);
      channel_->record(EventRecord{static_cast<std::uint32_t>(index), pairs.pairs, pairs.removed});
    } else {
      rec.skipped = true;
    }
    if (!rec.skipped) applyPairs(e, pairs, rec);  // skipped: the peer left, nothing exchanged
    rec.seconds = std::chrono::duration<double>(Clock::now() - te).count();
    return rec;
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
