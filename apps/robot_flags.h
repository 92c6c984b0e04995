// The flags `moslam robot` and `moslam team` share, and what they become: the solver flags as a
// robot process's DgsNodeOptions (and the in-process reference's RobustDgsOptions), the simulated
// scenario as a ScenarioSpec, and both as the command line `moslam team` hands each robot.
#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "moslam/distributed/robust_dgs.h"
#include "moslam/io/g2o.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/robot_session.h"
#include "robust_flags.h"
#include "solver_flags.h"

namespace moslam::cli {

struct SolveFlags {
  SolverArgs solver;  // the same solver flags as `moslam dgs` (the robots solve in Jacobi order)
  double leave_timeout = 15.0;  // seconds
  double join_timeout = 60.0;
  double stall_timeout = 300.0;
  bool robust = false;
  RobustSolveArgs robust_args;  // --separator-test, --gnc-threshold, --separator-support
  // --robust-loop-closures (g2o data): the robust factors are the loop closures (gnc.h,
  // LoopClosureFactors), not the separators.
  bool robust_loop_closures = false;
};

// After AddScenarioFlags: --robust-loop-closures excludes --scenario.
void AddSolveFlags(CLI::App* sub, SolveFlags& f);
std::chrono::milliseconds Ms(double seconds);
DgsNodeOptions NodeOptions(const SolveFlags& f);
// The in-process reference of a robust team: RunRobustDgs with the processes' solver, GNC
// options and separator check.
RobustDgsOptions ReferenceRobustOptions(const DgsNodeOptions& o);
// The flags again, for a robot process's command line.
std::vector<std::string> SolveArgs(const SolveFlags& f);
// --online: the whole solver at every rendezvous (two-level, error-bound rule, refinement), as
// `moslam simulate --online` (OnlineOptions::DefaultSolver); the other solver flags still apply.
SolveFlags OnlineSolveFlags(SolveFlags f);

// The simulated scenario of `moslam robot --scenario` and `moslam team --scenario`.
struct ScenarioFlags {
  std::string name;  // --scenario; empty: not a scenario run
  ScenarioSpec spec;
  double rendezvous_timeout = 60.0;  // seconds
  std::string initial_poses = "known";
  ScenarioSpec get() const {
    ScenarioSpec s = spec;
    s.scenario = name;
    s.known_initial_poses = initial_poses == "known";
    return s;
  }
};

// `with_robots`: also --robots (moslam team has its own). Every flag but --scenario needs it:
// given with --data (a g2o folder has none of them) it is an error, not ignored.
void AddScenarioFlags(CLI::App* sub, ScenarioFlags& f, bool with_robots);
// Refuses what the online mission does not run, and a refinement of initial poses the robots do
// not know (`who`: robot or team).
void CheckScenarioFlags(const char* who, bool online, const ScenarioSpec& spec);
// The flags again, for a robot process's command line.
std::vector<std::string> ScenarioArgs(const ScenarioFlags& f);
// g2o reading with object keys (the scenario's maps).
G2oReadOptions WithObjects();
// What the JSON summaries of a scenario run say of it: scenario, seed, initial poses and the
// robots' association options.
nlohmann::json ScenarioJson(const ScenarioSpec& spec);

}  // namespace moslam::cli
