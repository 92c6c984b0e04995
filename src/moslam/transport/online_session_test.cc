// Online mapping between robot sessions (robot_session.h with online = true) as threads over the
// in-process transport: every group solve, and every robot's map after it and at the end, equal
// the in-process twin (online/online_team.h on RunMultiRobotObjectSlam). Between processes over
// DDS: apps/team_test.cc.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/metrics/metrics.h"
#include "moslam/online/online_team.h"
#include "moslam/transport/dying_transport_test_util.h"
#include "moslam/transport/group_transport.h"
#include "moslam/transport/in_process_transport.h"
#include "moslam/transport/robot_session.h"
#include "moslam/transport/session_test_util.h"

namespace moslam {
namespace {

using std::chrono::milliseconds;

RobotSessionOptions OnlineSessionOptions(const ScenarioSpec& spec) {
  RobotSessionOptions o;
  o.slam = ScenarioSlamConfig(spec);
  o.online = true;
  o.dgs.solver = OnlineOptions::DefaultSolver();
  // Bounds of waiting for a partner, there only to end a broken run: no test waits them out (a
  // robot that leaves is found by leave_timeout). Wide, as a partner busy with a group solve of
  // its own may be far behind on a loaded machine: 31.6 s with 14 busy loops beside the robust
  // restart test on 2 cores, whose quiet run takes 6 s; with 20 s they failed it.
  o.dgs.join_timeout = milliseconds(120000);
  o.dgs.stall_timeout = milliseconds(120000);
  o.dgs.finish_timeout = milliseconds(5000);
  o.rendezvous_timeout = milliseconds(120000);
  o.log = [](const std::string&) {};
  return o;
}

// chairs25, 6 robots of 40 poses, seed 2: held landmarks, borrowed copies and a group of three.
ScenarioSpec SixRobots() {
  ScenarioSpec spec;
  spec.scenario = "chairs25";
  spec.robots = 6;
  spec.poses_per_robot = 40;
  spec.seed = 2;
  return spec;
}

OnlineRun RunTwin(const SimulationData& data, const RobotSessionOptions& session,
                  const std::map<int, int>& dies_in_solve = {}) {
  OnlineOptions options;
  options.solver = DriverOptions(session.dgs);
  options.lambda = session.slam.rendezvous.lambda();
  options.dies_in_solve = dies_in_solve;
  if (session.dgs.gnc) {  // the same robust solve
    RobustDgsOptions robust;
    robust.gnc = *session.dgs.gnc;
    robust.check_separators = session.dgs.separator_check.has_value();
    if (session.dgs.separator_check) robust.consistency = *session.dgs.separator_check;
    robust.retest_left_out = session.dgs.retest_left_out;
    options.robust = robust;
  }
  return RunOnline(data, session.slam, options);
}

// Robust group solves (RobotSessionOptions::online with dgs.gnc): the simulation's defaults.
RobotSessionOptions RobustOnlineSessionOptions(const ScenarioSpec& spec) {
  RobotSessionOptions o = OnlineSessionOptions(spec);
  const RobustDgsOptions defaults;
  o.dgs.gnc = defaults.gnc;
  o.dgs.separator_check = defaults.consistency;
  o.dgs.retest_left_out = defaults.retest_left_out;
  return o;
}

struct Crash : std::runtime_error {
  Crash() : std::runtime_error("simulated crash") {}
};
struct Leave : std::runtime_error {
  Leave() : std::runtime_error("simulated departure") {}
};

// One session per robot, each on its thread over one in-process network, with the options
// `options(robot)` gives; a session that throws Crash is restarted (a fresh transport, as a new
// process) with the same options; one that throws Leave is gone for good (its transport closed,
// its result left empty). Every other failure fails the test.
// `wrap` (optional) puts a transport of the test's between a robot's session and the network;
// `before_restart` (optional) is called with the robot before a crashed session restarts.
using WrapTransport =
    std::function<std::unique_ptr<Transport>(int robot, std::unique_ptr<Transport>)>;
std::vector<RobotSessionResult> RunSessions(
    const SimulationData& data, int robots,
    const std::function<RobotSessionOptions(int)>& options, const WrapTransport& wrap = {},
    const std::function<void(int)>& before_restart = {}) {
  InProcessNetwork net;
  std::vector<std::unique_ptr<Transport>> transports;
  for (int r = 0; r < robots; ++r) {
    std::unique_ptr<Transport> t = net.connect(r, {[](const std::string&) {}});
    transports.push_back(wrap ? wrap(r, std::move(t)) : std::move(t));
  }
  std::vector<RobotSessionResult> results(static_cast<std::size_t>(robots));
  std::vector<std::string> errors(results.size());
  std::vector<std::thread> threads;
  for (int r = 0; r < robots; ++r) {
    threads.emplace_back([&, r]() {
      const auto ri = static_cast<std::size_t>(r);
      const RobotSessionOptions o = options(r);
      while (true) {
        try {
          RobotSession session(SliceForRobot(data, r), *transports[ri], o);
          results[ri] = session.run();
          return;
        } catch (const Crash&) {
          transports[ri].reset();  // the process is gone; restarted, it receives the history
          if (before_restart) before_restart(r);
          transports[ri] = net.connect(r, {[](const std::string&) {}});
        } catch (const Leave&) {
          transports[ri].reset();
          return;
        } catch (const std::exception& e) {
          errors[ri] = e.what();
          return;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  for (const std::string& e : errors) EXPECT_EQ(e, "");
  return results;
}

// Every group solve of every robot (but `except`) and its final map against the twin: the same
// steps, robots and sweeps; returns the largest difference of a map (m or rad), counts the
// solves compared.
double CompareWithTwin(const std::vector<RobotSessionResult>& results, const OnlineRun& twin,
                       std::size_t* solves, int except = -1) {
  double largest_difference = 0.0;
  for (int r = 0; r < static_cast<int>(results.size()); ++r) {
    if (r == except) continue;
    const RobotSessionResult& got = results[static_cast<std::size_t>(r)];
    std::vector<const GroupSolveRecord*> expected;
    for (const GroupSolveRecord& s : twin.solves) {
      if (std::find(s.robots.begin(), s.robots.end(), r) != s.robots.end()) expected.push_back(&s);
    }
    EXPECT_EQ(got.solves.size(), expected.size()) << "robot " << r;
    for (std::size_t i = 0; i < std::min(expected.size(), got.solves.size()); ++i) {
      const SessionSolve& s = got.solves[i];
      EXPECT_EQ(s.step, expected[i]->step);
      EXPECT_EQ(s.robots, expected[i]->robots);
      EXPECT_EQ(s.unlinked, expected[i]->unlinked);
      if (expected[i]->robust_rounds == 0 && expected[i]->sweeps == 0) {  // least squares
        EXPECT_EQ(s.refine_steps, expected[i]->refine_steps);
        EXPECT_EQ(s.rotation_rounds, expected[i]->rotation_sweeps);
      }
      if (!s.replayed) {
        EXPECT_GT(s.sent.estimates_bytes + s.sent.status_bytes, 0);
      }
      const Values& map = twin.maps.at({s.step, r});
      largest_difference = std::max(largest_difference, MaxPoseDifference(s.estimate, map));
      EXPECT_EQ(s.estimate.size(), map.size());
      ++*solves;
    }
    const Values& final_map = twin.slam.robots[static_cast<std::size_t>(r)].estimate();
    EXPECT_EQ(got.final_estimate.size(), final_map.size());
    largest_difference = std::max(largest_difference, MaxPoseDifference(got.final_estimate, final_map));
  }
  return largest_difference;
}

TEST(OnlineSession, OverTheInProcessTransportEqualsTheInProcessTwin) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  const RobotSessionOptions options = OnlineSessionOptions(spec);
  const OnlineRun twin = RunTwin(data, options);
  ASSERT_GE(twin.solves.size(), 3u);
  int team_factors = 0, borrowed = 0;
  std::size_t largest = 0;
  for (const GroupSolveRecord& s : twin.solves) {
    team_factors += s.team_factors;
    borrowed += s.borrowed;
    largest = std::max(largest, s.robots.size());
  }
  // The schedule exercises held partner landmarks (robots out of range), copies held by another
  // robot of the group (the joining statuses' team pairs), and a group of three.
  EXPECT_GT(team_factors, 0);
  EXPECT_GT(borrowed, 0);
  EXPECT_GE(largest, 3u);

  const std::vector<RobotSessionResult> results =
      RunSessions(data, spec.robots, [&](int) { return options; });
  std::size_t solves = 0;
  const double largest_difference = CompareWithTwin(results, twin, &solves);
  EXPECT_GT(solves, twin.solves.size());  // each solve counted once per robot of it
  EXPECT_LE(largest_difference, 1e-9);
  std::printf("online twin vs sessions: %zu group solves (largest %zu robots, %d team factors), "
              "largest difference %.2e\n",
              twin.solves.size(), largest, team_factors, largest_difference);
}

// The robot of the most group solves of the twin (ties: the lowest id) and their number.
std::pair<int, int> BusiestRobot(const OnlineRun& twin) {
  std::map<int, int> solves_of;
  for (const GroupSolveRecord& g : twin.solves) {
    for (int r : g.robots) ++solves_of[r];
  }
  if (solves_of.empty()) return {-1, 0};
  return *std::max_element(solves_of.begin(), solves_of.end(),
                           [](const auto& a, const auto& b) { return a.second < b.second; });
}

// Kills a robot's session twice (throws Crash): in round 6 of its second group solve, then right
// after the first solve, from its third on, that `second` accepts (solves counted per incarnation,
// replayed ones included).
class TwoCrashes {
 public:
  explicit TwoCrashes(std::function<bool(const SessionSolve&)> second =
                          [](const SessionSolve&) { return true; })
      : second_(std::move(second)) {}
  void arm(RobotSessionOptions& o) {
    o.dgs.on_round = [this](const DgsNodeRound& round) {
      if (round.round == 0) return;
      if (!round.replayed && round.round == 6 && solves_seen_ == 1 && crashes_ == 0) crash();
    };
    o.on_solve = [this](const SessionSolve& s) {
      ++solves_seen_;
      if (!s.replayed && solves_seen_ >= 3 && crashes_ == 1 && second_(s)) crash();
    };
  }
  int crashes() const { return crashes_; }

 private:
  void crash() {
    ++crashes_;
    solves_seen_ = 0;
    throw Crash();
  }
  std::function<bool(const SessionSolve&)> second_;
  std::atomic<int> crashes_{0};
  std::atomic<int> solves_seen_{0};
};

// Robust group solves between sessions: every map after every solve and at the end equal the
// twin's robust solves (OnlineOptions::robust), and so do the verdicts: the pairs set aside at the
// end (each robot holds its own) and the factors of its own graph rejected. One robot is killed in
// a solve and again between two, and takes the verdicts of its finished solves from its journal.
TEST(OnlineSession, RobustGroupSolvesEqualTheTwinsAndSurviveARestart) {
  ScenarioSpec spec = SixRobots();
  spec.poses_per_robot = 60;  // pairs set aside, one taken back, and groups left unlinked
  const SimulationData data = SimulateScenario(spec);
  const RobotSessionOptions base = RobustOnlineSessionOptions(spec);
  const OnlineRun twin = RunTwin(data, base);
  int rejected = 0, taken_back = 0, observation_outliers = 0, unlinked = 0;
  for (const GroupSolveRecord& g : twin.solves) {
    rejected += g.rejected;
    taken_back += g.taken_back;
    observation_outliers += g.observation_outliers;
    unlinked += g.unlinked ? 1 : 0;
  }
  std::printf("robust twin: %zu group solves, %d pairs set aside (%d taken back), %d observations "
              "rejected, %d unlinked, %zu set aside at the end\n",
              twin.solves.size(), rejected, taken_back, observation_outliers, unlinked,
              twin.set_aside.size());
  // The schedule exercises pairs set aside and taken back, rejected observations and a group
  // left unlinked.
  EXPECT_GT(rejected, 0);
  EXPECT_GT(taken_back, 0);
  EXPECT_GT(observation_outliers, 0);
  EXPECT_GT(unlinked, 0);
  const std::pair<int, int> busiest = BusiestRobot(twin);
  const int victim = busiest.first, victim_solves = busiest.second;
  ASSERT_GE(victim_solves, 4);

  const std::filesystem::path dir = test::ScratchDir();
  // The second death right after a solve after which pairs of it stand aside or factors of it
  // are rejected.
  TwoCrashes crashes(
      [](const SessionSolve& s) { return s.set_aside + s.observation_outliers > 0; });
  const std::vector<RobotSessionResult> results = RunSessions(data, spec.robots, [&](int r) {
    RobotSessionOptions o = base;
    o.dgs.state_dir = (dir / std::to_string(r)).string();
    if (r == victim) crashes.arm(o);
    return o;
  });
  EXPECT_EQ(crashes.crashes(), 2);
  std::size_t solves = 0;
  const double largest_difference = CompareWithTwin(results, twin, &solves);
  EXPECT_LE(largest_difference, 1e-9);
  // Each solve's traffic counts the robust solve's own: the weights and the check's covariances.
  std::int64_t weights = 0, covariances = 0;
  for (const RobotSessionResult& result : results) {
    for (const SessionSolve& s : result.solves) {
      weights += s.sent.weights_bytes;
      covariances += s.sent.covariances_bytes;
      EXPECT_LE(s.sent.estimates_bytes + s.sent.status_bytes + s.sent.coarse_bytes +
                    s.sent.weights_bytes + s.sent.covariances_bytes,
                s.sent.sent_bytes);
    }
  }
  EXPECT_GT(weights, 0);
  EXPECT_GT(covariances, 0);
  // The verdicts: the pairs set aside (each robot's are the twin's that involve it) and the
  // weights of every robot's own factors.
  std::set<std::pair<Key, Key>> twin_aside;
  for (const SharedObject& o : twin.set_aside) {
    twin_aside.insert(UnorderedPair(o.alpha_object, o.beta_object));
  }
  for (int r = 0; r < spec.robots; ++r) {
    std::set<std::pair<Key, Key>> expected, got;
    for (const auto& pair : twin_aside) {
      if (pair.first.robot == r || pair.second.robot == r) expected.insert(pair);
    }
    for (const SharedObject& o : results[static_cast<std::size_t>(r)].set_aside) {
      got.insert(UnorderedPair(o.alpha_object, o.beta_object));
    }
    EXPECT_EQ(got, expected) << "robot " << r;
    int rejected_own = 0;
    for (double w : twin.slam.robots[static_cast<std::size_t>(r)].factorWeights()) {
      rejected_own += w != 1.0 ? 1 : 0;
    }
    const std::vector<SessionSolve>& mine = results[static_cast<std::size_t>(r)].solves;
    if (!mine.empty()) {
      EXPECT_EQ(mine.back().observation_outliers, rejected_own) << "robot " << r;
    }
  }
  // The victim took verdicts from its journal: a replayed solve after which pairs stood aside.
  const std::vector<SessionSolve>& victims = results[static_cast<std::size_t>(victim)].solves;
  EXPECT_TRUE(std::any_of(victims.begin(), victims.end(), [](const SessionSolve& s) {
    return s.replayed && s.set_aside + s.observation_outliers > 0;
  }));
  std::printf("robust online twin vs sessions: %zu solves compared, largest difference %.2e\n",
              solves, largest_difference);
  std::filesystem::remove_all(dir);
}

// A robot killed in the DGS of a group solve, and again between two solves, and restarted each
// time from its state directory: every robot's maps are still the twin's (the finished solves
// taken from the journal, the interrupted one resumed from its node's journal).
TEST(OnlineSession, ARobotKilledInAndBetweenGroupSolvesResumesFromItsJournal) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  const RobotSessionOptions base = OnlineSessionOptions(spec);
  const OnlineRun twin = RunTwin(data, base);
  const std::pair<int, int> busiest = BusiestRobot(twin);
  const int victim = busiest.first, victim_solves = busiest.second;
  ASSERT_GE(victim_solves, 4);

  const std::filesystem::path dir = test::ScratchDir();
  TwoCrashes crashes;  // the second right after its third solve
  std::vector<std::string> log;
  std::mutex log_mutex;
  const std::vector<RobotSessionResult> results = RunSessions(data, spec.robots, [&](int r) {
    RobotSessionOptions o = base;
    o.dgs.state_dir = (dir / std::to_string(r)).string();
    if (r != victim) return o;
    o.log = [&](const std::string& text) {
      std::lock_guard<std::mutex> lock(log_mutex);
      log.push_back(text);
    };
    crashes.arm(o);
    return o;
  });
  EXPECT_EQ(crashes.crashes(), 2);
  std::size_t solves = 0;
  EXPECT_LE(CompareWithTwin(results, twin, &solves), 1e-9);
  const std::vector<SessionSolve>& got = results[static_cast<std::size_t>(victim)].solves;
  ASSERT_EQ(got.size(), static_cast<std::size_t>(victim_solves));
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].replayed, i < 3) << "solve " << i;
  const auto said = [&](const std::string& what) {
    return std::any_of(log.begin(), log.end(),
                       [&](const std::string& l) { return l.find(what) != std::string::npos; });
  };
  EXPECT_TRUE(said("restart: 1 group solves taken from"));
  EXPECT_TRUE(said("restart: 3 group solves taken from"));
  // Each finished solve's node journal is gone (the solve record replaces it); every map saved.
  EXPECT_FALSE(std::filesystem::exists(dir / std::to_string(victim) / "solves" /
                                       fmt::format("step_{:04d}", got[1].step)));
  for (const SessionSolve& s : got) {
    EXPECT_TRUE(std::filesystem::exists(dir / std::to_string(victim) / "maps" /
                                        fmt::format("step_{:04d}", s.step) / "map.g2o"));
  }
  std::filesystem::remove_all(dir);
}

// The rendezvous the robots but `victim` skipped; each must be with the victim after `step`.
int SkippedWithTheVictimAfter(const std::vector<RobotSessionResult>& results, int victim,
                              int step) {
  int skipped = 0;
  for (int r = 0; r < static_cast<int>(results.size()); ++r) {
    if (r == victim) continue;
    for (const SessionRendezvous& e : results[static_cast<std::size_t>(r)].rendezvous) {
      skipped += e.skipped ? 1 : 0;
      EXPECT_EQ(e.skipped,
                e.event.step > step && (e.event.alpha == victim || e.event.beta == victim))
          << "robot " << r << " step " << e.event.step;
    }
  }
  return skipped;
}

// A robot that leaves for good right after one of its group solves: its partners find it gone
// when they wait for it, at a rendezvous or for its joining status, skip it from then on, and map
// exactly as the twin in which it leaves after that step (MultiRobotSlamConfig::leave_after). At
// the next step two events are added so that robot x, which shares objects with it but has not
// found it gone, is in range of it only through robot a: x finds it gone while the group forms,
// and its pairs with it become held factors of the solve with a.
TEST(OnlineSession, ARobotThatLeavesForGoodIsSkippedAndTheOthersMapAsTheTwin) {
  const ScenarioSpec spec = SixRobots();
  SimulationData data = SimulateScenario(spec);
  RobotSessionOptions base = OnlineSessionOptions(spec);
  base.dgs.leave_timeout = milliseconds(300);
  const OnlineRun full = RunTwin(data, base);
  std::map<int, std::vector<int>> steps_of = SolveStepsOf(full);
  ASSERT_FALSE(steps_of.empty());
  const int victim = Busiest(steps_of);
  ASSERT_GE(steps_of[victim].size(), 3u);
  const int last_step = steps_of[victim][1];  // it leaves after its second solve
  RobotSessionOptions twin_options = base;
  twin_options.slam.leave_after[victim] = last_step;

  // x: shares objects with the victim and has no rendezvous with it in (last_step, meet]; a:
  // linked to x at step meet, where the two added events are, with the victim in range of a.
  const OnlineRun before = RunTwin(data, twin_options);
  const int meet = last_step + 1;
  ASSERT_LT(meet, data.numSteps());
  const auto shares = [&](int p, int q) {
    return std::any_of(before.slam.shared.begin(), before.slam.shared.end(), [&](const SharedObject& o) {
      const int a = o.alpha_object.robot, b = o.beta_object.robot;
      return (a == p && b == q) || (a == q && b == p);
    });
  };
  const auto met_again = [&](int r) {
    return std::any_of(data.rendezvous.begin(), data.rendezvous.end(), [&](const RendezvousEvent& e) {
      return e.step > last_step && e.step <= meet &&
             ((e.alpha == r && e.beta == victim) || (e.alpha == victim && e.beta == r));
    });
  };
  const SimulationData original = data;
  OnlineRun twin;
  int x = -1, a = -1;
  for (int r = 0; r < spec.robots && x < 0; ++r) {
    if (r == victim || !shares(r, victim) || met_again(r)) continue;
    for (int q = 0; q < spec.robots && x < 0; ++q) {
      if (q == r || q == victim || !shares(r, q)) continue;
      data = original;
      const auto at = std::upper_bound(data.rendezvous.begin(), data.rendezvous.end(), meet,
                                       [](int step, const RendezvousEvent& e) { return step < e.step; });
      data.rendezvous.insert(at, {RendezvousEvent{meet, std::min(victim, q), std::max(victim, q)},
                                  RendezvousEvent{meet, std::min(q, r), std::max(q, r)}});
      twin = RunTwin(data, twin_options);
      // The solve of x and a at `meet` holds x's pairs with the victim.
      for (const GroupSolveRecord& s : twin.solves) {
        if (s.step == meet && s.team_factors > 0 &&
            std::count(s.robots.begin(), s.robots.end(), r) > 0 &&
            std::count(s.robots.begin(), s.robots.end(), q) > 0) {
          x = r;
          a = q;
        }
      }
    }
  }
  ASSERT_GE(x, 0) << "no robot x of the kind the test needs in this scenario";
  int twin_skipped = 0;
  for (const RendezvousRecord& e : twin.slam.rendezvous) twin_skipped += e.skipped ? 1 : 0;
  ASSERT_GT(twin_skipped, 1);
  for (const GroupSolveRecord& s : twin.solves) {
    if (s.step > last_step) {
      EXPECT_EQ(std::count(s.robots.begin(), s.robots.end(), victim), 0);
    }
  }

  std::vector<std::pair<int, std::string>> log;
  std::mutex log_mutex;
  const std::vector<RobotSessionResult> results = RunSessions(data, spec.robots, [&](int r) {
    RobotSessionOptions o = base;
    o.log = [&, r](const std::string& text) {
      std::lock_guard<std::mutex> lock(log_mutex);
      log.emplace_back(r, text);
    };
    if (r == victim) {
      o.on_solve = [&](const SessionSolve& s) {
        if (s.step == last_step) throw Leave();
      };
    }
    return o;
  });
  std::size_t solves = 0;
  EXPECT_LE(CompareWithTwin(results, twin, &solves, victim), 1e-9);
  const int skipped = SkippedWithTheVictimAfter(results, victim, last_step);
  EXPECT_EQ(skipped, twin_skipped);
  // x found it gone at step meet, waiting for its joining status.
  const std::string found = fmt::format("robot {} left for good", victim);
  const std::string at = fmt::format("at step {})", meet);
  EXPECT_TRUE(std::any_of(log.begin(), log.end(), [&](const auto& l) {
    return l.first == x && l.second.find(found) != std::string::npos &&
           l.second.find(at) != std::string::npos;
  }));
  std::printf("robot %d left after step %d: %d rendezvous skipped, robot %d found it gone in a "
              "group with robot %d, %zu solves of the others compared with the twin\n",
              victim, last_step, skipped, x, a, solves);
}

// A robot that comes back after its partners found it gone (killed right after its second solve,
// restarted from its journal once the partner of its next rendezvous has found it gone): the
// partner's presence status lists it, so at that rendezvous it learns that the team went on
// without it, leaves the team (its presence status says so) and maps alone to the end; the others
// map exactly as the twin in which it leaves after its second solve. Before, it failed at that
// rendezvous (rendezvous_timeout).
TEST(OnlineSession, ARobotBackAfterItWasFoundGoneContinuesAloneAndTheOthersMapAsTheTwin) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  RobotSessionOptions base = OnlineSessionOptions(spec);
  base.dgs.leave_timeout = milliseconds(300);
  const OnlineRun full = RunTwin(data, base);
  std::map<int, std::vector<int>> steps_of = SolveStepsOf(full);
  ASSERT_FALSE(steps_of.empty());
  const int victim = Busiest(steps_of);
  ASSERT_GE(steps_of[victim].size(), 3u);
  const int last_step = steps_of[victim][1];
  const int partner = FirstPartnerAfter(data, victim, last_step);  // the first to wait for it
  ASSERT_GE(partner, 0);
  RobotSessionOptions twin_options = base;
  twin_options.slam.leave_after[victim] = last_step;
  const OnlineRun twin = RunTwin(data, twin_options);

  const std::filesystem::path dir = test::ScratchDir();
  std::mutex log_mutex;
  std::condition_variable logged;
  std::vector<std::pair<int, std::string>> log;
  const std::string found = fmt::format("robot {} left for good", victim);
  std::atomic<bool> crashed{false};
  const std::vector<RobotSessionResult> results = RunSessions(
      data, spec.robots,
      [&](int r) {
        RobotSessionOptions o = base;
        o.dgs.state_dir = (dir / std::to_string(r)).string();
        o.log = [&, r](const std::string& text) {
          std::lock_guard<std::mutex> lock(log_mutex);
          log.emplace_back(r, text);
          logged.notify_all();
        };
        if (r == victim) {
          o.on_solve = [&](const SessionSolve& s) {
            if (!s.replayed && s.step == last_step && !crashed.exchange(true)) throw Crash();
          };
        }
        return o;
      },
      {},
      [&](int) {  // back only once its next partner has found it gone
        std::unique_lock<std::mutex> lock(log_mutex);
        logged.wait(lock, [&] {
          return std::any_of(log.begin(), log.end(), [&](const auto& l) {
            return l.first == partner && l.second.find(found) != std::string::npos;
          });
        });
      });
  ASSERT_TRUE(crashed);
  std::size_t solves = 0;
  EXPECT_LE(CompareWithTwin(results, twin, &solves, victim), 1e-9);
  const RobotSessionResult& back = results[static_cast<std::size_t>(victim)];
  EXPECT_FALSE(back.final_estimate.empty());
  EXPECT_TRUE(back.left_team);
  EXPECT_GT(back.left_team_step, last_step);
  for (int r = 0; r < spec.robots; ++r) {
    EXPECT_EQ(results[static_cast<std::size_t>(r)].left_team, r == victim) << "robot " << r;
  }
  for (const SessionRendezvous& e : back.rendezvous) {
    EXPECT_EQ(e.skipped, e.event.step > last_step) << "step " << e.event.step;
  }
  ASSERT_EQ(back.solves.size(), 2u);  // both replayed from its journal, none after
  for (const SessionSolve& s : back.solves) EXPECT_TRUE(s.replayed);
  const std::string alone =
      fmt::format("robot {} found this robot gone: it continues alone", partner);
  EXPECT_TRUE(std::any_of(log.begin(), log.end(), [&](const auto& l) {
    return l.first == victim && l.second.find(alone) != std::string::npos;
  }));
  std::printf("robot %d back after robot %d found it gone: %zu solves of the others compared with "
              "the twin\n",
              victim, partner, solves);
  std::filesystem::remove_all(dir);
}

// A robot that dies between its joining status of a group solve and its DgsNode's first status:
// its partners formed the group with it; their nodes find it gone at the first step, before it
// took any (TeamChangedError), and they form the group again without it (its pairs with them
// held), as if it had left before; it is gone for good from then on. Every map of the others
// equals the twin's in which it takes part in that step's rendezvous and in no solve from then
// on (OnlineOptions::dies_in_solve). Before, its partner in the solve failed (no value for its
// landmarks), and the team with it; taken as silent in the solve, it left its partner (the
// group of robots 0 and 1: robot 0 died) with no anchor, the estimate collapsed.
TEST(OnlineSession, ARobotThatDiesBetweenItsJoiningStatusAndItsNodesFirstStatusIsLeftOut) {
  const ScenarioSpec spec = SixRobots();
  const SimulationData data = SimulateScenario(spec);
  RobotSessionOptions base = OnlineSessionOptions(spec);
  base.dgs.leave_timeout = milliseconds(300);
  const OnlineRun full = RunTwin(data, base);
  std::map<int, std::vector<int>> steps_of = SolveStepsOf(full);
  ASSERT_FALSE(steps_of.empty());
  const auto twin_of = [&](int victim, int dies_at) {
    RobotSessionOptions o = base;
    o.slam.leave_after[victim] = dies_at;
    return RunTwin(data, o, {{victim, dies_at}});
  };
  // Two cases: the robot with the most solves dies in its second; and a robot dies in a group of
  // three or more whose others still solve together, formed again (the solve's second attempt).
  struct Case {
    int victim = -1, dies_at = -1;
  };
  std::vector<Case> cases;
  const int busiest = Busiest(steps_of);
  ASSERT_GE(steps_of[busiest].size(), 3u);
  cases.push_back({busiest, steps_of[busiest][1]});
  for (const GroupSolveRecord& s : full.solves) {
    if (s.robots.size() < 3 || cases.size() == 2) continue;
    for (int victim : s.robots) {
      const OnlineRun twin = twin_of(victim, s.step);
      if (std::any_of(twin.solves.begin(), twin.solves.end(),
                      [&](const GroupSolveRecord& g) { return g.step == s.step; })) {
        cases.push_back({victim, s.step});
        break;
      }
    }
  }
  ASSERT_EQ(cases.size(), 2u) << "no group of three of the kind the test needs in this scenario";
  for (const Case& c : cases) {
    const int victim = c.victim, dies_at = c.dies_at;
    SCOPED_TRACE(fmt::format("robot {} dies in its solve of step {}", victim, dies_at));
    std::vector<std::pair<int, std::string>> log;
    std::mutex log_mutex;
    const std::vector<RobotSessionResult> results = RunSessions(
        data, spec.robots,
        [&](int r) {
          RobotSessionOptions o = base;
          o.log = [&, r](const std::string& text) {
            std::lock_guard<std::mutex> lock(log_mutex);
            log.emplace_back(r, text);
          };
          return o;
        },
        [&](int r, std::unique_ptr<Transport> t) -> std::unique_ptr<Transport> {
          if (r != victim) return t;
          // Its second status of the solve: after the joining status, its node's first.
          auto statuses = std::make_shared<int>(0);
          const auto solve = static_cast<std::uint32_t>(dies_at + 1);
          return std::make_unique<DyingTransport>(
              std::move(t),
              [=](const StatusPacket& p) { return p.solve == solve && ++*statuses == 2; },
              [] { throw Leave(); });
        });
    const OnlineRun twin = twin_of(victim, dies_at);
    std::size_t solves = 0;
    EXPECT_LE(CompareWithTwin(results, twin, &solves, victim), 1e-9);
    const int skipped = SkippedWithTheVictimAfter(results, victim, dies_at);
    const std::string found = fmt::format("robot {} left for good (it joined the group solve of "
                                          "step {} and left before its first step)", victim, dies_at);
    EXPECT_TRUE(std::any_of(log.begin(), log.end(), [&](const auto& l) {
      return l.second.find(found) != std::string::npos;
    }));
    const bool again = std::any_of(twin.solves.begin(), twin.solves.end(),
                                   [&](const GroupSolveRecord& g) { return g.step == dies_at; });
    std::printf("robot %d died in its solve of step %d: %d rendezvous skipped, the others %s, %zu "
                "solves of theirs compared with the twin\n",
                victim, dies_at, skipped, again ? "solved again without it" : "had no partner left",
                solves);
  }
}

TEST(GroupTransport, MapsTheGroupsRobotsAndRoutesEverythingElse) {
  InProcessNetwork net;
  auto t2 = net.connect(2), t5 = net.connect(5), t7 = net.connect(7);
  std::vector<Received> elsewhere;
  GroupTransport g5(*t5, {2, 5}, 9, [&](Received r) { elsewhere.push_back(std::move(r)); });
  EXPECT_EQ(g5.self(), 1);
  StatusPacket st;
  st.robot = 1;
  st.neighbours = {0};
  g5.publish(st);
  // Robot 2 receives robot 5's status of solve 9 with real ids.
  std::vector<Received> at2;
  for (int i = 0; i < 20 && at2.empty(); ++i) at2 = t2->poll(milliseconds(50));
  ASSERT_EQ(at2.size(), 1u);
  const auto& real = std::get<StatusPacket>(at2[0].packet);
  EXPECT_EQ(real.robot, 5);
  EXPECT_EQ(real.solve, 9u);
  EXPECT_EQ(real.neighbours, std::vector<int>{2});

  // Robot 2's estimates of solve 9 arrive re-labelled; its solve-10 status, robot 7's status
  // and an object list go elsewhere.
  EstimatesPacket e;
  e.receiver = 5;
  e.solve = 9;
  e.round = 1;
  e.message.sender = 2;
  e.message.stage = DgsStage::kRotation;
  e.message.keys = {Key::Pose(2, 3)};
  e.message.values.assign(9, 0.0);
  t2->send(e);
  StatusPacket later;
  later.robot = 2;
  later.solve = 10;
  t2->publish(later);
  StatusPacket other;
  other.robot = 7;
  other.solve = 9;
  t7->publish(other);
  ObjectListPacket list;
  list.robot = 2;
  list.objects.push_back({0, "chair", SE3()});
  t2->publish(list);
  std::vector<Received> got;
  for (int i = 0; i < 40 && (got.empty() || elsewhere.size() < 3); ++i) {
    for (Received& r : g5.poll(milliseconds(50))) got.push_back(std::move(r));
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].sender, 0);
  const auto& mapped = std::get<EstimatesPacket>(got[0].packet);
  EXPECT_EQ(mapped.receiver, 1);
  EXPECT_EQ(mapped.message.sender, 0);
  EXPECT_EQ(mapped.message.keys.front(), Key::Pose(0, 3));
  EXPECT_EQ(elsewhere.size(), 3u);
  EXPECT_EQ(g5.alive(), (std::set<int>{0}));
  EXPECT_THROW(g5.publish(list), InvalidInputError);
  EXPECT_THROW(GroupTransport(*t5, {2, 7}, 9, [](Received) {}), InvalidInputError);
}

}  // namespace
}  // namespace moslam
