// One robot's side of the whole distributed solver as a program: the two DGS stages with either
// stopping rule, the two-level correction, the pose stage by conjugate gradients and the
// refinement (dgs_driver.h, in Jacobi order), written against a TeamChannel that knows nothing
// of the solver. Every robot of the team runs the same program; a channel step is the only
// place it talks to the others:
//
//   step(stage, estimates, report, share, weights, covariances):  sends `estimates` (and
//   `weights`, the robust solve's factor weights, and `covariances`, its separator check's map
//   covariances: robust_program.h) to the neighbours, `report` (and the coarse `share`, if any)
//   to every robot, and returns once it holds the report of every live robot for this step, the
//   estimates of every neighbour whose report says it sent some, the share of every robot whose
//   report says it has one, and the weights (covariances) of every neighbour whose report says
//   weights (covariance): a robot that sends weights (covariances) sends one to each of its
//   neighbours.
//
// There is no coordinator: every global quantity is computed by every robot from the same reports
// in robot id order (the sums of the conjugate gradients and of the cost, the stopping rules, the
// Gauss-Newton step decision), and every robot assembles and solves the small coarse system
// (coarse_system.h) from the shares of all, keeping only its own and its neighbours' unknowns.
// So all robots take the same decisions on the same numbers, none is a single point of failure,
// and nothing has to be taken over when a robot leaves; the price is that every robot receives
// every coarse share (k x k blocks, robots x neighbours of them per correction).
//
// The program performs the agent calls of DgsDriver with SweepOrder::kJacobi in the same order on
// the same numbers (sums in robot id order, the coarse system over the robots in id order), so a
// team of programs reproduces the in-process driver's result; dgs_node.h runs it over a network
// transport with a journal, in-process tests compare the two.
//
// Robots that leave: the channel drops them from the reports (absent()); the program then treats
// them as the driver treats silent robots: their variables stay at their last estimates, the
// coarse readiness ignores their separators and, in the refinement, from the next Gauss-Newton
// step the others count their separators (RobotAgent::setUnresponsive).
#pragma once

#include <limits>
#include <map>
#include <set>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/robot_agent.h"

namespace moslam {

// What a robot tells every robot at a channel step.
struct TeamReport {
  bool sent = false;          // it sent estimates to its neighbours in this step
  bool initialised = false;   // it has solved in the stage (flagged initialisation)
  bool coarse_ready = false;  // it can take part in a coarse correction now
  bool has_share = false;     // a coarse share comes with this report
  double change = std::numeric_limits<double>::infinity();  // lastChange(), +inf before a solve
  double bound = std::numeric_limits<double>::infinity();   // errorBound(window)
  double value[2] = {0.0, 0.0};  // the step's inputs to the team-wide sums and maxima
  bool weights = false;       // a WeightMessage to every neighbour comes with this step
  bool covariance = false;    // a CovarianceMessage to every neighbour comes with this step
};

struct TeamStep {
  std::vector<Message> estimates;          // from neighbours, sender order
  std::map<int, TeamReport> reports;       // every live robot's, this one included
  std::map<int, CoarseMessage> shares;     // the coarse shares that came with them
  std::map<int, WeightMessage> weights;    // from neighbours whose report says weights, to it
  std::map<int, CovarianceMessage> covariances;  // from neighbours whose report says covariance
};

// The team's sum (in robot id order, as DgsDriver::gather) and maximum (0 when every value is
// below) of report.value[i] over the step's reports: what every robot computes alike.
double TeamSum(const TeamStep& step, int i);
double TeamMax(const TeamStep& step, int i);
// Every live robot's report.value[i] in the step, by robot id.
std::map<int, double> TeamValues(const TeamStep& step, int i);

class TeamChannel {
 public:
  virtual ~TeamChannel() = default;
  // See the top. `share`: null or this robot's coarse share (report.has_share must say so).
  // Throws moslam::Error when the team makes no progress (the channel's timeouts).
  // `weights`: one per neighbour when report.weights, else none; `covariances` alike with
  // report.covariance.
  virtual TeamStep step(DgsStage stage, const std::vector<OutgoingMessage>& estimates,
                        const TeamReport& report, const CoarseMessage* share,
                        const std::vector<WeightMessage>& weights,
                        const std::vector<CovarianceMessage>& covariances) = 0;
  // Robots of the team that left (no longer in the reports).
  virtual std::set<int> absent() const = 0;
};

// What one robot's program measured: as DgsResult's reports, seen by this robot (the team-wide
// decisions are the same on every robot).
struct RobotProgramResult {
  DgsStageReport rotation, pose;
  RefineReport refine;  // steps, costs, sweeps, coarse corrections; no traffic (the channel's)
  int channel_steps = 0;
};

// Runs the whole solve on `agent` (in kIdle): the rotation and pose stages, then the refinement
// when options.refine. options.order must be SweepOrder::kJacobi (InvalidInputError otherwise).
// Leaves the agent in kDone.
RobotProgramResult RunRobotProgram(RobotAgent& agent, const DgsOptions& options,
                                   TeamChannel& channel);

}  // namespace moslam
