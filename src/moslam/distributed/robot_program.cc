#include "moslam/distributed/robot_program.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/coarse_system.h"

namespace moslam {

double TeamSum(const TeamStep& step, int i) {
  double total = 0.0;
  for (const auto& [r, report] : step.reports) total += report.value[i];
  return total;
}

double TeamMax(const TeamStep& step, int i) {
  double m = 0.0;
  for (const auto& [r, report] : step.reports) m = std::max(m, report.value[i]);
  return m;
}

std::map<int, double> TeamValues(const TeamStep& step, int i) {
  std::map<int, double> out;
  for (const auto& [r, report] : step.reports) out[r] = report.value[i];
  return out;
}

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

class Program {
 public:
  Program(RobotAgent& agent, const DgsOptions& options, TeamChannel& channel)
      : agent_(agent), options_(options), channel_(channel) {}

  RobotProgramResult run() {
    runStage(DgsStage::kRotation, result_.rotation);
    runStage(DgsStage::kPose, result_.pose);
    agent_.finish();
    if (options_.refine) runRefinement();
    return result_;
  }

 private:
  // One channel step; the estimates received are delivered to the agent.
  TeamStep step(DgsStage stage, bool send, TeamReport report,
                const CoarseMessage* share = nullptr) {
    std::vector<OutgoingMessage> out;
    if (send) out = agent_.outgoing();
    report.sent = !out.empty();
    report.has_share = share != nullptr;
    TeamStep got = channel_.step(stage, out, report, share, {}, {});
    ++result_.channel_steps;
    for (const Message& m : got.estimates) agent_.receive(m);
    return got;
  }

  TeamReport progressReport() const {
    TeamReport r;
    r.initialised = agent_.initialised();
    constexpr double kInf = std::numeric_limits<double>::infinity();
    r.change = r.initialised ? agent_.lastChange() : kInf;
    r.bound = r.initialised ? agent_.errorBound(options_.error_bound_window) : kInf;
    return r;
  }

  static bool AllCoarseReady(const TeamStep& s) {
    for (const auto& [r, report] : s.reports) {
      if (!report.coarse_ready || !report.has_share) return false;
    }
    return !s.reports.empty();
  }

  // The coarse system of the robots that shared (id order), factorized; null when some live robot
  // could not take part or the matrix is not positive definite (every robot decides alike).
  static std::unique_ptr<CoarseSystem> Assemble(const TeamStep& s, int k, Eigen::MatrixXd* B,
                                                int ncols) {
    if (!AllCoarseReady(s)) return nullptr;
    std::vector<int> robots;
    for (const auto& [r, share] : s.shares) robots.push_back(r);
    auto coarse = std::make_unique<CoarseSystem>(robots, k);
    if (B) *B = Eigen::MatrixXd(coarse->rows(), ncols);
    for (const auto& [r, share] : s.shares) {
      const Eigen::MatrixXd residual = coarse->addShare(share);
      if (B) B->middleRows(coarse->index(r), k) = residual;
    }
    if (!coarse->factorize()) return nullptr;
    return coarse;
  }

  std::map<int, Eigen::MatrixXd> MySolution(const CoarseSystem& coarse, const Eigen::MatrixXd& Y,
                                            DgsStage stage, std::uint32_t iteration, int k,
                                            int ncols) const {
    const CoarseMessage m = coarse.solutionFor(agent_.robot(), agent_.neighbourRobots(), Y, stage,
                                               agent_.robot(), iteration);
    std::map<int, Eigen::MatrixXd> y;
    for (const auto& [s, block] : m.blocks) y[s] = UnflattenMatrix(block, k, ncols);
    return y;
  }

  // ---- stages 1 and 2 -------------------------------------------------------------------
  void runStage(DgsStage stage, DgsStageReport& report) {
    const double eta = stage == DgsStage::kRotation ? options_.eta_rotation : options_.eta_pose;
    if (stage == DgsStage::kRotation) {
      agent_.startRotation();
    } else {
      agent_.startPose();
    }
    const bool by_cg = stage == DgsStage::kPose &&
                       options_.pose_solver == DgsOptions::PoseSolver::kConjugateGradient;
    if (!options_.flagged_initialisation) {
      step(stage, true, TeamReport());  // the initial estimates
    }
    report.status = StageStatus::kMaxIterations;
    if (by_cg) {
      // With flagged initialisation, the flagged sweeps until no robot is left to initialise,
      // then the conjugate gradients from their values: the driver's rule (dgs_driver.h).
      int warm = 0;
      for (int initialised = 0;
           options_.flagged_initialisation && warm < options_.max_iterations;) {
        ++warm;
        const bool solved = agent_.iterate();
        const TeamStep got = step(stage, solved, progressReport());
        StageStopRule rule(options_.stopping, eta);
        for (const auto& [r, rep] : got.reports) rule.add(rep.initialised, rep.change, rep.bound);
        report.iterations = warm;
        report.final_change = rule.maxChange();
        if (FlaggedSweepsDone(rule, initialised)) break;
        initialised = rule.initialisedRobots();
      }
      if (warm < options_.max_iterations) runPoseByConjugateGradients(report, warm);
      return;
    }
    for (int it = 1; it <= options_.max_iterations; ++it) {
      const bool solved = agent_.iterate();
      TeamReport mine = progressReport();
      mine.coarse_ready = options_.coarse_correction && agent_.coarseReady(channel_.absent());
      const TeamStep got = step(stage, solved, mine);
      StageStopRule rule(options_.stopping, eta);
      for (const auto& [r, rep] : got.reports) rule.add(rep.initialised, rep.change, rep.bound);
      const bool converged = rule.converged();
      bool all_ready = !got.reports.empty();
      for (const auto& [r, rep] : got.reports) all_ready = all_ready && rep.coarse_ready;
      if (!converged && options_.coarse_correction && all_ready) {
        if (coarseCorrection(stage, it)) ++report.coarse_corrections;
      }
      report.iterations = it;
      report.final_change = rule.maxChange();
      report.final_error_bound = rule.maxBound();
      if (converged) {
        report.status = StageStatus::kConverged;
        break;
      }
    }
  }

  bool coarseCorrection(DgsStage stage, int iteration) {
    const int k = stage == DgsStage::kRotation ? 3 : 6;
    const int ncols = stage == DgsStage::kRotation ? 3 : 1;
    CoarseMessage m = ShareMessage(CoarseKind::kShare, stage, agent_.robot(),
                                   static_cast<std::uint32_t>(iteration), agent_.coarseShare());
    TeamReport mine;
    mine.coarse_ready = true;
    const TeamStep got = step(stage, false, mine, &m);
    Eigen::MatrixXd B, Y;
    const auto coarse = Assemble(got, k, &B, ncols);
    if (!coarse || !coarse->solve(B, &Y)) return false;
    agent_.applyCoarse(MySolution(*coarse, Y, stage, static_cast<std::uint32_t>(iteration), k,
                                  ncols));
    return true;
  }

  // ---- conjugate gradients (pose stage, refinement steps; cg_decisions.h) ---------------------
  CgOutcome solveByConjugateGradients(DgsStage stage, const CgGoal& goal) {
    const DgsOptions::Refinement& opt = options_.refinement;
    CgOutcome outcome;
    int& sweeps = outcome.sweeps;
    std::unique_ptr<CoarseSystem> coarse;
    std::unique_ptr<PieceCoarseSystem> pieces;  // by pieces (refinement.coarse_piece_poses)
    const bool by_pieces = stage == DgsStage::kRefine && opt.coarse_piece_poses > 0;
    bool coarse_tried = false;
    auto precondition = [&]() {
      agent_.startPreconditioner();
      if (opt.preconditioner == RefinePreconditioner::kTwoLevel && !coarse_tried) {
        coarse_tried = true;
        const auto sweep = static_cast<std::uint32_t>(sweeps);
        if (by_pieces) {
          pieces = pieceMatrix(sweep);
        } else {
          coarse = coarseMatrix(stage, sweep);
        }
      }
      // Jacobi: one sweep, or two around the correction
      const int passes = coarse || pieces ? 2 : 1;
      for (int pass = 0; pass < passes; ++pass) {
        const bool solved = agent_.iterate();
        step(stage, solved, progressReport());
        ++sweeps;
        if (pass == 0 && coarse) coarseResidualCorrection(stage, *coarse, sweeps);
        if (pass == 0 && pieces) pieceResidualCorrection(*pieces, sweeps);
      }
    };
    auto reduce = [&](double value0, double value1) {
      TeamReport mine;
      mine.value[0] = value0;
      mine.value[1] = value1;
      return step(stage, false, mine);
    };
    CgDecisions cg(goal);
    precondition();
    if (cg.start(TeamSum(reduce(agent_.residualDot(), 0.0), 0))) {
      agent_.firstDirection();
      while (true) {
        const double curvature = agent_.curvature();
        const TeamStep got = reduce(curvature, agent_.directionNorm());
        const std::optional<double> alpha = cg.stepLength(TeamSum(got, 0), TeamMax(got, 1));
        if (!alpha) break;
        agent_.advance(*alpha);
        precondition();
        const double rz = TeamSum(reduce(agent_.residualDot(), 0.0), 0);
        const CgDecisions::Next next = cg.next(rz, sweeps);
        if (next.stop) break;
        agent_.nextDirection(next.beta);
      }
    }
    outcome.converged = cg.converged();
    outcome.model_decrease = cg.modelDecrease();
    return outcome;
  }

  // The step's coarse matrix from every robot's rows (null: no two-level correction this step).
  std::unique_ptr<CoarseSystem> coarseMatrix(DgsStage stage, std::uint32_t sweep) {
    TeamReport mine;
    CoarseMessage m;
    const bool ready = agent_.refineCoarseReady();
    if (ready) {
      m = ShareMessage(CoarseKind::kMatrix, stage, agent_.robot(), sweep,
                       agent_.refineCoarseMatrix());
      mine.coarse_ready = true;
    }
    const TeamStep got = step(stage, false, mine, ready ? &m : nullptr);
    return Assemble(got, 6, nullptr, 1);
  }

  // The same by pieces: every robot assembles the team's piece system from the matrices shared.
  std::unique_ptr<PieceCoarseSystem> pieceMatrix(std::uint32_t sweep) {
    TeamReport mine;
    CoarseMessage m;
    const bool ready = agent_.refineCoarseReady();
    if (ready) {
      m = agent_.refinePieceMatrix(options_.refinement.coarse_piece_poses, sweep);
      mine.coarse_ready = true;
    }
    const TeamStep got = step(DgsStage::kRefine, false, mine, ready ? &m : nullptr);
    if (!AllCoarseReady(got)) return nullptr;
    auto coarse = std::make_unique<PieceCoarseSystem>();
    for (const auto& [r, share] : got.shares) coarse->addMatrix(share);
    if (!coarse->factorize()) return nullptr;
    return coarse;
  }

  void pieceResidualCorrection(const PieceCoarseSystem& coarse, int sweep) {
    const auto iteration = static_cast<std::uint32_t>(sweep);
    const CoarseMessage m = agent_.refinePieceResidual(iteration);
    TeamReport mine;
    mine.coarse_ready = true;
    const TeamStep got = step(DgsStage::kRefine, false, mine, &m);
    // Robots of the system that left meanwhile contribute a zero residual (their variables stay).
    std::vector<CoarseMessage> residuals;
    for (const auto& [r, share] : got.shares) {
      if (coarse.has(r) && share.kind == CoarseKind::kPieceResidual) residuals.push_back(share);
    }
    Eigen::VectorXd Y;
    if (!coarse.solve(residuals, &Y)) return;
    agent_.applyRefinePieces(
        coarse.solutionFor(agent_.robot(), agent_.neighbourRobots(), Y, agent_.robot(), iteration));
    ++result_.refine.coarse_corrections;
  }

  void coarseResidualCorrection(DgsStage stage, const CoarseSystem& coarse, int sweep) {
    CoarseMessage m;
    m.kind = CoarseKind::kResidual;
    m.stage = stage;
    m.sender = agent_.robot();
    m.iteration = static_cast<std::uint32_t>(sweep);
    m.k = 6;
    m.ncols = 1;
    m.residual = FlattenMatrix(agent_.refineCoarseResidual());
    TeamReport mine;
    mine.coarse_ready = true;
    const TeamStep got = step(stage, false, mine, &m);
    // Robots of the system that left meanwhile contribute a zero residual (their variables stay).
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(coarse.rows(), 1);
    for (const auto& [r, share] : got.shares) {
      if (coarse.index(r) < 0 || share.kind != CoarseKind::kResidual) continue;
      B.middleRows(coarse.index(r), 6) = UnflattenMatrix(share.residual, 6, 1);
    }
    Eigen::MatrixXd Y;
    if (!coarse.solve(B, &Y)) return;
    agent_.applyRefineCoarse(
        MySolution(coarse, Y, stage, static_cast<std::uint32_t>(sweep), 6, 1));
    ++(stage == DgsStage::kRefine ? result_.refine.coarse_corrections
                                   : result_.pose.coarse_corrections);
  }

  void runPoseByConjugateGradients(DgsStageReport& report, int sweeps_before) {
    CgGoal goal;
    goal.eta_change = options_.eta_pose;
    goal.max_sweeps = options_.max_iterations - sweeps_before;
    const CgOutcome outcome = solveByConjugateGradients(DgsStage::kPose, goal);
    report.status = outcome.converged ? StageStatus::kConverged : StageStatus::kMaxIterations;
    report.iterations = sweeps_before + outcome.sweeps;
  }

  // Plain block Jacobi sweeps on the step's system; each robot reports its change and ||delta_r||.
  void solveBySweeps(RefineStepSummary& summary) {
    const DgsOptions::Refinement& opt = options_.refinement;
    for (int sweep = 1; sweep <= opt.max_sweeps; ++sweep) {
      const bool solved = agent_.iterate();
      TeamReport mine;
      mine.value[0] = agent_.initialised() ? agent_.lastChange() : 0.0;
      mine.value[1] = agent_.incrementNorm();
      const TeamStep got = step(DgsStage::kRefine, solved, mine);
      const bool stop = TeamMax(got, 0) <= opt.sweep_tolerance * TeamMax(got, 1);
      summary.sweeps = sweep;
      summary.linear_converged = stop;
      if (stop) break;
    }
  }

  // ---- refinement -----------------------------------------------------------------------------
  double teamCost(bool candidate) {
    TeamReport mine;
    mine.value[0] = agent_.costShare(candidate);
    return TeamSum(step(DgsStage::kRefine, false, mine), 0);
  }

  void runRefinement() {
    RefineReport& report = result_.refine;
    const auto stage_start = Clock::now();
    const DgsOptions::Refinement& opt = options_.refinement;
    std::set<int> told;  // robots that left, told to the agent
    auto tellAbsent = [&]() {
      bool changed = false;
      for (int r : channel_.absent()) {
        if (!told.insert(r).second) continue;
        agent_.setUnresponsive(r);
        changed = true;
      }
      return changed;
    };
    agent_.startRefine();
    tellAbsent();
    double cost = teamCost(false);
    report.initial_cost = cost;
    report.final_cost = cost;
    report.status = StageStatus::kMaxIterations;
    double lambda = 0.0;
    for (int s = 1; s <= opt.max_iterations; ++s) {
      const auto step_start = Clock::now();
      if (tellAbsent()) cost = teamCost(false);  // the shares changed
      RefineStepSummary summary;
      summary.iteration = s;
      summary.lambda = lambda;
      summary.cost_before = cost;
      agent_.beginStep(lambda);
      if (opt.solver == RefineSolver::kConjugateGradient) {
        CgGoal goal;
        goal.tolerance = opt.cg_tolerance;
        goal.max_sweeps = opt.max_sweeps;
        const CgOutcome outcome = solveByConjugateGradients(DgsStage::kRefine, goal);
        summary.sweeps = outcome.sweeps;
        summary.linear_converged = outcome.converged;
        summary.predicted_decrease = outcome.model_decrease;
      } else {
        solveBySweeps(summary);
      }
      report.sweeps += summary.sweeps;
      // Every robot takes the driver's decision on the same team sums; a halved step needs one
      // more cost all-reduce each (dgs_driver.h).
      summary.cost_candidate = teamCost(true);
      RefineDecision decision;
      while ((decision = DecideRefineStep(summary, opt, lambda, report)).backtrack) {
        agent_.scaleStep(0.5);
        ++summary.backtracks;
        summary.step_scale *= 0.5;
        summary.cost_candidate = teamCost(true);
      }
      const double candidate = summary.cost_candidate;
      const bool accept = decision.accept;
      const bool finished = decision.finished;
      if (accept) {
        agent_.acceptStep();
        cost = candidate;
      }
      summary.accepted = accept;
      summary.seconds = Since(step_start);
      report.iterations = s;
      report.final_cost = cost;
      report.steps.push_back(summary);
      if (finished) break;
    }
    agent_.finishRefine();
    report.seconds = Since(stage_start);
  }

  RobotAgent& agent_;
  const DgsOptions& options_;
  TeamChannel& channel_;
  RobotProgramResult result_;
};

}  // namespace

RobotProgramResult RunRobotProgram(RobotAgent& agent, const DgsOptions& options,
                                   TeamChannel& channel) {
  options.validate();
  if (options.order != SweepOrder::kJacobi) {
    throw InvalidInputError("robot program: the robots of a team solve in parallel (Jacobi "
                            "order); Gauss-Seidel order needs a central sequencer");
  }
  if (agent.state() != AgentState::kIdle) {
    throw InvalidInputError("robot program: the agent must be new (state " +
                            ToString(agent.state()) + ")");
  }
  return Program(agent, options, channel).run();
}

}  // namespace moslam
