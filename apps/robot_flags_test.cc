// The flags `moslam team` hands each robot process (SolveArgs, ScenarioArgs) against the parser
// of `moslam robot` (AddSolveFlags, AddScenarioFlags): every flag the parser knows is forwarded,
// and the forwarded command line parses back to itself. A flag added to the parser and not to the
// forwarding would let the robots run with its default while the team's reference uses the value.
#include "robot_flags.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <vector>

namespace moslam::cli {
namespace {

std::vector<std::string> Forwarded(const SolveFlags& f, const ScenarioFlags& s) {
  std::vector<std::string> a = SolveArgs(f);
  for (const std::string& x : ScenarioArgs(s)) a.push_back(x);
  return a;
}

// Parses `args` (flags only) with robot's parser into fresh flags; their forwarded line.
std::vector<std::string> Reparsed(const std::vector<std::string>& args) {
  CLI::App app;
  SolveFlags f;
  ScenarioFlags s;
  AddSolveFlags(&app, f);
  AddScenarioFlags(&app, s, true);
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them reversed
  app.parse(reversed);
  return Forwarded(f, s);
}

TEST(RobotFlags, EveryFlagOfTheRobotsParserIsForwardedAndReadsBack) {
  SolveFlags f;
  f.robust = true;
  f.leave_timeout = 7.5;
  f.solver.no_flagged = true;
  f.solver.weighted = true;
  f.solver.refine = true;
  f.solver.refine_linear_tolerance = 0.125;
  f.solver.stages = "two-level";
  f.robust_args.retest_left_out = false;
  f.robust_args.retest_groups = false;
  f.robust_args.one_to_one_after_gnc = true;
  f.robust_args.gnc_threshold = 9.5;
  f.robust_loop_closures = true;  // g2o data only; forwarded alike
  ScenarioFlags s;
  s.name = "house";
  s.spec.robots = 3;
  s.spec.leave_one_out_check = true;
  s.spec.ambiguity_ratio = 0.625;
  s.spec.covariance_gate = 22.46;
  s.spec.loop_closure = true;
  s.spec.rendezvous_constellation = true;
  s.initial_poses = "unknown";
  const std::vector<std::string> forwarded = Forwarded(f, s);

  CLI::App app;
  SolveFlags parsed_solve;
  ScenarioFlags parsed_scenario;
  AddSolveFlags(&app, parsed_solve);
  AddScenarioFlags(&app, parsed_scenario, true);
  // Aliases of a forwarded flag, and help.
  const std::set<std::string> not_forwarded = {"--help", "--coarse"};
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& name : option->get_lnames()) {
      const std::string flag = "--" + name;
      if (not_forwarded.count(flag)) continue;
      EXPECT_NE(std::find(forwarded.begin(), forwarded.end(), flag), forwarded.end())
          << flag << " is not forwarded to the robot processes";
    }
  }
  EXPECT_EQ(Reparsed(forwarded), forwarded);
}

// The loop closures robust: g2o data only, and only with --robust (a scenario's robust factors
// are its object factors).
TEST(RobotFlags, RobustLoopClosuresNeedRobustAndRefuseAScenario) {
  const auto parse = [](std::vector<std::string> args) {
    CLI::App app;
    SolveFlags f;
    ScenarioFlags s;
    AddScenarioFlags(&app, s, true);
    AddSolveFlags(&app, f);
    std::reverse(args.begin(), args.end());
    app.parse(args);
    return f.robust_loop_closures;
  };
  EXPECT_TRUE(parse({"--robust", "--robust-loop-closures"}));
  EXPECT_FALSE(parse({"--robust"}));
  EXPECT_THROW(parse({"--robust-loop-closures"}), CLI::RequiresError);
  EXPECT_THROW(parse({"--scenario", "house", "--robust", "--robust-loop-closures"}),
               CLI::ExcludesError);
}

}  // namespace
}  // namespace moslam::cli
