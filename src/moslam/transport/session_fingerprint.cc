#include "moslam/transport/session_fingerprint.h"

#include <string>

#include "moslam/transport/record_bytes.h"

namespace moslam::transport_detail {

std::uint64_t SessionFingerprint(const RobotScenarioData& d, const RobotSessionOptions& options) {
  const MultiRobotSlamConfig& c = options.slam;
  Fingerprint f;
  f.add(static_cast<std::uint64_t>(d.robot));
  f.add(static_cast<std::uint64_t>(d.num_robots));
  for (const OdometryReading& o : d.measurements.odometry) {
    f.add(o.measurement);
    f.add(o.information);
  }
  for (const auto& pose : d.measurements.detections) {
    f.add(static_cast<std::uint64_t>(pose.size()));
    for (const ObjectDetection& z : pose) {
      f.add(z.label);
      f.add(z.measurement);
      f.add(z.information);
    }
  }
  if (c.known_initial_poses) {  // unknown: never read
    for (const SE3& x : d.initial_poses) f.add(x);
  }
  for (const RendezvousEvent& e : d.events) {
    f.add(static_cast<std::uint64_t>(e.step) << 32 | static_cast<std::uint64_t>(e.alpha) << 16 |
          static_cast<std::uint64_t>(e.beta));
  }
  for (const AssociationGate* g : {&c.slam.association, &c.rendezvous.gate}) {
    f.add(g->sigma);
    f.add(g->sigma_rotation_deg);
    f.add(g->num_sigmas);
  }
  f.add(static_cast<std::uint64_t>(c.slam.update_every));
  f.add(static_cast<std::uint64_t>(c.slam.iterations_per_update));
  f.add(static_cast<std::uint64_t>(c.slam.localization_iterations));
  f.add(c.slam.exclusion_radius);
  f.add(static_cast<std::uint64_t>(c.slam.leave_one_out_check));
  f.add(c.slam.leave_one_out_rival_radii);
  f.add(static_cast<std::uint64_t>(c.final_iterations));
  f.add(static_cast<std::uint64_t>(c.rendezvous.refine_alignment));
  f.add(c.rendezvous.max_correction_m);
  f.add(c.rendezvous.max_correction_deg);
  f.add(static_cast<std::uint64_t>(c.rendezvous.min_inliers));
  f.add(c.rendezvous.lambda());
  f.add(static_cast<std::uint64_t>(c.known_initial_poses));
  f.add(static_cast<std::uint64_t>(c.rendezvous.check_consistency));
  f.add(static_cast<std::uint64_t>(c.rendezvous.refine_by_constellation));
  for (const ConstellationConfig* k : {&c.rendezvous.constellation, &c.rendezvous.consistency}) {
    f.add(k->sigma_translation);
    f.add(k->sigma_rotation_deg);
    f.add(k->drift_per_m);
    f.add(k->num_sigmas);
    f.add(static_cast<std::uint64_t>(k->min_support));
    f.add(k->same_object_radius);
    f.add(static_cast<std::uint64_t>(k->ambiguity_margin));
    f.add(static_cast<std::uint64_t>(k->max_search_nodes));
  }
  if (!c.known_initial_poses && c.rendezvous.overlap.enabled) {  // (as loop closure, below)
    const OverlapCheck& o = c.rendezvous.overlap;
    f.add(std::string("overlap"));
    f.add(o.camera.horizontal_fov_deg);
    f.add(o.camera.vertical_fov_deg);
    f.add(o.camera.min_range);
    f.add(o.camera.max_range);
    f.add(o.radius);
    f.add(static_cast<std::uint64_t>(o.min_seen));
    f.add(o.min_confirmed_fraction);
  }
  if (c.slam.ambiguity_ratio > 0.0) {  // (only then, as the covariance gate and loop closure)
    f.add(std::string("ambiguity_ratio"));
    f.add(c.slam.ambiguity_ratio);
  }
  if (c.slam.covariance_gate > 0.0) {
    f.add(std::string("covariance_gate"));
    f.add(c.slam.covariance_gate);
  }
  if (c.slam.loop_closure) {  // (only then: the fingerprints of journals without it stay)
    f.add(std::string("loop_closure"));
    f.add(static_cast<std::uint64_t>(c.slam.loop_closure_window));
    f.add(static_cast<std::uint64_t>(c.slam.loop_closure_one_label_min_support));
    f.add(static_cast<std::uint64_t>(c.slam.loop_closure_iterations));
    f.add(c.slam.loop_closure_sigma_rotation_deg);
    f.add(c.slam.loop_closure_sigma_translation);
    const ConstellationConfig& k = c.slam.loop_closure_alignment;
    f.add(k.sigma_translation);
    f.add(k.sigma_rotation_deg);
    f.add(k.drift_per_m);
    f.add(k.num_sigmas);
    f.add(static_cast<std::uint64_t>(k.min_support));
    f.add(k.same_object_radius);
    f.add(static_cast<std::uint64_t>(k.ambiguity_margin));
    f.add(static_cast<std::uint64_t>(k.max_search_nodes));
  }
  if (options.online) {  // the group solves change the maps, hence the later rendezvous
    f.add(std::string("online"));
    AddSolverOptions(f, options.dgs.solver);
    if (options.dgs.gnc) {  // (only then: the fingerprints of least-squares journals stay)
      f.add(std::string("robust"));
      AddRobustOptions(f, options.dgs.gnc, options.dgs.separator_check, options.dgs.retest_left_out,
                       options.dgs.retest_groups, options.dgs.one_to_one_after_gnc);
    }
  }
  return f.value();
}

}  // namespace moslam::transport_detail
