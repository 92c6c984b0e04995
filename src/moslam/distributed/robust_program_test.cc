// The robust robot program (robust_program.h): a team of programs, one thread per robot over an
// in-memory channel, reproduces RunRobustDgs (robust_dgs.h), with and without the separator check.
#include "moslam/distributed/robust_program.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/distributed/board_channel_test_util.h"
#include "moslam/distributed/dgs_test_util.h"
#include "moslam/distributed/partition.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/metrics/metrics.h"
#include "moslam/robust/spoil.h"
#include "moslam/robust/spoil_testing.h"
#include "moslam/solver/initialization.h"

namespace moslam {
namespace {

struct TeamOutcome {
  Values values;
  std::map<int, RobustProgramResult> results;
  std::map<int, std::vector<std::size_t>> factors;  // per robot: its subgraph's factors in graph
  std::string error;
};

// Each robot's subgraph in graph order (`reversed`: the odd robots' in reverse order, as a robot's
// own file may list the separators otherwise than its neighbour's file), and the index of each of
// its factors in the graph.
std::vector<std::pair<RobustRobotProblem, std::vector<std::size_t>>> Parts(
    const PoseGraph& graph, const Values& initial, const std::vector<bool>& robust,
    const std::vector<bool>& checked = {}, bool reversed = false) {
  std::set<int> robots;
  for (const Key& k : graph.keys()) robots.insert(k.robot);
  std::vector<std::pair<RobustRobotProblem, std::vector<std::size_t>>> parts;
  for (int r : robots) {
    RobustRobotProblem p;
    p.robot = r;
    std::vector<std::size_t> index;
    for (std::size_t n = graph.factors().size(), k = 0; k < n; ++k) {
      const std::size_t i = reversed && r % 2 == 1 ? n - 1 - k : k;
      const RelativePoseFactor& f = graph.factors()[i];
      if (f.a().robot != r && f.b().robot != r) continue;
      p.subgraph.add(f);
      p.robust.push_back(robust[i]);
      if (!checked.empty()) p.checked.push_back(checked[i]);
      index.push_back(i);
    }
    for (const PriorFactor& prior : graph.priors()) {
      if (prior.key().robot == r) p.subgraph.add(prior);
    }
    for (const auto& [k, x] : initial) {
      if (k.robot == r) p.initial[k] = x;
    }
    parts.emplace_back(std::move(p), std::move(index));
  }
  return parts;
}

// What a robot receives from the team, changed before its program sees it (a faulty peer).
using Tamper = std::function<void(int robot, TeamStep& received)>;

// The board's channel with `tamper` applied to every step a robot receives.
class TamperedChannel : public TeamChannel {
 public:
  TamperedChannel(test::SharedBoard& board, int robot, const Tamper& tamper)
      : inner_(board, robot), robot_(robot), tamper_(tamper) {}
  TeamStep step(DgsStage stage, const std::vector<OutgoingMessage>& estimates,
                const TeamReport& report, const CoarseMessage* share,
                const std::vector<WeightMessage>& weights,
                const std::vector<CovarianceMessage>& covariances) override {
    TeamStep got = inner_.step(stage, estimates, report, share, weights, covariances);
    if (tamper_) tamper_(robot_, got);
    return got;
  }
  std::set<int> absent() const override { return inner_.absent(); }
  std::size_t steps() const { return inner_.steps(); }

 private:
  test::BoardChannel inner_;
  int robot_;
  const Tamper& tamper_;
};

TeamOutcome RunTeam(const PoseGraph& graph, const Values& initial, const std::vector<bool>& robust,
                    const RobustProgramOptions& options, const std::vector<bool>& checked = {},
                    bool reversed = false, const Tamper& tamper = {}) {
  const auto parts = Parts(graph, initial, robust, checked, reversed);
  const Key anchor = GaugeAnchor(graph);
  test::SharedBoard board(static_cast<int>(parts.size()));
  TeamOutcome outcome;
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (const auto& part : parts) {
    threads.emplace_back([&, part]() {
      const RobustRobotProblem& p = part.first;
      AgentOptions ao;
      ao.gamma = options.solver.gamma;
      ao.refine_gamma = options.solver.refinement.gamma;
      ao.flagged_initialisation = options.solver.flagged_initialisation;
      ao.weight_by_information = options.solver.weight_by_information;
      std::unique_ptr<RobotAgent> agent;
      const AgentFactory make = [&](const PoseGraph& g, const Values& start) -> RobotAgent& {
        agent = std::make_unique<RobotAgent>(p.robot, g, start, anchor, ao);
        return *agent;
      };
      TamperedChannel channel(board, p.robot, tamper);
      try {
        RobustProgramResult r = RunRobustRobotProgram(p, options, make, channel);
        EXPECT_EQ(static_cast<std::size_t>(r.channel_steps), channel.steps());
        std::lock_guard<std::mutex> lock(mutex);
        outcome.values.insert(r.estimate.begin(), r.estimate.end());
        outcome.results[p.robot] = std::move(r);
        outcome.factors[p.robot] = part.second;
      } catch (const test::TeamAborted&) {
        // Another robot failed; its error is the one reported.
      } catch (const std::exception& e) {
        board.abort(e.what());
      }
    });
  }
  for (std::thread& t : threads) t.join();
  outcome.error = board.failure();
  return outcome;
}

RobustDgsOptions ReferenceOptions(const RobustProgramOptions& o) {
  RobustDgsOptions r;
  r.dgs = o.solver;
  r.gnc = o.gnc;
  r.check_separators = o.check_separators;
  r.consistency = o.consistency;
  r.retest_left_out = o.retest_left_out;
  r.retest_groups = o.retest_groups;
  r.retest_group_solves = o.retest_group_solves;
  r.one_to_one_after_gnc = o.one_to_one_after_gnc;
  return r;
}

RobustProgramOptions BlocksWorldOptions() {
  RobustProgramOptions o;
  o.solver.order = SweepOrder::kJacobi;
  o.solver.coarse_correction = true;
  o.solver.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
  o.gnc.threshold = 1.0;  // blocks_world: see robust/gnc_test.cc
  return o;
}

// Every robot's weights are the in-process driver's, its estimate equals it, and the rejected
// separators are the spoiled ones.
// Returns the team's outcome.
TeamOutcome ExpectSameAsRunRobustDgs(const PoseGraph& graph, const Values& initial,
                                     const std::vector<bool>& robust,
                                     const RobustProgramOptions& options,
                                     const RobustDgsResult& reference,
                                     const std::vector<bool>& checked = {}, bool reversed = false) {
  TeamOutcome team = RunTeam(graph, initial, robust, options, checked, reversed);
  EXPECT_EQ(team.error, "");
  if (!team.error.empty()) return team;
  EXPECT_EQ(team.values.size(), reference.values.size());
  if (team.values.size() != reference.values.size()) return team;
  EXPECT_LE(MaxPoseDifference(team.values, reference.values), 1e-9);
  std::int64_t weight_messages = 0;
  for (const auto& [robot, r] : team.results) {
    EXPECT_EQ(r.status, reference.status) << "robot " << robot;
    EXPECT_EQ(r.iterations, reference.iterations) << "robot " << robot;
    EXPECT_EQ(r.polished, reference.polished) << "robot " << robot;
    EXPECT_EQ(r.polish_refused, reference.polish_refused) << "robot " << robot;
    const std::vector<std::size_t>& index = team.factors.at(robot);
    EXPECT_EQ(r.weights.size(), index.size());
    if (r.weights.size() != index.size()) return team;
    for (std::size_t j = 0; j < index.size(); ++j) {
      EXPECT_EQ(r.weights[j], reference.weights[index[j]]) << "robot " << robot << " factor "
                                                           << index[j];
    }
    // Its copies of the neighbours' variables the last solve held are the owners' estimates
    // (the inliers' solve, kept or refused, holds no rejected factor).
    for (std::size_t j = 0; j < index.size(); ++j) {
      const RelativePoseFactor& f = graph.factors()[index[j]];
      if ((r.polished || r.polish_refused) && r.weights[j] < 0.5) continue;
      for (const Key& k : {f.a(), f.b()}) {
        if (k.robot == robot) continue;
        EXPECT_LE(MaxPoseDifference({{k, r.neighbours.at(k)}}, {{k, team.values.at(k)}}), 1e-9)
            << ToString(k);
      }
    }
    weight_messages += r.weight_messages;
  }
  if (reference.iterations > 0) {
    EXPECT_GT(weight_messages, 0);
  }
  return team;
}

TEST(RobustProgram, ATeamOfProgramsIsRunRobustDgsWithoutTheCheckOnSpoiledBlocksWorld) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  SpoilOptions spoil;
  spoil.fraction = 0.5;
  spoil.seed = 2;
  const SpoiledGraph spoiled = SpoilSeparators(data.graph, spoil);
  const std::vector<bool> robust = DefaultRobustFactors(spoiled.graph);
  RobustProgramOptions options = BlocksWorldOptions();
  options.check_separators = false;
  const RobustDgsResult reference =
      RunRobustDgs(spoiled.graph, data.initial, robust, ReferenceOptions(options));
  // The case at work: GNC rounds, outliers rejected, the inliers solved alone.
  ASSERT_EQ(reference.status, GncStatus::kConverged);
  ASSERT_GT(reference.iterations, 1);
  ASSERT_GT(reference.outliers, 0);
  ASSERT_TRUE(reference.polished);
  for (std::size_t i = 0; i < spoiled.outlier.size(); ++i) {
    EXPECT_EQ(reference.weights[i] < 0.5, spoiled.outlier[i]) << "factor " << i;
  }
  ExpectSameAsRunRobustDgs(spoiled.graph, data.initial, robust, options, reference);
}

TEST(RobustProgram, WithoutOutliersItIsTheLeastSquaresSolveAndSendsNoWeight) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  const std::vector<bool> robust = DefaultRobustFactors(data.graph);
  RobustProgramOptions options = BlocksWorldOptions();
  options.gnc.threshold = 0.0;  // chi-square: every residual of blocks_world is far below it
  options.check_separators = false;
  const RobustDgsResult reference =
      RunRobustDgs(data.graph, data.initial, robust, ReferenceOptions(options));
  ASSERT_EQ(reference.status, GncStatus::kAllInliers);
  const TeamOutcome team = RunTeam(data.graph, data.initial, robust, options);
  ASSERT_EQ(team.error, "");
  EXPECT_LE(MaxPoseDifference(team.values, reference.values), 1e-9);
  for (const auto& [robot, r] : team.results) {
    EXPECT_EQ(r.status, GncStatus::kAllInliers);
    EXPECT_EQ(r.weight_messages, 0);
    EXPECT_EQ(r.solves.size(), 1u);
    EXPECT_FALSE(r.polished);
  }
}

// Robot 2 linked to robot 1 by two separators that place it far apart: GNC rejects both, and
// the inliers leave robot 2 unlinked, so no robot solves the inliers alone (RunRobustDgs keeps
// the rounds' estimate too).
TEST(RobustProgram, InliersThatUnlinkARobotAreNotSolvedAlone) {
  Values gt;
  const PoseGraph chain = test::ChainOfRobots(3, 6, &gt);
  PoseGraph graph;
  for (const RelativePoseFactor& f : chain.factors()) {
    if (f.a().robot == f.b().robot) {  // stiff chains: robot 2's cannot bend to both
      graph.add(RelativePoseFactor(f.a(), f.b(), f.measured(), 1e4 * f.information()));
    } else if (std::min(f.a().robot, f.b().robot) != 1 || f.a().robot == f.b().robot) {
      graph.add(f);
    }
  }
  auto wrong = [&](Key a, Key b, const SE3& error) {
    graph.add(RelativePoseFactor(a, b, gt.at(a).between(gt.at(b)) * error, Matrix6::Identity()));
  };
  wrong(Key::Pose(1, 5), Key::Pose(2, 0), SE3(SO3::Exp(Vector3(0.0, 0.0, 1.5)), Vector3(30, 0, 0)));
  wrong(Key::Pose(1, 3), Key::Pose(2, 5), SE3(SO3::Exp(Vector3(0.0, 0.0, -1.5)), Vector3(-30, 20, 0)));
  std::vector<bool> robust(graph.factors().size(), false);
  robust[robust.size() - 1] = robust[robust.size() - 2] = true;
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  options.check_separators = false;
  // The two wrong separators disagree, so the truncated cost is lowest with one of them kept
  // (robot 2 fits it exactly); GNC reaches that optimum when the refinement halves the steps
  // that raise F. The case under test is the rejection of both, where GNC ends without halving.
  options.solver.refinement.max_backtracks = 0;
  const RobustDgsResult reference =
      RunRobustDgs(graph, gt, robust, ReferenceOptions(options));
  ASSERT_EQ(reference.outliers, 2);
  ASSERT_FALSE(reference.polished);
  ExpectSameAsRunRobustDgs(graph, gt, robust, options, reference);
}

// Robot 0's landmark of object B is held only by its separator to robot 1's once GNC rejects
// its own (weak, 10 m wrong) observation, and robot 1 reaches robot 0 only through separators.
// The inliers' DGS solves it to their optimum, by the driver and the robots alike: robot 0 solves
// what is tied down first (robot_agent.h). While an agent waited for all of its variables to be
// tied down, each robot waited for the other: stage 1 ran to max_iterations, every translation
// came back 0 and the inliers' cost rose 1e3-fold (house, rendered perception); KeepInlierSolve,
// which turned that solve away, still refuses any inliers' solve that raises their cost.
TEST(RobustProgram, ALandmarkHeldOnlyBySeparatorsIsSolvedWithTheInliers) {
  const SE3 frame1(SO3::Exp(Vector3(0.0, 0.0, 0.7)), Vector3(3.0, 2.0, 0.0));
  const SE3 step(SO3(), Vector3(1.0, 0.0, 0.0));
  const SE3 a(SO3::Exp(Vector3(0.0, 0.0, 0.3)), Vector3(2.0, 1.0, 0.0));
  const SE3 b(SO3::Exp(Vector3(0.0, 0.0, -0.4)), Vector3(2.0, -1.0, 0.5));
  Values gt = {{Key::Pose(0, 0), SE3()},         {Key::Pose(0, 1), step},
               {Key::Pose(1, 0), frame1},        {Key::Pose(1, 1), frame1 * step},
               {Key::Object(0, 0), a},           {Key::Object(0, 1), b},
               {Key::Object(1, 0), a},           {Key::Object(1, 1), b}};
  Matrix6 lambda = Matrix6::Identity();  // the paper's: 5 deg, 0.2 m
  lambda.topLeftCorner<3, 3>() *= 1.0 / std::pow(5.0 * 3.14159265358979 / 180.0, 2);
  lambda.bottomRightCorner<3, 3>() *= 1.0 / (0.2 * 0.2);
  const Matrix6 stiff = 1e4 * Matrix6::Identity();
  PoseGraph graph;
  std::vector<bool> robust;
  auto add = [&](Key x, Key y, const SE3& error, const Matrix6& information, bool is_robust) {
    graph.add(RelativePoseFactor(x, y, gt.at(x).between(gt.at(y)) * error, information));
    robust.push_back(is_robust);
  };
  for (int r = 0; r < 2; ++r) {
    add(Key::Pose(r, 0), Key::Pose(r, 1), SE3(), stiff, false);
    add(Key::Pose(r, 0), Key::Object(r, 0), SE3(), stiff, true);
  }
  add(Key::Pose(1, 1), Key::Object(1, 1), SE3(), stiff, true);
  const std::size_t wrong = graph.factors().size();
  add(Key::Pose(0, 1), Key::Object(0, 1), SE3(SO3(), Vector3(10.0, 0.0, 0.0)),
      Matrix6::Identity(), true);
  add(Key::Object(0, 0), Key::Object(1, 0), SE3(), lambda, true);
  add(Key::Object(0, 1), Key::Object(1, 1), SE3(), lambda, true);
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  options.check_separators = false;
  const RobustDgsResult reference = RunRobustDgs(graph, gt, robust, ReferenceOptions(options));
  ASSERT_EQ(reference.outliers, 1);
  EXPECT_LT(reference.weights[wrong], 0.5);
  EXPECT_TRUE(reference.polished);
  EXPECT_FALSE(reference.polish_refused);
  EXPECT_LT(MaxPoseDifference(reference.values, gt), 1e-6);  // the inliers are exact
  std::vector<bool> inliers(graph.factors().size(), true);
  inliers[wrong] = false;
  DgsOptions dgs = options.solver;
  dgs.refine = true;
  const DgsResult alone = RunDgs(SubGraph(graph, inliers), reference.values, dgs);
  EXPECT_EQ(alone.rotation.status, StageStatus::kConverged);
  ExpectSameAsRunRobustDgs(graph, gt, robust, options, reference);
  // The guard: a solve that raises the cost beyond rounding is not kept.
  EXPECT_TRUE(KeepInlierSolve(401.0, 401.0 * (1.0 + 1e-7)));
  EXPECT_TRUE(KeepInlierSolve(401.0, 12.0));
  EXPECT_TRUE(KeepInlierSolve(0.0, 1e-13));
  EXPECT_FALSE(KeepInlierSolve(401.0, 401.1));
  EXPECT_FALSE(KeepInlierSolve(401.0, std::numeric_limits<double>::quiet_NaN()));
  EXPECT_FALSE(KeepInlierSolve(401.0, std::numeric_limits<double>::infinity()));
}

// The separator check over the channel (C1-C4 of robust_program.h): blocks_world in 4 robots with
// 90 % of the separators wrong, the maps taken as exact (as scripts/robust-g2o.sh runs it): the
// check rejects most wrong ones, leaves pairs of linked robots to GNC, and GNC the rest.
TEST(RobustProgram, ATeamOfProgramsIsRunRobustDgsWithTheCheckOnSpoiledBlocksWorld) {
  const Dataset data = ReadG2oFolder(test::BlocksWorldFolder(4));
  SpoilOptions spoil;
  spoil.fraction = 0.9;
  spoil.seed = 1;
  const SpoiledGraph spoiled = SpoilSeparators(data.graph, spoil);
  const std::vector<bool> robust = DefaultRobustFactors(spoiled.graph);
  RobustProgramOptions options = BlocksWorldOptions();
  options.consistency.map_uncertainty = false;
  const RobustDgsResult reference =
      RunRobustDgs(spoiled.graph, data.initial, robust, ReferenceOptions(options));
  ASSERT_GT(reference.consistency_rejected, 0);
  ASSERT_GT(reference.consistency_deferred, 0);
  ASSERT_GT(reference.iterations, 0);
  for (std::size_t i = 0; i < spoiled.outlier.size(); ++i) {
    EXPECT_EQ(reference.weights[i] < 0.5, spoiled.outlier[i]) << "factor " << i;
  }
  const TeamOutcome team =
      ExpectSameAsRunRobustDgs(spoiled.graph, data.initial, robust, options, reference);
  int rejected = 0, deferred = 0;
  for (const auto& [robot, r] : team.results) {
    rejected += r.check_rejected;
    deferred += r.check_deferred;
    if (robot > 0) {
      EXPECT_GT(r.check_bytes, 0) << "robot " << robot;  // its map estimates
    }
  }
  EXPECT_EQ(rejected, reference.consistency_rejected);
  EXPECT_EQ(deferred, reference.consistency_deferred);
  // The odd robots' factors in reverse order, so that two neighbours list their separators in
  // opposite orders: the weights and verdicts they exchange name the same separators.
  SCOPED_TRACE("the odd robots' factors in reverse order");
  ExpectSameAsRunRobustDgs(spoiled.graph, data.initial, robust, options, reference, {}, true);
}

// With the maps' covariances (PCM's test): robot 1 sends robot 0 its map's estimates and their
// joint covariance; the wrong separators are rejected, the right ones across the drift kept.
TEST(RobustProgram, TheCheckWithMapCovariancesIsRunRobustDgs) {
  std::vector<bool> wrong;
  const PoseGraph graph = test::DriftingPairWithWrongSeparators(&wrong);
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  const RobustDgsResult reference =
      RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
  const std::size_t first = graph.factors().size() - wrong.size();
  for (std::size_t s = 0; s < wrong.size(); ++s) {
    EXPECT_EQ(reference.weights[first + s] < 0.5, static_cast<bool>(wrong[s])) << "separator " << s;
  }
  ASSERT_EQ(reference.consistency_rejected, 2);
  const TeamOutcome team = ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference);
  ASSERT_EQ(team.error, "");
  // Robot 1's map estimates of its 8 separator variables and their covariance, then its
  // estimates of the 2 in the rejected separators for the readmission, and again after the
  // inliers' solve for the re-test (which finds no candidate, and no group: two wrong ones are
  // fewer than min_support): RunRobustDgs's count.
  ASSERT_EQ(reference.group_retests, 0);
  EXPECT_EQ(team.results.at(1).check_messages, 4);
  EXPECT_EQ(team.results.at(1).check_bytes, reference.consistency_bytes);
  EXPECT_EQ(team.results.at(0).check_rejected, 2);
}

// A peer whose messages break the check's protocol is refused by name, not trusted: the lower
// robot's check needs the higher one's covariance with its estimates, and the higher one reads a
// verdict of one entry per separator they share, then the pair's flag.
TEST(RobustProgram, ThePeersCheckMessagesThatBreakTheProtocolAreRefusedNamingIt) {
  std::vector<bool> wrong;
  const PoseGraph graph = test::DriftingPairWithWrongSeparators(&wrong);
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  ASSERT_TRUE(options.consistency.map_uncertainty);
  const Tamper no_covariance = [](int robot, TeamStep& got) {
    if (robot == 0) got.covariances.clear();
  };
  EXPECT_NE(RunTeam(graph, initial, robust, options, {}, false, no_covariance)
                .error.find("robot 1 sent its map's estimates without their covariance"),
            std::string::npos);
  bool first = true;  // only robot 1's thread reads and writes it
  const Tamper short_verdict = [&first](int robot, TeamStep& got) {
    const auto it = got.weights.find(0);
    if (robot != 1 || it == got.weights.end() || !first) return;
    first = false;  // the check's first exchange, before any GNC round
    it->second.weights.pop_back();
  };
  const TeamOutcome team = RunTeam(graph, initial, robust, options, {}, false, short_verdict);
  EXPECT_NE(team.error.find("robot 0 sent a separator check verdict of"), std::string::npos)
      << team.error;
  EXPECT_NE(team.error.find("of 8 entries where the 8 separators robot 1 shares with it need 9"),
            std::string::npos)
      << team.error;
}

// The re-test of the check's rejects (robust_dgs_test.cc, the same layout): the robots' programs
// re-test the same two separators in the same order and reach RunRobustDgs's weights and estimate.
TEST(RobustProgram, TheRetestOfTheChecksRejectsIsRunRobustDgs) {
  std::vector<bool> wrong;
  const PoseGraph graph = test::DriftingPairWithANearMiss(&wrong);
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  options.consistency.threshold = 12.0;
  options.retest_left_out = true;
  const RobustDgsResult reference =
      RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
  ASSERT_EQ(reference.retests, 2);
  ASSERT_EQ(reference.retest_readmitted, 1);
  ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference);
  {
    SCOPED_TRACE("robot 1's factors in reverse order");
    ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference, {}, true);
  }
  const TeamOutcome team = RunTeam(graph, initial, robust, options);
  ASSERT_EQ(team.error, "");
  EXPECT_EQ(team.results.at(0).retests, 2);
  EXPECT_EQ(team.results.at(1).retests, 2);
  EXPECT_EQ(team.results.at(0).retest_readmitted, 1);  // robot 0 owns the separators
  EXPECT_EQ(team.results.at(1).retest_readmitted, 0);
  // Robot 1 sends every message of the check, the re-test's estimates included.
  EXPECT_EQ(team.results.at(1).check_bytes, reference.consistency_bytes);
}

// With the one-to-one rule kept after GNC (test::TwoChairsSideBySide, whose wrong pair the
// readmission would take back and the re-test would try): the programs are RunRobustDgs, the
// owner of the pair settling it alone.
TEST(RobustProgram, OneToOneAfterGncIsRunRobustDgs) {
  const PoseGraph graph = test::TwoChairsSideBySide();
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  options.one_to_one_after_gnc = true;
  const RobustDgsResult reference = RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
  ASSERT_EQ(reference.weights.back(), 0.0);
  ASSERT_EQ(reference.consistency_rejected, 1);
  const TeamOutcome team = ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference);
  ASSERT_EQ(team.error, "");
  for (const auto& [robot, r] : team.results) {
    EXPECT_EQ(r.readmitted, 0) << "robot " << robot;
    EXPECT_EQ(r.retests, 0) << "robot " << robot;
  }
  options.one_to_one_after_gnc = false;  // the pair back, in both
  const RobustDgsResult without = RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
  ASSERT_EQ(without.weights.back(), 1.0);
  ExpectSameAsRunRobustDgs(graph, initial, robust, options, without);
}

// The rule in the group re-test (test::ObjectsMappedTwice, whose three pairs the check leaves out
// come back through the readmission without the rule, and are re-tested as a group with it): the
// programs are RunRobustDgs either way.
TEST(RobustProgram, OneToOneAfterGncInTheGroupRetestIsRunRobustDgs) {
  const PoseGraph graph = test::ObjectsMappedTwice();
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  for (const bool one_to_one : {true, false}) {
    SCOPED_TRACE(one_to_one ? "with the rule" : "without");
    options.one_to_one_after_gnc = one_to_one;
    const RobustDgsResult reference =
        RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
    ASSERT_EQ(reference.group_retests, one_to_one ? 1 : 0);
    ASSERT_EQ(reference.readmitted, one_to_one ? 0 : 3);
    const TeamOutcome team = ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference);
    ASSERT_EQ(team.error, "");
  }
}

// The graph's last factor unseen by the check (the `checked` mask; Jacobi options, chordal start):
// RunRobustDgs with that mask, and the programs with it against it. Returns the reference.
RobustDgsResult ExpectLastFactorUncheckedAsRunRobustDgs(const PoseGraph& graph) {
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  std::vector<bool> checked(graph.factors().size(), true);
  checked.back() = false;
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  const RobustDgsResult reference =
      RunRobustDgs(graph, initial, robust, ReferenceOptions(options), checked);
  ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference, checked);
  return reference;
}

// The check sees only the factors `checked` marks (online: not the held factors): here robot 1's
// map without a wrong factor between its first and last poses, which is kept (least squares).
// The programs with the mask are RunRobustDgs with it.
TEST(RobustProgram, TheCheckedMaskIsRunRobustDgsWithIt) {
  std::vector<bool> wrong;
  PoseGraph graph = test::DriftingPairWithWrongSeparators(&wrong);
  const RelativePoseFactor end = graph.factors()[58];  // robot 0's last odometry factor
  graph.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 59),
                               SE3(SO3::Exp(Vector3(0.0, 0.0, 0.3)), Vector3(2.0, 0.0, 0.0)),
                               end.information()));
  const RobustDgsResult reference = ExpectLastFactorUncheckedAsRunRobustDgs(graph);
  EXPECT_EQ(reference.consistency_rejected, 2);  // the check sees robot 1's map without it
  // The mask matters: the wrong factor bends the map the check tests robot 1's separators in, so
  // that without the mask it leaves all 8 out, and robot 1 unlinked.
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  EXPECT_THROW(RunRobustDgs(graph, ChordalInitialization(graph, SE3()),
                            DefaultRobustFactors(graph), ReferenceOptions(options)),
               UnderdeterminedError);
}

// A robot that neighbours another only through separators the check does not see (online: a
// held factor anchored at another robot's first pose) sends it no map estimate or covariance
// (a first version sent the covariance of no variable: a Cholesky of nothing, not finite; that
// robot's program threw and the others waited for it).
// Robot 2 (a third drifting chain, exact factors): four checked separators to robot 0 and one
// unchecked to robot 1.
TEST(RobustProgram, ANeighbourOnlyThroughUncheckedSeparatorsIsNotChecked) {
  std::vector<bool> wrong;
  PoseGraph graph = test::DriftingPairWithWrongSeparators(&wrong);
  const Matrix6 information = graph.factors().front().information();
  const auto truth = [](int r, int i) {  // as DriftingPairWithWrongSeparators lays the chains
    SE3 x(SO3(), Vector3(0.0, 3.0 * r, 0.0));
    const SE3 step(SO3::Exp(Vector3(0.0, 0.0, 0.05)), Vector3(0.5, 0.0, 0.0));
    for (int k = 0; k < i; ++k) x = x * step;
    return x;
  };
  const auto pose = [](int r, int i) { return Key::Pose(r, static_cast<std::uint64_t>(i)); };
  for (int i = 0; i + 1 < 20; ++i) {
    graph.add(RelativePoseFactor(pose(2, i), pose(2, i + 1), truth(2, i).between(truth(2, i + 1)),
                                 information));
  }
  for (int i : {0, 5, 10, 15}) {
    graph.add(RelativePoseFactor(pose(0, i), pose(2, i), truth(0, i).between(truth(2, i)),
                                 information));
  }
  graph.add(RelativePoseFactor(pose(1, 12), pose(2, 12), truth(1, 12).between(truth(2, 12)),
                               information));
  // The two wrong separators of robots 0 and 1.
  EXPECT_EQ(ExpectLastFactorUncheckedAsRunRobustDgs(graph).consistency_rejected, 2);
}

// A check that leaves a robot with no separator (two agreeing separators, fewer than min_support,
// and no confirmed pair to link them): RunRobustDgs throws UnderdeterminedError; every program
// finds it alike, solves nothing and keeps its initial estimate.
TEST(RobustProgram, ACheckThatUnlinksARobotStopsEveryRobotBeforeAnySolve) {
  std::vector<bool> wrong;
  const PoseGraph full = test::DriftingPairWithWrongSeparators(&wrong);
  PoseGraph graph;
  int separators = 0;
  for (const RelativePoseFactor& f : full.factors()) {
    if (f.a().robot != f.b().robot && ++separators > 2) continue;
    graph.add(f);
  }
  const std::vector<bool> robust = DefaultRobustFactors(graph);
  const Values initial = ChordalInitialization(graph, SE3());
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  EXPECT_THROW(RunRobustDgs(graph, initial, robust, ReferenceOptions(options)),
               UnderdeterminedError);
  const TeamOutcome team = RunTeam(graph, initial, robust, options);
  ASSERT_EQ(team.error, "");
  ASSERT_EQ(team.results.size(), 2u);
  for (const auto& [robot, r] : team.results) {
    EXPECT_TRUE(r.unlinked) << "robot " << robot;
    EXPECT_TRUE(r.solves.empty());
    EXPECT_TRUE(r.neighbours.empty());
    const std::vector<std::size_t>& index = team.factors.at(robot);
    for (std::size_t j = 0; j < index.size(); ++j) {
      const RelativePoseFactor& f = graph.factors()[index[j]];
      EXPECT_EQ(r.weights[j], f.a().robot != f.b().robot ? 0.0 : 1.0);
    }
  }
  Values own;
  for (const auto& [k, x] : initial) own[k] = x;
  EXPECT_EQ(MaxPoseDifference(team.values, own), 0.0);
}

// A single robot's file split among robots (`moslam team <file> --robots 2 --robust`): CSAIL with
// 30 % of its loop closures wrong, the file's loop closures robust (LoopClosureFactors, in a block
// and between blocks). Each robot checks its own through its own odometry (C5) beside the
// separator check, as RunRobustDgs; without C5 the wrong ones inside a block stay for GNC, which
// misses some.
TEST(RobustProgram, EachRobotChecksItsOwnLoopClosuresAsRunRobustDgs) {
  const auto [data, spoiled] = test::SpoilPgoFile("CSAIL.g2o", 0.3);
  const SplitGraph split = SplitIntoRobots(spoiled.graph, data.initial, 2);
  const std::vector<bool> robust = LoopClosureFactors(split.graph);
  ASSERT_EQ(robust, DefaultRobustFactors(spoiled.graph));  // the file's loop closures
  int within = 0;                                          // wrong loop closures inside a block
  for (std::size_t i = 0; i < spoiled.outlier.size(); ++i) {
    const RelativePoseFactor& f = split.graph.factors()[i];
    within += spoiled.outlier[i] && f.a().robot == f.b().robot ? 1 : 0;
  }
  ASSERT_GT(within, 0);
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  options.gnc.threshold = 5.0;
  const RobustDgsResult reference =
      RunRobustDgs(split.graph, split.initial, robust, ReferenceOptions(options));
  for (std::size_t i = 0; i < spoiled.outlier.size(); ++i) {
    EXPECT_EQ(reference.weights[i] < 0.5, spoiled.outlier[i]) << "factor " << i;
  }
  const TeamOutcome team =
      ExpectSameAsRunRobustDgs(split.graph, split.initial, robust, options, reference);
  int rejected = 0;
  for (const auto& [robot, r] : team.results) rejected += r.check_rejected;
  EXPECT_EQ(rejected, reference.consistency_rejected);
  EXPECT_GE(rejected, within);
}

// C5 before C1: robot 1's wrong loop closures, two that its own check can neither confirm nor
// reject or three that it confirms, are left out of the map it sends for the separator check
// (robust_dgs_test.cc, the same graphs): the programs keep every right separator and reach
// RunRobustDgs's weights and estimate.
TEST(RobustProgram, MapsWithoutTheirOwnLoopClosuresAsRunRobustDgs) {
  for (int loop_closures : {2, 3}) {
    SCOPED_TRACE(loop_closures);
    std::vector<bool> wrong, robust;
    const PoseGraph graph =
        test::DriftingPairWithBendingLoopClosures(&wrong, &robust, loop_closures);
    const Values initial = ChordalInitialization(graph, SE3());
    RobustProgramOptions options;
    options.solver.order = SweepOrder::kJacobi;
    const RobustDgsResult reference =
        RunRobustDgs(graph, initial, robust, ReferenceOptions(options));
    ASSERT_EQ(reference.consistency_rejected, 2);
    const std::size_t first = graph.factors().size() - loop_closures - wrong.size();
    for (std::size_t s = 0; s < wrong.size(); ++s) {
      EXPECT_EQ(reference.weights[first + s] < 0.5, static_cast<bool>(wrong[s])) << s;
    }
    const TeamOutcome team = ExpectSameAsRunRobustDgs(graph, initial, robust, options, reference);
    ASSERT_EQ(team.error, "");
    EXPECT_EQ(team.results.at(0).check_rejected + team.results.at(1).check_rejected, 2);
  }
}

TEST(RobustProgram, RejectsBadInput) {
  Values gt;
  const PoseGraph graph = test::ChainOfRobots(2, 3, &gt);
  const auto parts = Parts(graph, gt, std::vector<bool>(graph.factors().size(), false));
  RobustRobotProblem p = parts.front().first;
  p.robust.pop_back();
  test::SharedBoard board(1);
  test::BoardChannel channel(board, p.robot);
  std::unique_ptr<RobotAgent> agent;
  const AgentFactory make = [&](const PoseGraph& g, const Values& start) -> RobotAgent& {
    agent = std::make_unique<RobotAgent>(p.robot, g, start, GaugeAnchor(graph), AgentOptions());
    return *agent;
  };
  RobustProgramOptions options;
  options.solver.order = SweepOrder::kJacobi;
  EXPECT_THROW(RunRobustRobotProgram(p, options, make, channel), InvalidInputError);
  p = parts.front().first;
  p.checked.assign(p.subgraph.factors().size() + 1, true);
  EXPECT_THROW(RunRobustRobotProgram(p, options, make, channel), InvalidInputError);
  p = parts.front().first;
  options.solver.order = SweepOrder::kGaussSeidel;
  EXPECT_THROW(RunRobustRobotProgram(p, options, make, channel), InvalidInputError);
  options.solver.order = SweepOrder::kJacobi;
  options.retest_group_solves = 0;
  EXPECT_THROW(RunRobustRobotProgram(p, options, make, channel), InvalidInputError);
  options.retest_group_solves = 10;
  EXPECT_THROW(RunRobustRobotProgram(p, options, nullptr, channel), InvalidInputError);
}

TEST(RobustProgram, BadOptionsNameTheField) {
  using R = RobustProgramOptions;
  R base;
  base.solver.order = SweepOrder::kJacobi;
  EXPECT_TRUE(test::EachChangeIsRefused<R>(
      {
          {"retest_group_solves", [](R& o) { o.retest_group_solves = 0; }},
          {"solver.order must be Jacobi", [](R& o) { o.solver.order = SweepOrder::kGaussSeidel; }},
          {"consistency.threshold", [](R& o) { o.consistency.threshold = -1.0; }},
          {"min_support", [](R& o) { o.consistency.min_support = 0; }},
      },
      base));
  // Without the check, its options are not read.
  R unchecked = base;
  unchecked.check_separators = false;
  unchecked.consistency.threshold = -1.0;
  EXPECT_NO_THROW(unchecked.validate());
}

}  // namespace
}  // namespace moslam
