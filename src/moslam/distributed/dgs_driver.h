// In-process driver of the distributed Gauss-Seidel solver (shared/DGS.md): N robot agents
// (robot_agent.h), one per robot owning variables (partition.h), run stage 1 (rotations) then
// stage 2 (pose step). Every message that crosses between agents is serialized
// (messages.h), counted, and the DECODED bytes are delivered, so message and byte counts are the
// real traffic.
//
//   DgsResult r = RunDgs(graph, initial, options);
//
// Per stage: every agent starts the stage; without flagged initialisation the agents first
// exchange their initial estimates (iteration 0 messages, counted in iteration 0). Then sweeps:
// each robot, in the robot order, solves once; Gauss-Seidel delivers its messages before the
// next robot solves, Jacobi delivers all messages at the end of the sweep. The stage stops after
// the first sweep in which every live robot has solved in the stage and changed by at most eta
// (lastChange() <= eta; with StageStopping::kErrorBound: errorBound() <= eta, dgs_types.h), or
// after max_iterations sweeps. A robot that cannot solve yet (flagged
// initialisation) sends nothing that sweep. The sweeps converge linearly, so the distance left to
// the fixed point (the centralized two-stage estimate) is about eta * rho / (1 - rho) for a
// per-sweep contraction rho; on blocks_world rho reaches 0.97 in stage 1 and 0.9996 in stage 2.
//
// Robot order: robot 0 first; with flagged initialisation, then repeatedly every robot not yet
// ordered that is linked to the ordered set, most linking neighbour variables first (ties: lower
// robot id), then any robot left over; without it, 0, 1, ..., N-1.
//
// Refinement (beyond DGS.md; options.refine, or runRefineStage()): Gauss-Newton on the SE(3) cost
// F = sum 1/2 r^T Omega r from the two-stage estimate. Each step linearises every robot at the
// current estimate (the anchor stays fixed) and solves H delta = -g with robot-by-robot block
// solves: robot r solves with its own block H_rr and its neighbours' latest values. Only values
// of separator variables cross during a step (6 numbers each); the neighbours' poses are never
// re-sent (robot_agent.h). A coordinator (the first live robot of the order) gathers scalars and
// broadcasts decisions with control messages (messages.h, 32 bytes each, counted with the rest).
// The linear solve (refinement.solver):
//   - kConjugateGradient (default): conjugate gradients on H delta = -g, preconditioned by
//     the sweeps: a forward and a backward Gauss-Seidel sweep from z = 0 (symmetric block
//     Gauss-Seidel, SSOR with refinement.gamma), or one Jacobi sweep (block Jacobi) with
//     SweepOrder::kJacobi. The sweeps exchange z; each robot keeps its neighbours' search
//     directions and increments from the z it received and the broadcast alpha and beta. Per
//     iteration two all-reduces (p.Hp, res.z: every robot reports its part, the coordinator
//     broadcasts alpha, beta and whether to stop); stops when sqrt(res.z / res0.z0) <=
//     refinement.cg_tolerance or at refinement.max_sweeps. Measured: blocks_world and
//     sphere2500 / torus3D in up to 64 robots reach the optimum in 5-8 steps of 15-400 sweeps;
//   - kSweeps: plain block Gauss-Seidel (Jacobi) sweeps on H delta = -g, SOR gamma; after each
//     sweep every robot reports (its change, ||delta_r||) and sweeping stops when the largest
//     change is at most refinement.sweep_tolerance times the largest ||delta_r||, or after
//     refinement.max_sweeps. Converges like stage 2 (per-sweep contraction near 1 on 49
//     robots): tens of thousands of sweeps without over-relaxation.
// After the linear solve every robot reports its share of F at x Exp(delta) (each separator
// counted once, by the lower robot id); the coordinator accepts the step when F does not rise,
// else halves it (x Exp(delta / 2): a broadcast and one more cost report, no new linear solve)
// and accepts the first that lowers F enough (DecideRefineStep), up to refinement.max_backtracks
// halvings; when none does it rejects the step, and the step is solved again with
// Levenberg-Marquardt damping lambda diag(H_rr) on each robot's own blocks (lambda:
// refinement.initial_lambda, then x10 per rejection; /10 after an accepted damped step, 0 below
// refinement.min_lambda). It stops when an accepted step lowers F by at most
// refinement.relative_cost_tolerance * F (converged; also when a rejected step raised F by no more
// than that: nothing left to gain), when F is at most refinement.absolute_cost_tolerance
// (converged), after refinement.max_iterations steps, or when lambda exceeds max_lambda
// (kNoDecreasingStep). A robot that stops answering during the refinement (SilentRobot with stage
// kRefine: at the start of that Gauss-Newton step) keeps its last accepted estimate; the others
// hold its variables fixed and count its separators.
//
// Faults (FaultInjection): a robot that stops answering stops at the start of a given sweep: it
// no longer solves, sends or receives; the others keep its last estimate, finish, and the result
// lists it (its variables keep the estimate it had). Messages can be duplicated, replayed stale
// (the previous sweep's messages re-delivered after the current ones) and shuffled within each
// delivery batch; the agents ignore duplicates and stale messages, so the estimate is unchanged.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "moslam/distributed/cg_decisions.h"
#include "moslam/distributed/dgs_types.h"
#include "moslam/distributed/messages.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

// How a refinement step's linear system is solved (see the top).
enum class RefineSolver {
  kSweeps,             // block Gauss-Seidel (or Jacobi) sweeps on H delta = -g, SOR gamma
  kConjugateGradient,  // conjugate gradients preconditioned by the same sweeps
};
std::string ToString(RefineSolver solver);

// The preconditioner of the refinement's conjugate gradients (see the top).
enum class RefinePreconditioner {
  kSweeps,    // a forward and a backward block Gauss-Seidel sweep (one Jacobi sweep)
  kTwoLevel,  // the same sweeps around a coarse correction over the robots' rigid motions
};
std::string ToString(RefinePreconditioner preconditioner);
// "sweeps" | "two-level"; throws InvalidInputError otherwise.
RefinePreconditioner RefinePreconditionerFromString(const std::string& text);

struct DgsOptions {
  double eta_rotation = 1e-2;  // stage 1 stops when every robot's change is <= this
  double eta_pose = 1e-2;      // stage 2 likewise
  // What eta bounds (dgs_types.h): the change (DGS.md) or the estimated distance to the fixed
  // point; the latter with ratios of changes over the last error_bound_window solves, in [1, 64].
  StageStopping stopping = StageStopping::kChange;
  int error_bound_window = 10;
  double gamma = 1.0;          // over-relaxation in (0, 2); 1: plain Gauss-Seidel / Jacobi
  SweepOrder order = SweepOrder::kGaussSeidel;
  int max_iterations = 1000;   // sweeps per stage
  bool flagged_initialisation = true;
  bool weight_by_information = false;  // unit weights as the DGS reference
  // How the pose stage is solved: the robot-by-robot sweeps of DGS.md (default), or conjugate
  // gradients on the same linear system (beyond DGS.md), preconditioned as the refinement's
  // (refinement.preconditioner: the sweeps, around a coarse correction when two-level, whose
  // basis is the robots' rotations and translations as a whole at the stage's starting point).
  // The start: with flagged initialisation, the stage's flagged sweeps until no robot is left to
  // initialise (one sweep in Gauss-Seidel order, as many as the robots' links are deep in
  // Jacobi order), so that every robot starts from its own solve with the neighbours that
  // solved before it; without, the first exchange's values (zero increments, the anchor's
  // translation). Starting from those instead of the flagged sweep, as before, pulled every robot
  // towards zero translations and left errors the iterations are slow to remove: ais2klinik in 4
  // robots ended the stage 2210x above the optimum at the 1000-sweep cap, 1.12x now (README,
  // "The 2D benchmark graphs"). The stage stops when every robot's change in an iteration is at
  // most eta_pose (the DGS measure) or after max_iterations sweeps, the flagged ones included. Same
  // fixed point (the centralized two-stage estimate), reached in far fewer sweeps where the sweeps
  // contract slowly (long chains split in pieces: sphere2500, torus3D). Every message and the
  // scalars of the two all-reduces per iteration are serialized and counted.
  enum class PoseSolver { kSweeps, kConjugateGradient };
  PoseSolver pose_solver = PoseSolver::kSweeps;
  // Two-level DGS (beyond DGS.md): after every sweep that does not stop the stage, a Galerkin
  // correction over the motions of whole robots (RobotAgent::coarseShare / applyCoarse): each
  // robot sends its rows of the coarse system (k x k blocks, k = 3 in stage 1, 6 in stage 2) to
  // the coordinator (the first live robot in the order), which solves it (Cholesky, k * robots
  // unknowns) and sends each robot the coarse unknowns of itself and its neighbours
  // (messages.h, CoarseMessage; counted in the sweep's messages and bytes). Same fixed point as
  // the one-level sweeps, and far fewer of them as the team grows (README: blocks_world eta 1e-2,
  // 13-22 sweeps for 2-49 robots against 22-225). Skipped, for that
  // sweep, while some live robot has not yet solved with all its separators (flagged
  // initialisation) or when the coarse matrix is not positive definite.
  bool coarse_correction = false;

  bool refine = false;  // RunDgs: run the refinement after the two stages
  struct Refinement {
    RefineSolver solver = RefineSolver::kConjugateGradient;
    RefinePreconditioner preconditioner = RefinePreconditioner::kTwoLevel;
    int max_iterations = 100;                // Gauss-Newton steps (accepted or rejected)
    double relative_cost_tolerance = 1e-10;  // converged when a step gains <= this * F
    // Converged when F is at most this (a graph its measurements fit exactly, such as a tree:
    // F falls to rounding, where the relative rule cannot end; the centralized optimizer's).
    double absolute_cost_tolerance = 1e-20;
    int max_sweeps = 1000;                   // per step
    double sweep_tolerance = 1e-3;           // kSweeps: max change <= this * max ||delta_r||
    double cg_tolerance = 1e-2;              // kConjugateGradient: sqrt(res.z / res0.z0)
    double gamma = 1.0;                      // over-relaxation of the sweeps, in (0, 2)
    double initial_lambda = 1e-4;            // damping after the first rejected step
    double max_lambda = 1e10;
    // An accepted damped step divides lambda by 10; below this the damping stops (0). Stopping
    // it at once below initial_lambda (as before) let the refinement cycle on long 2D chains:
    // the undamped step rejected, the damped one accepted, the undamped one rejected again, each
    // accepted step gaining little (MIT split among 4 robots with these options' defaults: 9 %
    // above the optimum after 100 steps, 50 of them rejected; INTEL with `moslam dgs --refine`'s
    // two-level pipeline: 0.4 %; with 1e-10 both reach it: README, "Long 2D chains").
    double min_lambda = 1e-10;
    // A step that raises F is halved up to this many times (down to 1/16 of it by default)
    // before it is rejected: the Gauss-Newton direction is usually right where its length
    // overshoots, and each halving costs one broadcast and one cost report against a damped
    // solve's many sweeps. On INTEL split in 2, 4 and 16 robots the refinement reaches the
    // optimum in 11-12 steps, where without halving (0) it ended 5-8e-6 above it after 84-100
    // steps, 35-47 of them rejected (README, "Long 2D chains"). 0 turns halving off.
    int max_backtracks = 4;
    // The coarse space of the two-level preconditioner in refinement steps: 0, one rigid motion
    // per robot; L > 0, one per piece of L consecutive pose indices of a robot (its objects one
    // more piece; coarse_correction.h, CoarsePieceOf), so that a run of a long chain can turn
    // against the rest, which one motion per robot leaves to the sweeps (README, "The
    // refinement's coarse space by pieces"). Needs preconditioner kTwoLevel and the
    // conjugate-gradient solver; the pose stage's conjugate gradients keep one motion per robot.
    std::uint64_t coarse_piece_poses = 0;
  } refinement;

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct SilentRobot {
  int robot = 0;
  DgsStage stage = DgsStage::kRotation;
  // Stops answering at the start of this sweep (1-based) of `stage`; for kRefine, at the start of
  // this Gauss-Newton step (1-based).
  int iteration = 1;
};

struct FaultInjection {
  std::vector<SilentRobot> silent;
  bool duplicate = false;     // deliver every message twice
  bool replay_stale = false;  // re-deliver the previous sweep's messages after the current ones
  bool shuffle = false;       // deliver each batch in a random order
  std::uint32_t seed = 1;     // for shuffle
};

enum class StageStatus { kNotRun, kConverged, kMaxIterations, kNoDecreasingStep };
std::string ToString(StageStatus status);

struct DgsIterationStats {
  DgsStage stage = DgsStage::kRotation;
  int iteration = 0;          // 0: the initial exchange (no flagged initialisation); refinement:
                              // sweeps counted over the whole stage
  std::int64_t messages = 0;  // serialized messages sent during this sweep (control included)
  std::int64_t bytes = 0;
  std::int64_t control_messages = 0;  // refinement: the control messages among them (the sweep's
  std::int64_t control_bytes = 0;     // reports and decision; a step's cost reports and step
                                      // decision count in the step's last sweep)
  std::int64_t coarse_messages = 0;   // two-level: the coarse messages among them (rows to the
  std::int64_t coarse_bytes = 0;      // coordinator, solutions back)
  double max_change = 0.0;    // over the live robots (+inf while one has not solved yet)
  double max_increment = 0.0; // refinement by sweeps: the largest ||delta_r||
  double residual = 0.0;      // refinement by conjugate gradients: sqrt(res.z / res0.z0) after
                              // the iteration this sweep ends (0 otherwise)
  int robots_solved = 0;
  int refine_step = 0;        // refinement: the Gauss-Newton step (1-based)
  double seconds = 0.0;
};

struct DgsStageReport {
  StageStatus status = StageStatus::kNotRun;
  int iterations = 0;  // sweeps
  std::int64_t messages = 0;
  std::int64_t bytes = 0;
  double final_change = 0.0;       // the largest change of the last sweep
  double final_error_bound = 0.0;  // the largest errorBound(window) of the last sweep
  int coarse_corrections = 0;      // two-level DGS: corrections applied
};

// One Gauss-Newton step of the refinement.
struct RefineStepSummary {
  int iteration = 0;             // 1-based
  int sweeps = 0;
  bool linear_converged = false; // the sweep / CG tolerance was met (else max_sweeps)
  double lambda = 0.0;           // damping used
  double cost_before = 0.0;      // F at the current estimate (the robots' shares summed)
  double cost_candidate = 0.0;   // F at x Exp(delta)
  // kConjugateGradient: the decrease of the damped Gauss-Newton model that delta achieves
  // (cg_decisions.h), so (cost_before - cost_candidate) / predicted_decrease is the step's gain
  // ratio when it was not halved: near 1 where F is as quadratic as the model over the step. 0
  // with kSweeps.
  double predicted_decrease = 0.0;
  // Halvings of the step before the decision (max_backtracks): the step taken or rejected is
  // step_scale = 2^-backtracks times the linear solve's, and cost_candidate is F there.
  int backtracks = 0;
  double step_scale = 1.0;
  bool accepted = false;
  double seconds = 0.0;
  std::int64_t bytes = 0;  // everything the refinement sent up to the end of this step
};

struct RefineReport {
  StageStatus status = StageStatus::kNotRun;
  int iterations = 0;  // Gauss-Newton steps (accepted or rejected)
  int rejected = 0;
  int backtracks = 0;  // halvings of steps that raised F, over all steps
  int sweeps = 0;      // over all steps
  std::int64_t messages = 0;  // everything the refinement sent, control included
  std::int64_t bytes = 0;
  std::int64_t control_messages = 0;
  std::int64_t control_bytes = 0;
  std::int64_t coarse_messages = 0;  // two-level preconditioner
  std::int64_t coarse_bytes = 0;
  double initial_cost = 0.0;  // F at the two-stage estimate, as the robots' shares sum it
  double final_cost = 0.0;
  int coordinator = 0;
  int coarse_corrections = 0;  // two-level preconditioner: coarse corrections applied
  std::vector<RefineStepSummary> steps;
  double seconds = 0.0;
};

// The Gauss-Newton step decision of the refinement (see the top), taken on a step's summary:
// F at the current estimate (cost_before) and at x Exp(step_scale delta) (cost_candidate), the
// step's predicted decrease and its halvings so far (backtracks). A whole step is accepted when F
// does not rise; a halved one when F falls by at least kArmijoFraction * step_scale *
// predicted_decrease (with kSweeps, whose prediction is 0: when F does not rise). Else the step is
// halved again (backtrack; counted in report.backtracks, nothing else changed) while backtracks
// < max_backtracks, else rejected. Finished when a whole step's gain (or rise) is within
// relative_cost_tolerance * F, when F is at most absolute_cost_tolerance, when lambda passes
// max_lambda (report.status kNoDecreasingStep) or at max_iterations (never while halving).
// Updates `lambda`, counts a rejection in report.rejected and sets report.status kConverged when
// finished so. The in-process driver and every robot of a network team (robot_program.h) decide
// with it.
inline constexpr double kArmijoFraction = 1e-4;
struct RefineDecision {
  bool accept = false;
  bool backtrack = false;
  bool finished = false;
};
RefineDecision DecideRefineStep(const RefineStepSummary& step,
                                const DgsOptions::Refinement& options, double& lambda,
                                RefineReport& report);

struct SilentRobotReport {
  int robot = 0;
  DgsStage stage = DgsStage::kRotation;
  int iteration = 0;  // the sweep at whose start it stopped answering (0: before the stage)
};

struct DgsResult {
  Values values;  // every variable: the live robots' final estimates, the silent robots' last
  DgsStageReport rotation, pose;
  RefineReport refine;
  std::vector<DgsIterationStats> history;
  std::int64_t messages = 0;
  std::int64_t bytes = 0;
  std::vector<int> order;                   // the robot order used
  std::vector<SilentRobotReport> silent;    // robots that stopped answering
  std::int64_t duplicates_ignored = 0;      // summed over agents
  std::int64_t stale_ignored = 0;
  double seconds = 0.0;
};

class RobotAgent;
class CoarseSystem;
class PieceCoarseSystem;

// Called after every sweep (all stages) and after every refinement step, e.g. to print progress.
struct DgsProgress {
  std::function<void(const DgsIterationStats&)> on_sweep;
  std::function<void(const RefineStepSummary&)> on_refine_step;
};

// The driver as a class, so the stages can be run one by one on the same agents: construct,
// runRotationStage(), runPoseStage(), optionally runRefineStage(), result().
class DgsDriver {
 public:
  // Partitions `graph` by the robot in each key and builds one agent per robot owning
  // variables. Variables missing from `initial` start at the identity (the anchor included).
  // Throws InvalidInputError (bad options, a silent robot that does not exist),
  // UnderdeterminedError (robot 0 has no pose, part of the graph not connected to the anchor).
  DgsDriver(const PoseGraph& graph, const Values& initial, const DgsOptions& options = {},
            const FaultInjection& faults = {});
  ~DgsDriver();
  DgsDriver(const DgsDriver&) = delete;
  DgsDriver& operator=(const DgsDriver&) = delete;

  const DgsStageReport& runRotationStage();  // must be first
  const DgsStageReport& runPoseStage();      // after runRotationStage(); finishes the agents
  const RefineReport& runRefineStage();      // after runPoseStage(), once
  void setProgress(DgsProgress progress) { progress_ = std::move(progress); }
  // The result so far (values: every agent's current estimate).
  DgsResult result() const;

  const std::vector<int>& order() const { return order_; }
  int numAgents() const { return static_cast<int>(agents_.size()); }
  // The agent of `robot` (InvalidInputError when no agent owns variables of that robot).
  RobotAgent& agent(int robot);

 private:
  struct Wire {
    int from = 0;
    int to = 0;
    std::vector<std::uint8_t> bytes;
  };
  void runStage(DgsStage stage, DgsStageReport& report);
  // A stage's start: the live agents start it; every robot's estimates sent (sweep 0, when the
  // robots start knowing their neighbours' initial estimates); the stop rule over the live agents
  // after a sweep; a sweep's traffic and history recorded.
  void startStage(DgsStage stage);
  DgsIterationStats sendInitialEstimates(DgsStage stage);
  StageStopRule stopRule(double eta) const;
  void recordSweep(const DgsIterationStats& stats, DgsStageReport& report);
  void updateSilence(DgsStage stage, int iteration);
  void transmit(std::vector<Wire> batch, DgsIterationStats& stats);
  // Encodes, counts and decodes one control message (the bytes a network would carry).
  ControlMessage sendControl(const ControlMessage& m, int to, DgsIterationStats& stats);
  // One sweep: every live robot in the robot order (reversed: backward) solves once.
  void runSweeps(DgsStage stage, DgsIterationStats& stats, bool reverse);
  // The coarse correction of the two-level DGS; false (nothing changed) when some live robot is
  // not coarseReady() yet or the coarse matrix is not positive definite.
  bool coarseCorrection(DgsStage stage, int iteration, DgsIterationStats& stats);
  // Encodes, counts (unless to the sender itself) and decodes one coarse message.
  CoarseMessage sendCoarse(const CoarseMessage& m, int to, DgsIterationStats& stats);
  // The refinement's two-level preconditioner: the step's coarse system at the coordinator (null
  // when some live robot cannot take part or the matrix is not positive definite), and one coarse
  // correction of the robots' z with it.
  std::unique_ptr<CoarseSystem> refineCoarseSystem(DgsStage stage, DgsIterationStats& stats,
                                                   std::uint32_t sweep);
  // The live robots in id order when every one can take part in the step's coarse correction;
  // else none.
  std::vector<int> refineCoarseRobots() const;
  std::unique_ptr<PieceCoarseSystem> refinePieceSystem(DgsIterationStats& stats,
                                                       std::uint32_t sweep);
  void refinePieceCorrection(const PieceCoarseSystem& coarse, DgsIterationStats& stats,
                             std::uint32_t sweep);
  void refineCoarseCorrection(DgsStage stage, const CoarseSystem& coarse,
                              DgsIterationStats& stats, std::uint32_t sweep);
  // The bookkeeping of a stage solved by conjugate gradients or refined: the sweep being
  // recorded, traffic waiting for the next one.
  struct RefineRun {
    DgsStage stage = DgsStage::kRefine;
    int step = 0;
    bool open = false;
    DgsIterationStats current, pending;
    std::chrono::steady_clock::time_point sweep_start;
    std::set<int> told_silent;  // robots whose silence the live agents were told about
  };
  // The refinement: tells the live agents of robots newly silent (true if any); the team's cost
  // (at the step's candidate or not); one Gauss-Newton step of the team, true when it finishes
  // the refinement (cost, lambda: the accepted cost and the damping, updated).
  bool tellSilence(RefineRun& run);
  double refineCost(RefineRun& run, bool candidate);
  bool refineStep(RefineRun& run, double& cost, double& lambda);
  int coordinator() const;  // the first live robot of the order, -1 if none
  void openSweep(RefineRun& run);
  void closeSweep(RefineRun& run);
  DgsIterationStats& traffic(RefineRun& run);
  enum class Reduce { kSum, kMax };
  // Every live robot reports share() (and second(), if given) to the coordinator; returns their
  // sum or maximum (summed in robot id order: independent of the order of arrival), and the
  // maximum of the second values in max_second.
  double gather(RefineRun& run, ControlKind kind, std::uint32_t sweep,
                const std::function<double(RobotAgent&)>& share, Reduce reduce,
                double* max_second = nullptr,
                const std::function<double(RobotAgent&)>& second = {});
  void broadcast(RefineRun& run, std::uint32_t sweep, bool stop, double coefficient);
  double observedChange() const;
  void solveBySweeps(RefineRun& run, RefineStepSummary& summary);
  CgOutcome solveByConjugateGradients(RefineRun& run, const CgGoal& goal);
  // The pose stage by conjugate gradients (DgsOptions::pose_solver), after `sweeps_before`
  // flagged sweeps of the stage's max_iterations.
  void runPoseByConjugateGradients(DgsStageReport& report, int sweeps_before);
  std::vector<Wire> encodeOutgoing(int robot) const;
  bool live(int robot) const;

  DgsOptions options_;
  FaultInjection faults_;
  std::map<int, std::unique_ptr<RobotAgent>> agents_;
  std::vector<int> order_;
  std::map<int, SilentRobotReport> silent_;
  std::map<int, std::vector<Wire>> previous_;  // per sender: its previous sweep's messages
  std::uint64_t rng_state_ = 1;
  DgsResult result_;
  DgsProgress progress_;
};

// Partitions `graph` by the robot in each key and runs both stages (and the refinement when
// options.refine). Variables missing from
// `initial` start at the identity (the anchor included). Throws InvalidInputError (bad options,
// a silent robot that does not exist), UnderdeterminedError (robot 0 has no pose, a part of the
// graph is not connected to the anchor).
DgsResult RunDgs(const PoseGraph& graph, const Values& initial, const DgsOptions& options = {},
                 const FaultInjection& faults = {});

// The robot order described above, from links[i] = {robot j: number of neighbour variables of
// robot i owned by j} for the robots `robots` (ascending; robot 0 first if present).
std::vector<int> FlaggedRobotOrder(const std::vector<int>& robots,
                                   const std::vector<std::map<int, int>>& links);

}  // namespace moslam
