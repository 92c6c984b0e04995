// Robot sessions (robot_session.h) as threads over the in-process transport: the rendezvous
// exchange and the DGS give the in-process pipeline's result (RunMultiRobotObjectSlam,
// AssembleJointProblem, RunDgs in Jacobi order); forged object lists and answers are rejected and
// logged; a robot that crashes in the rendezvous phase and restarts from its journal loses
// nothing. Between processes over DDS: apps/team_test.cc.
#include "moslam/transport/robot_session.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/metrics/metrics.h"
#include "moslam/online/group_solve.h"
#include "moslam/slam/constellation.h"
#include "moslam/transport/dying_transport_test_util.h"
#include "moslam/transport/in_process_transport.h"
#include "moslam/transport/session_test_util.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

// Three robots, 40 poses: a few rendezvous, every robot linked to robot 0.
ScenarioSpec Small() {
  ScenarioSpec s;
  s.scenario = "chairs25";
  s.robots = 3;
  s.poses_per_robot = 40;
  s.seed = 1;
  return s;
}

struct Reference {
  MultiRobotSlamResult slam;
  JointProblem joint;
  DgsResult dgs;
  std::set<std::vector<std::uint64_t>> shared;
};

std::vector<std::uint64_t> Tuple(const SharedObject& o) {
  return {static_cast<std::uint64_t>(o.beta_object.robot), o.beta_object.index,
          static_cast<std::uint64_t>(o.alpha_object.robot), o.alpha_object.index};
}

Reference InProcess(const ScenarioSpec& spec, const SimulationData& data) {
  Reference r;
  const MultiRobotSlamConfig config = ScenarioSlamConfig(spec);
  r.slam = RunMultiRobotObjectSlam(data, config);
  r.joint = AssembleJointProblem(r.slam.robots, r.slam.shared, config.rendezvous.lambda());
  r.dgs = RunDgs(r.joint.graph, r.joint.initial, DriverOptions(DgsNodeOptions{}));
  for (const SharedObject& o : r.slam.shared) r.shared.insert(Tuple(o));
  return r;
}

class Log {
 public:
  std::function<void(const std::string&)> sink() {
    return [this](const std::string& s) {
      std::lock_guard<std::mutex> lock(mutex_);
      lines_.push_back(s);
      logged_.notify_all();
    };
  }
  bool contains(const std::string& text) {
    std::lock_guard<std::mutex> lock(mutex_);
    return has(text);
  }
  // Blocks until a line contains `text`.
  void waitFor(const std::string& text) {
    std::unique_lock<std::mutex> lock(mutex_);
    logged_.wait(lock, [&] { return has(text); });
  }

 private:
  bool has(const std::string& text) const {
    for (const std::string& l : lines_) {
      if (l.find(text) != std::string::npos) return true;
    }
    return false;
  }
  std::mutex mutex_;
  std::condition_variable logged_;
  std::vector<std::string> lines_;
};

RobotSessionOptions Options(const ScenarioSpec& spec, Log& log, const std::string& state_dir = {}) {
  RobotSessionOptions o;
  o.slam = ScenarioSlamConfig(spec);
  // Bounds of waiting for a partner, there only to end a broken run: no test waits them out (a
  // robot that leaves is found by leave_timeout). Wide, as a partner busy with a group solve of
  // its own may be far behind on a loaded machine: 31.6 s with 14 busy loops beside the robust
  // restart test on 2 cores, whose quiet run takes 6 s; with 20 s they failed it.
  o.dgs.join_timeout = milliseconds(120000);
  o.dgs.stall_timeout = milliseconds(120000);
  o.dgs.finish_timeout = milliseconds(5000);
  o.dgs.state_dir = state_dir;
  o.rendezvous_timeout = milliseconds(120000);
  o.log = log.sink();
  return o;
}

// Checks a team's results against the in-process pipeline.
void ExpectEqualToInProcess(const std::vector<RobotSessionResult>& results, const Reference& ref) {
  std::set<std::vector<std::uint64_t>> shared;
  Values merged;
  std::int64_t bytes = 0;
  std::size_t alpha_events = 0;
  for (std::size_t r = 0; r < results.size(); ++r) {
    for (const SharedObject& o : results[r].shared) shared.insert(Tuple(o));
    for (const auto& [k, x] : results[r].dgs.estimate) merged.emplace(k, x);
    bytes += results[r].rendezvous_binary_bytes;
    for (const SessionRendezvous& e : results[r].rendezvous) alpha_events += e.alpha ? 1 : 0;
  }
  EXPECT_EQ(alpha_events, ref.slam.rendezvous.size());
  EXPECT_EQ(shared, ref.shared);
  EXPECT_EQ(bytes, ref.slam.bytes);  // the same messages, in the in-process encoding
  EXPECT_EQ(merged.size(), ref.dgs.values.size());
  EXPECT_LE(MaxPoseDifference(merged, ref.dgs.values), 1e-9);
}

// One session per robot, each on a thread of its own, over `transports` (robot r's at index r),
// with robot r's data from `slice`; fails the test when a session throws.
std::vector<RobotSessionResult> RunSessions(const ScenarioSpec& spec,
                                            std::vector<std::unique_ptr<Transport>>& transports,
                                            Log& log,
                                            const std::function<RobotScenarioData(int)>& slice) {
  std::vector<RobotSessionResult> results(static_cast<std::size_t>(spec.robots));
  std::vector<std::string> errors(results.size());
  std::vector<std::thread> threads;
  for (int r = 0; r < spec.robots; ++r) {
    threads.emplace_back([&, r]() {
      try {
        RobotSession session(slice(r), *transports[static_cast<std::size_t>(r)],
                             Options(spec, log));
        results[static_cast<std::size_t>(r)] = session.run();
      } catch (const std::exception& e) {
        errors[static_cast<std::size_t>(r)] = e.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& e : errors) EXPECT_EQ(e, "");
  return results;
}

// The whole team of `spec` over one in-process network, robot r with its slice of `data`.
std::vector<RobotSessionResult> RunTeam(const ScenarioSpec& spec, const SimulationData& data) {
  InProcessNetwork net;
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  return RunSessions(spec, transports, log, [&](int r) { return SliceForRobot(data, r); });
}

// What a test's hook throws to kill a robot process.
struct Crash {};

// Robot r's process killed once: its session with `first` runs until a hook of `first` throws
// Crash; then the process is gone (its transport destroyed) and restarts (a new transport, which
// receives the history), in `transport`. Returns false when the session ended without a crash.
bool RunUntilKilled(InProcessNetwork& net, Log& log, std::unique_ptr<Transport>& transport,
                    const RobotScenarioData& slice, const RobotSessionOptions& first,
                    const std::function<void()>& before_restart = {}) {
  try {
    RobotSession session(slice, *transport, first);
    session.run();
    return false;
  } catch (const Crash&) {
  }
  transport.reset();
  if (before_restart) before_restart();
  transport = net.connect(slice.robot, {log.sink()});
  return true;
}

// What a test's hook throws when a robot's process is gone for good (its battery died).
struct Gone {};

// The session with `o` throws What{} right after its `events`-th rendezvous.
template <typename What>
void ThrowAfterRendezvous(RobotSessionOptions& o, std::int64_t events) {
  auto seen = std::make_shared<std::int64_t>(0);
  o.on_rendezvous = [seen, events](const SessionRendezvous&) {
    if (++*seen == events) throw What{};
  };
}

// One session per robot, each on a thread of its own, over `transports` (robot r's at index r),
// with robot r's slice of `data` and the options `options(r)`; `before(r)`, when given, runs
// first on the robot's thread (a kill and restart: RunUntilKilled) and returns false when what
// it expected did not happen. A robot whose session throws Gone is gone for good: its transport
// closed, its result empty, listed in `*gone`. Fails the test when a session throws anything
// else.
std::vector<RobotSessionResult> RunSessionsWithFaults(
    const SimulationData& data, std::vector<std::unique_ptr<Transport>>& transports,
    const std::function<RobotSessionOptions(int)>& options, std::set<int>* gone,
    const std::function<bool(int)>& before = {}) {
  const int robots = static_cast<int>(transports.size());
  std::vector<RobotSessionResult> results(transports.size());
  std::vector<std::string> errors(results.size());
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (int r = 0; r < robots; ++r) {
    threads.emplace_back([&, r]() {
      const auto ri = static_cast<std::size_t>(r);
      try {
        if (before && !before(r)) {
          errors[ri] = "the robot's fault did not happen";
          return;
        }
        RobotSession session(SliceForRobot(data, r), *transports[ri], options(r));
        results[ri] = session.run();
      } catch (const Gone&) {
        transports[ri].reset();
        std::lock_guard<std::mutex> lock(mutex);
        gone->insert(r);
      } catch (const std::exception& e) {
        errors[ri] = e.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& e : errors) EXPECT_EQ(e, "");
  return results;
}

TEST(RobotSession, BadScenarioSpecsNameTheField) {
  using S = ScenarioSpec;
  EXPECT_TRUE(test::EachChangeIsRefused<S>({
      {"scenario must be", [](S& s) { s.scenario = "office"; }},
      {"robots must be in [1, 65535], got 0", [](S& s) { s.robots = 0; }},
      {"robots must be in [1, 65535], got 65536", [](S& s) { s.robots = 65536; }},
      {"sigma_rotation_deg", [](S& s) { s.sigma_rotation_deg = -1.0; }},
      {"sigma_translation", [](S& s) { s.sigma_translation = INFINITY; }},
      {"poses_per_robot", [](S& s) { s.poses_per_robot = 1; }},
      {"exclusion_radius", [](S& s) { s.exclusion_radius = std::nan(""); }},
      {"ambiguity_ratio", [](S& s) { s.ambiguity_ratio = 1.0; }},
      {"covariance_gate", [](S& s) { s.covariance_gate = -0.5; }},
  }));
}

TEST(RobotSession, OverTheInProcessTransportEqualsTheInProcessPipeline) {
  const ScenarioSpec spec = Small();
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  ASSERT_GE(ref.slam.rendezvous.size(), 2u);
  ASSERT_GE(ref.slam.shared.size(), 3u);

  const std::vector<RobotSessionResult> results = RunTeam(spec, data);
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
  for (const RobotSessionResult& r : results) {
    EXPECT_EQ(r.rendezvous_transport.rejected, 0);
    // Object lists and answers crossed the transport (bytes counted as such).
    if (!r.rendezvous.empty()) {
      EXPECT_GT(r.rendezvous_transport.objects_bytes, 0);
    }
  }
}

// The robots' own association options (ScenarioSpec: exclusion radius, leave-one-out check)
// reach every session's SLAM: the sessions give the in-process pipeline with them, which is not
// the one without them.
TEST(RobotSession, TheRobotsAssociationOptionsGiveTheInProcessPipelineWithThem) {
  ScenarioSpec spec = Small();
  spec.exclusion_radius = 1.0;
  spec.leave_one_out_check = true;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  EXPECT_GE(ref.slam.intra.refused, 1);
  EXPECT_GE(ref.slam.intra.discarded, 1);
  ScenarioSpec paper = spec;
  paper.exclusion_radius = 0.0;
  paper.leave_one_out_check = false;
  EXPECT_GT(MaxPoseDifference(InProcess(paper, data).dgs.values, ref.dgs.values), 1e-6);

  const std::vector<RobotSessionResult> results = RunTeam(spec, data);
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
}

// The covariance gate and the refusal of ambiguous matches (ScenarioSpec, as `moslam simulate`'s
// --covariance-gate and --ambiguity-ratio) reach every session's SLAM: each changes the in-process
// pipeline on its own and beside the other, and the sessions give the pipeline with both.
TEST(RobotSession, TheRobotsCovarianceGateAndAmbiguityRatioGiveTheInProcessPipelineWithThem) {
  ScenarioSpec spec = Small();
  spec.scenario = "house";  // kitchen chairs side by side: matches refused as ambiguous
  spec.seed = 2;
  spec.covariance_gate = 22.46;
  spec.ambiguity_ratio = 0.6;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  EXPECT_GE(ref.slam.intra.refused, 5);
  for (const auto& [what, option] : std::vector<std::pair<std::string, double ScenarioSpec::*>>{
           {"covariance gate", &ScenarioSpec::covariance_gate},
           {"ambiguity ratio", &ScenarioSpec::ambiguity_ratio}}) {
    ScenarioSpec without = spec;
    without.*option = 0.0;
    EXPECT_GT(MaxPoseDifference(InProcess(without, data).dgs.values, ref.dgs.values), 1e-6)
        << "without the " << what;
  }

  const std::vector<RobotSessionResult> results = RunTeam(spec, data);
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
}

// The robots' loop closure (slam/object_slam.h) runs inside each robot's own SLAM: the processes
// map and solve as the in-process pipeline with it.
TEST(RobotSession, TheRobotsLoopClosureGivesTheInProcessPipelineWithIt) {
  ScenarioSpec spec = Small();
  spec.scenario = "generated";
  spec.seed = 6;  // seeds 1-5 with 40 poses: no loop closed, or the team not linked
  spec.loop_closure = true;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  EXPECT_GE(ref.slam.intra.loop_closures, 4);
  ScenarioSpec paper = spec;
  paper.loop_closure = false;
  EXPECT_GT(MaxPoseDifference(InProcess(paper, data).dgs.values, ref.dgs.values), 1e-6);

  const std::vector<RobotSessionResult> results = RunTeam(spec, data);
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
}

// The rendezvous refined by the constellation of both maps (slam/rendezvous.h) runs inside each
// beta's rendezvous: the processes find the in-process pairs and estimate with it, which are not
// the ones without it.
TEST(RobotSession, TheRendezvousConstellationGivesTheInProcessPipelineWithIt) {
  ScenarioSpec spec = Small();
  spec.seed = 2;  // seeds 1-12 of chairs25, house and generated with 3 and 4 robots: the one
                  // whose pairs the refinement changes (25 pairs, 23 without)
  spec.rendezvous_constellation = true;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  ScenarioSpec proposals = spec;
  proposals.rendezvous_constellation = false;
  EXPECT_NE(InProcess(proposals, data).shared, ref.shared);

  const std::vector<RobotSessionResult> results = RunTeam(spec, data);
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
}

// Unknown initial poses: beta aligns the object maps and drops pairs of earlier rendezvous that
// the new ones contradict, as in-process; the answers carry the removed pairs. The slices hold
// random initial poses: the result does not change, so nothing reads them.
TEST(RobotSession, UnknownInitialPosesGiveTheInProcessPairsAndEstimateWithoutReadingThePoses) {
  ScenarioSpec spec = Small();
  spec.known_initial_poses = false;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  int removed = 0;
  for (const RendezvousRecord& r : ref.slam.rendezvous) removed += r.removed;
  ASSERT_GE(removed, 1);  // the removal crosses the transport in this run (3 measured)
  EXPECT_TRUE(SliceForRobot(data, 0, false).initial_poses.empty());

  InProcessNetwork net;
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  const std::vector<RobotSessionResult> results = RunSessions(spec, transports, log, [&](int r) {
    RobotScenarioData slice = SliceForRobot(data, r, true);
    std::mt19937 rng(static_cast<unsigned>(7 + r));
    std::uniform_real_distribution<double> u(-5.0, 5.0);
    for (SE3& x : slice.initial_poses) {
      x = SE3(SO3::Exp(Vector3(u(rng), u(rng), u(rng))), Vector3(u(rng), u(rng), u(rng)));
    }
    return slice;
  });
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
  int removed_seen = 0;
  for (const RobotSessionResult& r : results) {
    EXPECT_EQ(r.rendezvous_transport.rejected, 0);
    for (const SessionRendezvous& e : r.rendezvous) removed_seen += e.removed_shared;
  }
  EXPECT_EQ(removed_seen, 2 * removed);  // both robots of each event drop the pairs
  // Beta logs each alignment it refuses, with the reason, as the in-process run refused it.
  int refused = 0;
  for (const RendezvousRecord& r : ref.slam.rendezvous) {
    if (!r.alignment || *r.alignment == AlignmentStatus::kAligned) continue;
    ++refused;
    EXPECT_TRUE(
        log.contains(fmt::format("rendezvous with robot {} at step {}: alignment refused, {}",
                                 r.event.alpha, r.event.step, ToString(*r.alignment))))
        << "step " << r.event.step;
  }
  EXPECT_GE(refused, 1);
  EXPECT_FALSE(log.contains("alignment refused, aligned"));
}

TEST(RobotSession, RejectsAndLogsForgedObjectListsAndAnswersWithoutCrashing) {
  const ScenarioSpec spec = Small();
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_FALSE(data.rendezvous.empty());
  const RendezvousEvent e = data.rendezvous.front();
  const auto step = static_cast<std::uint32_t>(e.step);

  InProcessNetwork net;
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  // Waiting in the inboxes before the real messages of the first rendezvous.
  ObjectListPacket unknown;
  unknown.robot = 7;  // not a robot of the scenario
  unknown.step = step;
  unknown.objects.push_back({0, "chair", SE3()});
  net.inject(7, e.beta, unknown);
  ObjectListPacket nan;
  nan.robot = e.alpha;
  nan.step = step;
  nan.objects.push_back(
      {0, "chair", SE3(SO3(), Vector3(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0))});
  net.inject(e.alpha, e.beta, nan);
  ObjectListPacket wide = nan;
  wide.objects = {{std::uint64_t{1} << 40, "chair", SE3()}};  // valid DDS id, not a landmark index
  net.inject(e.alpha, e.beta, wide);
  SharedObjectsPacket forged;
  forged.sender = e.beta;
  forged.receiver = e.alpha;
  forged.step = step;
  forged.pairs = {{100000, 0}};  // an object the alpha robot does not have
  net.inject(e.beta, e.alpha, forged);
  SharedObjectsPacket removes = forged;
  removes.pairs.clear();
  removes.removed = {{0, 0}};  // nothing is shared before the first rendezvous
  net.inject(e.beta, e.alpha, removes);

  const std::vector<RobotSessionResult> results =
      RunSessions(spec, transports, log, [&](int r) { return SliceForRobot(data, r); });
  ASSERT_FALSE(HasFailure());
  ExpectEqualToInProcess(results, ref);
  EXPECT_TRUE(log.contains("unknown robot 7"));
  EXPECT_TRUE(log.contains("non-finite"));
  EXPECT_TRUE(log.contains("exceeds 32 bits"));
  EXPECT_TRUE(log.contains("names object 100000"));
  EXPECT_TRUE(log.contains("removes pair (0, 0), which the two do not share"));
  EXPECT_EQ(results[static_cast<std::size_t>(e.beta)].rendezvous_transport.rejected, 2);
}

// The robot with the most events crashes after its second one and restarts from its journal.
void CrashAndRestartInTheRendezvousPhase(const ScenarioSpec& spec) {
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  // The victim: the robot with the most events; it crashes after its second one.
  std::vector<int> events(static_cast<std::size_t>(spec.robots), 0);
  for (const RendezvousEvent& e : data.rendezvous) {
    ++events[static_cast<std::size_t>(e.alpha)];
    ++events[static_cast<std::size_t>(e.beta)];
  }
  const int victim = static_cast<int>(std::max_element(events.begin(), events.end()) - events.begin());
  ASSERT_GE(events[static_cast<std::size_t>(victim)], 3);
  const fs::path dir = test::ScratchDir();

  InProcessNetwork net;
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  std::vector<RobotSessionResult> results(static_cast<std::size_t>(spec.robots));
  std::vector<std::string> errors(results.size());
  std::vector<std::thread> threads;
  for (int r = 0; r < spec.robots; ++r) {
    threads.emplace_back([&, r]() {
      const auto ri = static_cast<std::size_t>(r);
      const std::string state = (dir / std::to_string(r)).string();
      try {
        RobotSessionOptions o = Options(spec, log, state);
        if (r == victim) {
          RobotSessionOptions first = o;
          int seen = 0;
          first.on_rendezvous = [&seen](const SessionRendezvous&) {
            if (++seen == 2) throw Crash{};
          };
          if (!RunUntilKilled(net, log, transports[ri],
                              SliceForRobot(data, r, spec.known_initial_poses), first)) {
            errors[ri] = "the victim did not crash";
            return;
          }
        }
        RobotSession session(SliceForRobot(data, r, spec.known_initial_poses), *transports[ri], o);
        results[ri] = session.run();
      } catch (const std::exception& ex) {
        errors[ri] = ex.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& err : errors) ASSERT_EQ(err, "");
  ExpectEqualToInProcess(results, ref);
  const auto& replayed = results[static_cast<std::size_t>(victim)].rendezvous;
  ASSERT_GE(replayed.size(), 3u);
  EXPECT_TRUE(replayed[0].replayed && replayed[1].replayed);
  EXPECT_FALSE(replayed[2].replayed);
  EXPECT_TRUE(log.contains("restart: 2 rendezvous taken from"));
  fs::remove_all(dir);
}

// With unknown initial poses too: the journal then holds the pairs an event removed.
TEST(RobotSession, ARobotThatCrashesInTheRendezvousPhaseAndRestartsLosesNothing) {
  for (const bool known : {true, false}) {
    SCOPED_TRACE(known ? "known initial poses" : "unknown initial poses");
    ScenarioSpec spec = Small();
    spec.known_initial_poses = known;
    CrashAndRestartInTheRendezvousPhase(spec);
  }
}

// The batch twin of a team that `victim` leaves after step `last_step`
// (MultiRobotSlamConfig::leave_after): per robot that stays, its estimate in the joint solve of
// the robots linked to it without the victim (BuildGroupProblem, no held estimates: their pairs
// with it dropped; the lowest of them holds the gauge), or its own map when it is linked to none.
struct LeaveTwin {
  MultiRobotSlamResult slam;
  std::map<int, Values> estimates;
  int skipped = 0;
  std::vector<int> solved;  // the robots of parts of two or more, solved together
};
LeaveTwin BatchTwinWithoutTheVictim(const ScenarioSpec& spec, const SimulationData& data,
                                    int victim, int last_step) {
  LeaveTwin twin;
  MultiRobotSlamConfig config = ScenarioSlamConfig(spec);
  config.leave_after[victim] = last_step;
  twin.slam = RunMultiRobotObjectSlam(data, config);
  for (const RendezvousRecord& e : twin.slam.rendezvous) twin.skipped += e.skipped ? 1 : 0;
  std::vector<int> stay;
  for (int r = 0; r < spec.robots; ++r) {
    if (r != victim) stay.push_back(r);
  }
  for (const std::vector<int>& part : LinkedGroups(stay, twin.slam.shared)) {
    if (part.size() < 2) {
      twin.estimates[part[0]] = twin.slam.robots[static_cast<std::size_t>(part[0])].estimate();
      continue;
    }
    std::vector<const ObjectSlam*> members;
    for (int r : part) members.push_back(&twin.slam.robots[static_cast<std::size_t>(r)]);
    twin.solved.insert(twin.solved.end(), part.begin(), part.end());
    const GroupProblem problem =
        BuildGroupProblem(members, twin.slam.shared, {}, config.rendezvous.lambda());
    EXPECT_EQ(problem.team_factors, 0);
    const DgsResult dgs = RunDgs(problem.graph, problem.initial, DriverOptions(DgsNodeOptions{}));
    for (const auto& [k, x] : dgs.values) {
      const int r = part[static_cast<std::size_t>(k.robot)];
      twin.estimates[r].emplace(Key{r, k.kind, k.index}, x);
    }
  }
  return twin;
}

// A robot that leaves for good in the rendezvous phase of a batch mission (robot 0, the gauge's
// owner, and the robot with the most events): its partners at later rendezvous find it gone
// (seen alive, then not alive for leave_timeout) and skip them; before the batch solve every
// robot that shares pairs with it finds it gone while the team forms, and the others solve
// without it, each estimate the twin's to 1e-9. Before, the first partner to wait for it failed
// at rendezvous_timeout. Third case: besides, a robot that stays crashes in round 3 of that solve
// and restarts from its journal (the closure journaled, the node's in solves/batch): the same.
TEST(RobotSession, TheOthersSolveTheBatchWithoutARobotThatLeavesForGood) {
  ScenarioSpec spec = Small();
  spec.robots = 4;
  const SimulationData data = SimulateScenario(spec);
  std::map<int, std::vector<int>> steps_of = EventStepsOf(data);
  const int busiest = Busiest(steps_of);
  const fs::path dir = test::ScratchDir();
  for (const auto& [victim, crash] : {std::pair{0, false}, std::pair{busiest, false},
                                      std::pair{busiest, true}}) {
    SCOPED_TRACE("robot " + std::to_string(victim) + " leaves" + (crash ? ", another crashes" : ""));
    fs::remove_all(dir);
    const std::vector<int>& steps = steps_of[victim];
    ASSERT_GE(steps.size(), 2u);
    const int last_step = steps.front();  // it leaves after the events of its first step
    ASSERT_GT(steps.back(), last_step);   // and misses a later one
    const LeaveTwin twin = BatchTwinWithoutTheVictim(spec, data, victim, last_step);
    ASSERT_GT(twin.skipped, 0);
    ASSERT_GE(twin.solved.size(), 2u);  // some robots that stay solve together
    const int crasher = crash ? twin.solved.front() : -1;

    InProcessNetwork net;
    Log log;
    std::vector<std::unique_ptr<Transport>> transports;
    for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
    const auto options = [&](int r) {
      RobotSessionOptions o = Options(spec, log, (dir / std::to_string(r)).string());
      o.dgs.leave_timeout = milliseconds(300);
      if (r == victim) {
        ThrowAfterRendezvous<Gone>(o, std::count(steps.begin(), steps.end(), last_step));
      }
      return o;
    };
    std::set<int> gone;
    const std::vector<RobotSessionResult> results =
        RunSessionsWithFaults(data, transports, options, &gone, [&](int r) {
          if (r != crasher) return true;
          RobotSessionOptions first = options(r);
          first.dgs.on_round = [](const DgsNodeRound& round) {
            if (round.round == 3) throw Crash{};
          };
          return RunUntilKilled(net, log, transports[static_cast<std::size_t>(r)],
                                SliceForRobot(data, r), first);
        });
    ASSERT_FALSE(HasFailure());
    ASSERT_EQ(gone, std::set<int>{victim});
    int skipped = 0;
    for (int r = 0; r < spec.robots; ++r) {
      if (r == victim) continue;
      const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
      for (const SessionRendezvous& e : got.rendezvous) {
        if (!e.skipped) continue;
        ++skipped;
        EXPECT_TRUE(e.event.alpha == victim || e.event.beta == victim);
      }
      const Values& expected = twin.estimates.at(r);
      EXPECT_EQ(got.dgs.estimate.size(), expected.size()) << "robot " << r;
      EXPECT_LE(MaxPoseDifference(got.dgs.estimate, expected), 1e-9) << "robot " << r;
      EXPECT_EQ(std::count(got.dgs.team.begin(), got.dgs.team.end(), victim), 0);
      for (const auto& [k, x] : got.dgs.estimate) EXPECT_EQ(k.robot, r);
      EXPECT_TRUE(fs::exists(dir / std::to_string(r) / "result.g2o"));
    }
    EXPECT_EQ(skipped, twin.skipped);
    EXPECT_TRUE(log.contains("robot " + std::to_string(victim) + " left for good"));
    EXPECT_TRUE(log.contains("batch solve without robot(s) " + std::to_string(victim)));
    if (crash) {
      const DgsNodeResult& restarted = results[static_cast<std::size_t>(crasher)].dgs;
      EXPECT_EQ(restarted.incarnation, 1u);
      EXPECT_GE(restarted.replayed_rounds, 2);
    }
  }
  fs::remove_all(dir);
}

// A batch robot that dies before some of its later partners ever heard from it (their links to
// it down from the start: DDS may not deliver its presence status before it dies): they cannot
// tell it from a robot not started; waiting for it at their rendezvous, they take it as gone for
// good after leave_timeout, never heard from; the others solve as when it left, each estimate
// the twin's to 1e-9. Before, such a partner failed at rendezvous_timeout. (A first version waited
// rendezvous_timeout for a robot never heard from: a partner waiting meanwhile for that partner's
// answer timed out first and failed.)
TEST(RobotSession, ARobotNeverHeardFromByAPartnerIsTakenAsGoneAfterTheLeaveTimeout) {
  ScenarioSpec spec = Small();
  spec.robots = 4;
  const SimulationData data = SimulateScenario(spec);
  std::map<int, std::vector<int>> steps_of = EventStepsOf(data);
  const int victim = Busiest(steps_of);
  const int last_step = steps_of[victim].front();  // it leaves after the events of its first step
  std::set<int> met, unheard;  // its partners up to then; those it meets only later
  for (const RendezvousEvent& e : data.rendezvous) {
    if (e.alpha != victim && e.beta != victim) continue;
    (e.step <= last_step ? met : unheard).insert(e.alpha == victim ? e.beta : e.alpha);
  }
  for (int r : met) unheard.erase(r);
  ASSERT_FALSE(unheard.empty()) << "no later partner of the kind the test needs";
  const LeaveTwin twin = BatchTwinWithoutTheVictim(spec, data, victim, last_step);
  ASSERT_GT(twin.skipped, 0);

  InProcessNetwork net;
  for (int r = 0; r < spec.robots; ++r) {
    if (r != victim && !met.count(r)) net.setLink(victim, r, false);  // it never reaches them
  }
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  std::set<int> gone;
  const std::vector<RobotSessionResult> results =
      RunSessionsWithFaults(data, transports, [&](int r) {
        RobotSessionOptions o = Options(spec, log);
        o.dgs.leave_timeout = milliseconds(300);
        if (r == victim) {
          ThrowAfterRendezvous<Gone>(o, std::count(steps_of[victim].begin(), steps_of[victim].end(), last_step));
        }
        return o;
      }, &gone);
  ASSERT_FALSE(HasFailure());
  ASSERT_EQ(gone, std::set<int>{victim});
  int skipped = 0;
  for (int r = 0; r < spec.robots; ++r) {
    if (r == victim) continue;
    const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
    for (const SessionRendezvous& e : got.rendezvous) skipped += e.skipped ? 1 : 0;
    const Values& expected = twin.estimates.at(r);
    EXPECT_EQ(got.dgs.estimate.size(), expected.size()) << "robot " << r;
    EXPECT_LE(MaxPoseDifference(got.dgs.estimate, expected), 1e-9) << "robot " << r;
  }
  EXPECT_EQ(skipped, twin.skipped);
  EXPECT_TRUE(log.contains("robot " + std::to_string(victim) + " left for good (never heard from"));
}

// A batch robot that comes back after its partners found it gone (killed after the events of its
// first step, restarted from its journal once a robot has found it gone: the partner of its next
// rendezvous, the first to wait for it): at that rendezvous the partner's
// presence status lists it, so it leaves the team, skips its later rendezvous and takes its own
// map as its result; the others solve without it, each estimate the twin's to 1e-9. Before, it
// failed at that rendezvous.
TEST(RobotSession, ABatchRobotBackAfterItWasFoundGoneContinuesAlone) {
  ScenarioSpec spec = Small();
  spec.robots = 4;
  const SimulationData data = SimulateScenario(spec);
  std::map<int, std::vector<int>> steps_of = EventStepsOf(data);
  const int victim = Busiest(steps_of);
  const int last_step = steps_of[victim].front();
  const int partner = FirstPartnerAfter(data, victim, last_step);  // the first to wait for it
  ASSERT_GE(partner, 0);
  const LeaveTwin twin = BatchTwinWithoutTheVictim(spec, data, victim, last_step);
  const fs::path dir = test::ScratchDir();
  fs::remove_all(dir);
  InProcessNetwork net;
  Log log;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < spec.robots; ++r) transports.push_back(net.connect(r, {log.sink()}));
  const auto options = [&](int r) {
    RobotSessionOptions o = Options(spec, log, (dir / std::to_string(r)).string());
    o.dgs.leave_timeout = milliseconds(300);
    return o;
  };
  std::set<int> gone;
  const std::vector<RobotSessionResult> results =
      RunSessionsWithFaults(data, transports, options, &gone, [&](int r) {
        if (r != victim) return true;
        RobotSessionOptions first = options(r);
        const std::vector<int>& steps = steps_of[victim];
        ThrowAfterRendezvous<Crash>(first, std::count(steps.begin(), steps.end(), last_step));
        return RunUntilKilled(net, log, transports[static_cast<std::size_t>(r)],
                              SliceForRobot(data, r), first,
                              [&] { log.waitFor(fmt::format("robot {} left for good", victim)); });
      });
  ASSERT_FALSE(HasFailure());
  ASSERT_TRUE(gone.empty());
  for (int r = 0; r < spec.robots; ++r) {
    const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
    EXPECT_EQ(got.left_team, r == victim) << "robot " << r;
    if (r == victim) {
      EXPECT_EQ(got.dgs.team, std::vector<int>{victim});
      EXPECT_EQ(got.dgs.estimate.size(), static_cast<std::size_t>(got.poses + got.landmarks));
      for (const SessionRendezvous& e : got.rendezvous) {
        EXPECT_EQ(e.skipped, e.event.step > last_step) << "step " << e.event.step;
      }
      continue;
    }
    const Values& expected = twin.estimates.at(r);
    EXPECT_EQ(got.dgs.estimate.size(), expected.size()) << "robot " << r;
    EXPECT_LE(MaxPoseDifference(got.dgs.estimate, expected), 1e-9) << "robot " << r;
  }
  EXPECT_TRUE(log.contains(fmt::format("robot {} found this robot gone: it continues alone",
                                       partner)));
  fs::remove_all(dir);
}

// A batch robot that dies between its joining status and its DgsNode's first status: the others
// formed the closure with it (none left); their nodes find it gone at the first step, before it
// took any (TeamChangedError), and the team is formed again without it: the others solve as when
// it had left before (its pairs dropped, the lowest robot holding the gauge), each estimate the
// twin's to 1e-9 (robot 0, the gauge's owner, and the robot with the most events). Before, the
// others failed at the node's join_timeout; taken as silent in the solve instead, robot 0's death
// left the others with no anchor (their positions collapsed).
TEST(RobotSession, ABatchRobotThatDiesBeforeItsNodesFirstStatusIsLeftOutOfTheSolve) {
  ScenarioSpec spec = Small();
  spec.robots = 4;
  const SimulationData data = SimulateScenario(spec);
  const Reference ref = InProcess(spec, data);
  ASSERT_TRUE(ref.joint.unanchored_robots.empty());
  const int busiest = Busiest(EventStepsOf(data));
  for (const int victim : {0, busiest}) {
    SCOPED_TRACE("robot " + std::to_string(victim) + " dies");
    const LeaveTwin twin = BatchTwinWithoutTheVictim(spec, data, victim, data.numSteps());
    ASSERT_GE(twin.solved.size(), 2u);
    InProcessNetwork net;
    Log log;
    std::vector<std::unique_ptr<Transport>> transports;
    for (int r = 0; r < spec.robots; ++r) {
      std::unique_ptr<Transport> t = net.connect(r, {log.sink()});
      if (r == victim) {  // its second status of a solve: the joining status, then its node's
        auto statuses = std::make_shared<int>(0);
        t = std::make_unique<DyingTransport>(
            std::move(t),
            [statuses](const StatusPacket& p) { return p.solve != kPresenceSolve && ++*statuses == 2; },
            [] { throw Gone{}; });
      }
      transports.push_back(std::move(t));
    }
    std::set<int> gone;
    const std::vector<RobotSessionResult> results =
        RunSessionsWithFaults(data, transports, [&](int) {
          RobotSessionOptions o = Options(spec, log);
          o.dgs.leave_timeout = milliseconds(300);
          return o;
        }, &gone);
    ASSERT_FALSE(HasFailure());
    ASSERT_EQ(gone, std::set<int>{victim});
    for (int r = 0; r < spec.robots; ++r) {
      if (r == victim) continue;
      const DgsNodeResult& got = results[static_cast<std::size_t>(r)].dgs;
      const Values& expected = twin.estimates.at(r);
      EXPECT_EQ(got.estimate.size(), expected.size()) << "robot " << r;
      EXPECT_LE(MaxPoseDifference(got.estimate, expected), 1e-9) << "robot " << r;
      EXPECT_EQ(std::count(got.team.begin(), got.team.end(), victim), 0);
    }
    EXPECT_TRUE(log.contains("robot " + std::to_string(victim) +
                             " left for good (it joined the batch solve and left before its "
                             "first step)"));
    EXPECT_TRUE(log.contains("batch solve without robot(s) " + std::to_string(victim)));
  }
}

// A partner alive on the network whose session never answers (connected, no packet): the robot
// waiting for it at their first rendezvous is not taken in by its liveness and fails at
// rendezvous_timeout, naming the partner, the step and the wait.
TEST(RobotSession, APartnerAliveButSilentFailsTheRendezvousAtItsTimeoutNamingIt) {
  const SimulationData data = SimulateScenario(Small());
  ASSERT_FALSE(data.rendezvous.empty());
  const RendezvousEvent& first = data.rendezvous.front();
  InProcessNetwork net;
  Log log;
  const std::unique_ptr<Transport> mine = net.connect(first.beta, {log.sink()});
  const std::unique_ptr<Transport> silent = net.connect(first.alpha);
  RobotSessionOptions o = Options(Small(), log);
  o.rendezvous_timeout = milliseconds(200);
  RobotSession session(SliceForRobot(data, first.beta), *mine, o);
  EXPECT_TRUE(test::ThrowsNaming<Error>(
      [&] { session.run(); },
      fmt::format("robot {}: no object list from robot {} for the rendezvous of step {} within 200 "
                  "ms",
                  first.beta, first.alpha, first.step)));
}

TEST(RobotSession, ValidatesItsInputs) {
  ScenarioSpec bad = Small();
  bad.scenario = "moon";
  EXPECT_THROW(bad.validate(), InvalidInputError);
  bad = Small();
  bad.poses_per_robot = 1;
  EXPECT_THROW(bad.validate(), InvalidInputError);
  bad = Small();
  bad.exclusion_radius = -0.1;
  EXPECT_THROW(bad.validate(), InvalidInputError);
  bad = Small();
  bad.ambiguity_ratio = 1.0;
  EXPECT_THROW(bad.validate(), InvalidInputError);
  bad = Small();
  bad.covariance_gate = std::numeric_limits<double>::infinity();
  EXPECT_THROW(bad.validate(), InvalidInputError);
  const SimulationData data = SimulateScenario(Small());
  EXPECT_THROW(SliceForRobot(data, 3), InvalidInputError);
  InProcessNetwork net;
  auto t1 = net.connect(1);
  Log log;
  EXPECT_THROW(RobotSession(SliceForRobot(data, 0), *t1, Options(Small(), log)),
               InvalidInputError);  // another robot's transport
  RobotSessionOptions o = Options(Small(), log);
  o.slam.rendezvous.ground_truth_association = true;
  EXPECT_THROW(RobotSession(SliceForRobot(data, 1), *t1, o), InvalidInputError);
  o = Options(Small(), log);
  o.rendezvous_timeout = milliseconds(0);
  EXPECT_THROW(o.validate(), InvalidInputError);
  // Online, the group solve makes the masks, and a robot holds its partners' landmarks refined.
  o = Options(Small(), log);
  o.online = true;
  o.dgs.gnc = GncOptions{};
  o.dgs.robust.assign(3, true);
  EXPECT_TRUE(test::ThrowsNaming([&] { o.validate(); }, "the robust and checked masks"));
  o = Options(Small(), log);
  o.online = true;
  o.dgs.solver.refine = false;
  EXPECT_TRUE(test::ThrowsNaming([&] { o.validate(); }, "online mapping needs the refinement"));
  // Data that is not one robot's of the team, and events that do not fit it.
  o = Options(Small(), log);
  RobotScenarioData d = SliceForRobot(data, 1);
  d.measurements.odometry.pop_back();
  EXPECT_TRUE(
      test::ThrowsNaming([&] { RobotSession(d, *t1, o); }, "inconsistent data for robot 1 of 3"));
  d = SliceForRobot(data, 1);
  d.initial_poses.pop_back();
  EXPECT_TRUE(test::ThrowsNaming([&] { RobotSession(d, *t1, o); }, "inconsistent data"));
  d = SliceForRobot(data, 1);
  ASSERT_GE(d.events.size(), 2u);
  std::swap(d.events[0], d.events[1]);
  if (d.events[0].step == d.events[1].step) d.events[1].step = d.events[0].step - 1;
  EXPECT_TRUE(test::ThrowsNaming([&] { RobotSession(d, *t1, o); },
                                 "rendezvous event 1 (step " + std::to_string(d.events[1].step)));
  d = SliceForRobot(data, 1);
  d.events[0].beta = d.events[0].alpha;
  EXPECT_TRUE(test::ThrowsNaming([&] { RobotSession(d, *t1, o); }, "does not fit the scenario"));
}

}  // namespace
}  // namespace moslam
