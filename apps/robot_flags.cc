#include "robot_flags.h"

#include <fmt/core.h>

#include "cli.h"
#include "commands.h"
#include "moslam/common/errors.h"

namespace moslam::cli {

void AddSolveFlags(CLI::App* sub, SolveFlags& f) {
  AddSolverFlags(sub, &f.solver);
  sub->add_flag("--robust", f.robust,
                "GNC-TLS around the solver, run by the robots (weights on the wire), after the "
                "pairwise check of the separators (map covariances on the wire), as `moslam dgs "
                "--robust`: the separators robust (the loop closures with --robust-loop-closures), "
                "and with --scenario the object measurements too (the refinement is forced on); "
                "with --online at every group solve, as "
                "`moslam simulate --online --robust` (pairs rejected set aside until their robots "
                "meet again)");
  AddRobustSolveFlags(sub, &f.robust_args);
  CLI::Option* loops =
      sub->add_flag("--robust-loop-closures", f.robust_loop_closures,
                    "With --robust on g2o data: the robust factors are the loop closures (every "
                    "factor but those between poses of consecutive indices, whatever their "
                    "robots), not the separators, and each robot checks its own through its "
                    "odometry: a single robot's file split among robots, as `moslam dgs <file> "
                    "--robots N --robust` (`moslam team` with a single file implies it)")
          ->needs(sub->get_option("--robust"));
  if (CLI::Option* scenario = sub->get_option_no_throw("--scenario")) loops->excludes(scenario);
  sub->add_option("--leave-timeout", f.leave_timeout,
                  "Seconds a waited-for robot may be unreachable before it counts as gone (one "
                  "never heard from too: start every robot within this of its first rendezvous)")
      ->check(Positive());
  sub->add_option("--join-timeout", f.join_timeout, "Seconds to wait for the team to form")
      ->check(Positive());
  sub->add_option("--stall-timeout", f.stall_timeout, "Seconds without progress before failing")
      ->check(Positive());
}

std::chrono::milliseconds Ms(double seconds) {
  return std::chrono::milliseconds(static_cast<std::int64_t>(seconds * 1000.0));
}

DgsNodeOptions NodeOptions(const SolveFlags& f) {
  DgsNodeOptions o;
  o.solver = f.solver.options(SweepOrder::kJacobi);
  o.leave_timeout = Ms(f.leave_timeout);
  o.join_timeout = Ms(f.join_timeout);
  o.stall_timeout = Ms(f.stall_timeout);
  o.finish_timeout = Ms(std::max(10.0, f.leave_timeout + 5.0));
  if (f.robust) {
    RobustDgsOptions r;
    f.robust_args.applyTo(&r);
    o.gnc = r.gnc;
    if (r.check_separators) o.separator_check = r.consistency;
    o.retest_left_out = r.retest_left_out;
    o.retest_groups = r.retest_groups;
    o.one_to_one_after_gnc = r.one_to_one_after_gnc;
    o.solver.refine = true;
  }
  return o;
}

RobustDgsOptions ReferenceRobustOptions(const DgsNodeOptions& o) {
  RobustDgsOptions r;
  r.dgs = DriverOptions(o);
  r.gnc = *o.gnc;
  r.check_separators = o.separator_check.has_value();
  if (o.separator_check) r.consistency = *o.separator_check;
  r.retest_left_out = o.retest_left_out;
  r.retest_groups = o.retest_groups;
  r.one_to_one_after_gnc = o.one_to_one_after_gnc;
  return r;
}

std::vector<std::string> SolveArgs(const SolveFlags& f) {
  std::vector<std::string> a = f.solver.args();
  for (const std::string& s :
       {std::string("--leave-timeout"), fmt::format("{}", f.leave_timeout),
        std::string("--join-timeout"), fmt::format("{}", f.join_timeout),
        std::string("--stall-timeout"), fmt::format("{}", f.stall_timeout)}) {
    a.push_back(s);
  }
  if (f.robust) {
    a.push_back("--robust");
    for (const std::string& s : f.robust_args.args()) a.push_back(s);
    if (f.robust_loop_closures) a.push_back("--robust-loop-closures");
  }
  return a;
}

SolveFlags OnlineSolveFlags(SolveFlags f) {
  f.solver.refine = true;
  f.solver.stopping = "error-bound";
  return f;
}

void AddScenarioFlags(CLI::App* sub, ScenarioFlags& f, bool with_robots) {
  const std::size_t before = sub->get_options().size();
  CLI::Option* scenario = sub->add_option("--scenario", f.name,
                  "Simulated scenario (chairs25 | house | generated): every process simulates it "
                  "and keeps its own robot's measurements")
      ->check(CLI::IsMember({"chairs25", "house", "generated"}));
  if (with_robots) {
    sub->add_option("--robots", f.spec.robots, "Robots of the scenario")->check(Positive());
  }
  sub->add_option("--seed", f.spec.seed, "Seed of the world, trajectories and noise");
  sub->add_option("--sigma-rot", f.spec.sigma_rotation_deg, "Noise: rotation sigma (deg)")
      ->check(NonNegative());
  sub->add_option("--sigma-trans", f.spec.sigma_translation, "Noise: translation sigma (m)")
      ->check(NonNegative());
  sub->add_option("--poses", f.spec.poses_per_robot, "Poses per robot")->check(CLI::Range(2, 100000));
  sub->add_option("--rendezvous-timeout", f.rendezvous_timeout,
                  "Seconds to wait for the peer of a rendezvous")
      ->check(Positive());
  sub->add_option("--initial-poses", f.initial_poses,
                  "known: the robots know one another's initial poses (the paper); unknown: a "
                  "rendezvous aligns the two object maps from the objects alone, and no process "
                  "is given the initial poses")
      ->check(CLI::IsMember({"known", "unknown"}));
  sub->add_option("--exclusion-radius", f.spec.exclusion_radius,
                  "A robot's landmark exclusion radius (m, 0: off): a detection that joins no "
                  "landmark but lies this close to one of its label is discarded (as simulate)")
      ->check(NonNegative());
  sub->add_flag("--leave-one-out-check", f.spec.leave_one_out_check,
                "A robot re-tests each match of a pose at the pose localised on its other "
                "matches, and refuses the ones that disagree (as simulate)");
  sub->add_option("--ambiguity-ratio", f.spec.ambiguity_ratio,
                  "A robot refuses a match whose prediction lies nearly as near another landmark "
                  "of its label (normalised distance ratio above R; 0: off, the paper's rule; as "
                  "simulate)")
      ->check(CLI::Range(0.0, 0.999));
  sub->add_option("--covariance-gate", f.spec.covariance_gate,
                  "A robot matches a detection to a landmark when the chi-square of the "
                  "measurement against the marginal covariance of its pose and the landmark is at "
                  "most CHI2 (6 dof: 22.46 is 99.9 %), instead of the fixed gate (0: off, the "
                  "paper's rule; as simulate)")
      ->check(NonNegative());
  sub->add_flag("--loop-closure", f.spec.loop_closure,
                "A robot aligns its recent landmarks with its older ones and joins the objects it "
                "mapped twice (as simulate; not with --online)");
  sub->add_flag("--rendezvous-constellation", f.spec.rendezvous_constellation,
                "Known initial poses: a rendezvous also aligns the two object maps by their "
                "constellation and takes that transform when more of its matches agree pairwise "
                "(as simulate; not with --online)");
  const std::vector<CLI::Option*> options = sub->get_options();
  for (std::size_t i = before; i < options.size(); ++i) {
    if (options[i] != scenario) options[i]->needs(scenario);
  }
}

void CheckScenarioFlags(const char* who, bool online, const ScenarioSpec& spec) {
  if (online && (spec.loop_closure || spec.rendezvous_constellation)) {
    throw InvalidInputError(fmt::format("{}: --loop-closure and --rendezvous-constellation are not "
                                        "part of the online mission (--online)",
                                        who));
  }
  if (spec.rendezvous_constellation && !spec.known_initial_poses) {
    throw InvalidInputError(fmt::format("{}: {}", who, kConstellationNeedsKnownPoses));
  }
}

std::vector<std::string> ScenarioArgs(const ScenarioFlags& f) {
  std::vector<std::string> a = {
      "--scenario", f.name, "--robots", std::to_string(f.spec.robots), "--seed",
      std::to_string(f.spec.seed), "--sigma-rot", fmt::format("{}", f.spec.sigma_rotation_deg),
      "--sigma-trans", fmt::format("{}", f.spec.sigma_translation), "--poses",
      std::to_string(f.spec.poses_per_robot), "--rendezvous-timeout",
      fmt::format("{}", f.rendezvous_timeout), "--initial-poses", f.initial_poses};
  for (const auto& [flag, value] : {std::pair{"--exclusion-radius", f.spec.exclusion_radius},
                                    std::pair{"--ambiguity-ratio", f.spec.ambiguity_ratio},
                                    std::pair{"--covariance-gate", f.spec.covariance_gate}}) {
    a.push_back(flag);
    a.push_back(fmt::format("{}", value));
  }
  if (f.spec.leave_one_out_check) a.push_back("--leave-one-out-check");
  if (f.spec.loop_closure) a.push_back("--loop-closure");
  if (f.spec.rendezvous_constellation) a.push_back("--rendezvous-constellation");
  return a;
}

nlohmann::json ScenarioJson(const ScenarioSpec& spec) {
  nlohmann::json j;
  j["scenario"] = spec.scenario;
  j["seed"] = spec.seed;
  j["initial_poses"] = spec.known_initial_poses ? "known" : "unknown";
  j["exclusion_radius"] = spec.exclusion_radius;
  j["leave_one_out_check"] = spec.leave_one_out_check;
  j["ambiguity_ratio"] = spec.ambiguity_ratio;
  j["covariance_gate"] = spec.covariance_gate;
  j["loop_closure"] = spec.loop_closure;
  j["rendezvous_constellation"] = spec.rendezvous_constellation;
  return j;
}

G2oReadOptions WithObjects() {
  G2oReadOptions o;
  o.scheme = KeyScheme::kWithObjects;
  return o;
}

}  // namespace moslam::cli
