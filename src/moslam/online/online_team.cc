#include "moslam/online/online_team.h"

#include <algorithm>
#include <chrono>
#include <iterator>
#include <set>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

DgsOptions OnlineOptions::DefaultSolver() {
  DgsOptions o;
  o.order = SweepOrder::kJacobi;
  o.coarse_correction = true;
  o.stopping = StageStopping::kErrorBound;
  o.refine = true;
  o.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;  // as the CLI's --refine
  return o;
}

void OnlineOptions::validate() const {
  solver.validate();
  ValidateInformation(lambda, "OnlineOptions: lambda");
}

OnlineTeam::OnlineTeam(OnlineOptions options) : options_(std::move(options)) {
  options_.validate();
}

void OnlineTeam::onRendezvous(const RendezvousGroup& group, MultiRobotSlamResult& team) {
  const auto robot = [&](int r) -> ObjectSlam& {
    if (r < 0 || r >= static_cast<int>(team.robots.size())) {
      throw InvalidInputError("OnlineTeam: the group names robot " + std::to_string(r) +
                              ", which the team does not have");
    }
    return team.robots[static_cast<std::size_t>(r)];
  };
  std::vector<int> present;  // the robots that left take part in no solve
  std::set_difference(group.robots.begin(), group.robots.end(), group.gone.begin(),
                      group.gone.end(), std::back_inserter(present));
  present.erase(std::remove_if(present.begin(), present.end(),
                               [&](int r) {
                                 const auto it = options_.dies_in_solve.find(r);
                                 return it != options_.dies_in_solve.end() &&
                                        it->second == group.step;
                               }),
                present.end());
  for (const std::vector<int>& part : LinkedGroups(present, team.shared)) {
    if (part.size() < 2) continue;  // nothing shared with the others yet
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<const ObjectSlam*> members;
    for (int r : part) members.push_back(&robot(r));
    const GroupProblem problem = BuildGroupProblem(members, team.shared, held_, options_.lambda);
    const DgsResult solved = RunDgs(problem.graph, problem.initial, options_.solver);
    GroupSolveRecord rec;
    rec.step = group.step;
    rec.robots = part;
    rec.object_object = problem.object_object;
    rec.team_factors = problem.team_factors;
    rec.borrowed = problem.borrowed;
    rec.rotation_sweeps = solved.rotation.iterations;
    rec.pose_sweeps = solved.pose.iterations;
    rec.refine_steps = solved.refine.iterations;
    rec.refine_status = solved.refine.status;
    rec.initial_cost = problem.graph.cost(problem.initial);
    rec.final_cost = problem.graph.cost(solved.values);
    rec.messages = solved.messages;
    rec.bytes = solved.bytes;
    for (GroupUpdate& u : SplitGroupSolution(problem, solved.values, team.shared, group.step)) {
      HeldEstimates& h = held_[u.robot];
      for (auto& [k, x] : u.held) h[k] = x;
      ObjectSlam& r = robot(u.robot);
      r.setEstimate(u.estimate);
      r.setTeamFactors(TeamFactors(u.robot, team.shared, h, options_.lambda));
    }
    rec.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    solves_.push_back(std::move(rec));
  }
}

MultiRobotSlamConfig::OnRendezvous OnlineTeam::hook(
    std::function<void(const RendezvousGroup&, const MultiRobotSlamResult&)> after) {
  return [this, after = std::move(after)](const RendezvousGroup& group,
                                          MultiRobotSlamResult& team) {
    onRendezvous(group, team);
    if (after) after(group, team);
  };
}

OnlineRun RunOnline(const SimulationData& data, MultiRobotSlamConfig slam, OnlineOptions options) {
  OnlineRun run;
  OnlineTeam team(std::move(options));
  std::size_t seen = 0;
  slam.on_rendezvous = team.hook([&](const RendezvousGroup& g, const MultiRobotSlamResult& r) {
    for (; seen < team.solves().size(); ++seen) {
      for (int robot : team.solves()[seen].robots) {
        run.maps[{g.step, robot}] = r.robots[static_cast<std::size_t>(robot)].estimate();
      }
    }
  });
  run.slam = RunMultiRobotObjectSlam(data, slam);
  run.solves = team.solves();
  return run;
}

}  // namespace moslam
