#include "moslam/transport/session_fingerprint.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "moslam/distributed/robust_dgs.h"

namespace moslam::transport_detail {
namespace {

struct SessionRun {
  RobotScenarioData data;
  RobotSessionOptions options;
};

SessionRun OnlineRobustRun() {
  ScenarioSpec spec;
  spec.robots = 3;
  spec.poses_per_robot = 30;
  SessionRun run;
  run.data = SliceForRobot(SimulateScenario(spec), 1);
  run.options.slam = ScenarioSlamConfig(spec);
  run.options.online = true;
  run.options.dgs.solver.refine = true;
  const RobustDgsOptions robust;
  run.options.dgs.gnc = robust.gnc;
  run.options.dgs.separator_check = robust.consistency;
  EXPECT_FALSE(run.data.events.empty());
  EXPECT_EQ(run.data.initial_poses.size(), 3u);
  return run;
}

TEST(SessionFingerprint, EverythingTheJournaledResultsDependOnChangesIt) {
  const SessionRun base = OnlineRobustRun();
  const std::uint64_t reference = SessionFingerprint(base.data, base.options);
  EXPECT_EQ(SessionFingerprint(base.data, base.options), reference);  // deterministic
  const std::vector<std::pair<std::string, std::function<void(SessionRun&)>>> changes = {
      {"robot", [](SessionRun& r) { r.data.robot = 2; }},
      {"odometry", [](SessionRun& r) { r.data.measurements.odometry[3].measurement = SE3(); }},
      {"a detection",
       [](SessionRun& r) {
         for (auto& pose : r.data.measurements.detections) {
           if (!pose.empty()) return pose.pop_back();
         }
       }},
      {"known initial poses", [](SessionRun& r) { r.data.initial_poses[2] = SE3(); }},
      {"an event", [](SessionRun& r) { r.data.events.pop_back(); }},
      {"association gate", [](SessionRun& r) { r.options.slam.slam.association.sigma *= 2.0; }},
      {"leave-one-out", [](SessionRun& r) { r.options.slam.slam.leave_one_out_check = true; }},
      {"ambiguity ratio", [](SessionRun& r) { r.options.slam.slam.ambiguity_ratio = 0.6; }},
      {"covariance gate", [](SessionRun& r) { r.options.slam.slam.covariance_gate = 22.46; }},
      {"loop closure", [](SessionRun& r) { r.options.slam.slam.loop_closure = true; }},
      {"rendezvous gate", [](SessionRun& r) { r.options.slam.rendezvous.gate.num_sigmas = 3.0; }},
      {"initial poses unknown", [](SessionRun& r) { r.options.slam.known_initial_poses = false; }},
      {"batch, not online", [](SessionRun& r) { r.options.online = false; }},
      {"solver", [](SessionRun& r) { r.options.dgs.solver.eta_pose *= 0.5; }},
      {"least squares", [](SessionRun& r) { r.options.dgs.gnc.reset(); }},
      {"GNC threshold", [](SessionRun& r) { r.options.dgs.gnc->threshold = 9.0; }},
      {"no separator check", [](SessionRun& r) { r.options.dgs.separator_check.reset(); }},
      {"check support", [](SessionRun& r) { r.options.dgs.separator_check->min_support = 4; }},
      {"one-to-one",
       [](SessionRun& r) { r.options.dgs.separator_check->one_to_one_objects = false; }},
      {"no re-test", [](SessionRun& r) { r.options.dgs.retest_left_out = false; }},
      {"no group re-test", [](SessionRun& r) { r.options.dgs.retest_groups = false; }},
      {"one-to-one after GNC", [](SessionRun& r) { r.options.dgs.one_to_one_after_gnc = true; }},
  };
  for (const auto& [what, change] : changes) {
    SessionRun changed = base;
    change(changed);
    EXPECT_NE(SessionFingerprint(changed.data, changed.options), reference) << what;
  }
}

TEST(SessionFingerprint, WaitingWritingReportingAndUnknownInitialPosesLeaveIt) {
  const SessionRun base = OnlineRobustRun();
  const std::uint64_t reference = SessionFingerprint(base.data, base.options);
  const std::vector<std::pair<std::string, std::function<void(SessionRun&)>>> changes = {
      {"rendezvous timeout", [](SessionRun& r) { r.options.rendezvous_timeout *= 2; }},
      {"leave timeout", [](SessionRun& r) { r.options.dgs.leave_timeout *= 2; }},
      {"state directory", [](SessionRun& r) { r.options.dgs.state_dir = "elsewhere"; }},
      {"log", [](SessionRun& r) { r.options.log = [](const std::string&) {}; }},
  };
  for (const auto& [what, change] : changes) {
    SessionRun changed = base;
    change(changed);
    EXPECT_EQ(SessionFingerprint(changed.data, changed.options), reference) << what;
  }
  // With unknown initial poses whatever the data holds of them is never read.
  SessionRun unknown = base;
  unknown.options.slam.known_initial_poses = false;
  const std::uint64_t without = SessionFingerprint(unknown.data, unknown.options);
  unknown.data.initial_poses[2] = SE3();
  EXPECT_EQ(SessionFingerprint(unknown.data, unknown.options), without);
  // A least-squares batch run ignores the online solver's options (its DgsNode journals them).
  SessionRun batch = base;
  batch.options.online = false;
  const std::uint64_t batch_reference = SessionFingerprint(batch.data, batch.options);
  batch.options.dgs.gnc->threshold = 9.0;
  batch.options.dgs.solver.eta_pose *= 0.5;
  EXPECT_EQ(SessionFingerprint(batch.data, batch.options), batch_reference);
}

}  // namespace
}  // namespace moslam::transport_detail
