#include "moslam/sim/sensing.h"

#include <algorithm>
#include <cmath>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

}  // namespace

void CameraModel::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("CameraModel: " + m); };
  if (!(horizontal_fov_deg > 0.0 && horizontal_fov_deg < 180.0)) {
    bad("horizontal_fov_deg must be in (0, 180)");
  }
  if (!(vertical_fov_deg > 0.0 && vertical_fov_deg < 180.0)) {
    bad("vertical_fov_deg must be in (0, 180)");
  }
  if (!(min_range >= 0.0) || !std::isfinite(min_range)) bad("min_range must be >= 0 and finite");
  if (!(max_range > min_range) || !std::isfinite(max_range)) {
    bad("max_range must be finite and greater than min_range");
  }
}

bool CameraModel::sees(const Vector3& p) const {
  const double d = p.norm();
  if (d < min_range || d > max_range || !(p.x() > 0.0)) return false;
  return std::abs(std::atan2(p.y(), p.x())) <= 0.5 * horizontal_fov_deg * kDegToRad &&
         std::abs(std::atan2(p.z(), p.x())) <= 0.5 * vertical_fov_deg * kDegToRad;
}

void NoiseModel::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("NoiseModel: " + m); };
  if (!(sigma_rotation_deg >= 0.0) || !std::isfinite(sigma_rotation_deg)) {
    bad("sigma_rotation_deg must be >= 0 and finite");
  }
  if (!(sigma_translation >= 0.0) || !std::isfinite(sigma_translation)) {
    bad("sigma_translation must be >= 0 and finite");
  }
}

Matrix6 NoiseModel::information(double sigma_floor) const {
  const double sr = std::max(sigma_rotation_deg * kDegToRad, sigma_floor);
  const double st = std::max(sigma_translation, sigma_floor);
  Vector6 d;
  d << Vector3::Constant(1.0 / (sr * sr)), Vector3::Constant(1.0 / (st * st));
  return d.asDiagonal();
}

Vector6 NoiseModel::sample(std::mt19937& rng) const {
  std::normal_distribution<double> n01;
  const double sr = sigma_rotation_deg * kDegToRad;
  Vector6 n;
  for (int k = 0; k < 3; ++k) n[k] = sr * n01(rng);
  for (int k = 3; k < 6; ++k) n[k] = sigma_translation * n01(rng);
  return n;
}

void SensingConfig::validate() const {
  camera.validate();
  odometry.validate();
  objects.validate();
  if (!(information_sigma_floor > 0.0) || !std::isfinite(information_sigma_floor)) {
    throw InvalidInputError("SensingConfig: information_sigma_floor must be positive and finite");
  }
}

std::vector<RobotMeasurements> SimulateSensing(const World& world,
                                               const std::vector<Trajectory>& trajectories,
                                               const SensingConfig& config) {
  config.validate();
  for (const auto& o : world.objects) {
    if (world.findClass(o.label) == nullptr) {
      throw InvalidInputError("world '" + world.name + "': object " + std::to_string(o.id) +
                              " has label '" + o.label + "', which is not a declared class");
    }
  }
  const Matrix6 odo_info = config.odometry.information(config.information_sigma_floor);
  const Matrix6 obj_info = config.objects.information(config.information_sigma_floor);
  std::vector<RobotMeasurements> out(trajectories.size());
  for (std::size_t r = 0; r < trajectories.size(); ++r) {
    std::seed_seq seq{config.seed, static_cast<unsigned>(r), 0x5e115u};
    std::mt19937 rng(seq);
    const Trajectory& traj = trajectories[r];
    auto& m = out[r];
    m.detections.resize(traj.size());
    for (std::size_t i = 0; i < traj.size(); ++i) {
      if (i > 0) {
        const SE3 z = traj[i - 1].between(traj[i]);
        m.odometry.push_back({z.retract(config.odometry.sample(rng)), odo_info});
      }
      const SE3 body_T_world = traj[i].inverse();
      for (const auto& o : world.objects) {
        if (!config.camera.sees(body_T_world.transformFrom(o.pose.translation()))) continue;
        const SE3 z = traj[i].between(o.pose);
        m.detections[i].push_back({o.label, z.retract(config.objects.sample(rng)), obj_info, o.id});
      }
    }
  }
  return out;
}

SimulationConfig NoiseSimulationConfig(int robots, int poses_per_robot, unsigned seed,
                                       double sigma_rotation_deg, double sigma_translation) {
  SimulationConfig sim;
  sim.trajectory.num_robots = robots;
  sim.trajectory.poses_per_robot = poses_per_robot;
  sim.trajectory.seed = seed;
  sim.sensing.seed = seed;
  for (NoiseModel* n : {&sim.sensing.odometry, &sim.sensing.objects}) {
    n->sigma_rotation_deg = sigma_rotation_deg;
    n->sigma_translation = sigma_translation;
  }
  return sim;
}

void SimulationConfig::validate() const {
  trajectory.validate();
  sensing.validate();
  rendezvous.validate();
}

SimulationData Simulate(const World& world, const SimulationConfig& config) {
  config.validate();
  ValidateWorld(world, "world '" + world.name + "'");
  SimulationData d;
  d.world = world;
  d.trajectories = GenerateTrajectories(world, config.trajectory);
  d.measurements = SimulateSensing(world, d.trajectories, config.sensing);
  d.rendezvous = DetectRendezvous(d.trajectories, config.rendezvous);
  return d;
}

MeasurementCoverage CoverageOf(const std::vector<RobotMeasurements>& measurements) {
  MeasurementCoverage c;
  for (const RobotMeasurements& robot : measurements) {
    int run = 0;
    for (const auto& pose : robot.detections) {
      ++c.poses;
      c.measurements += static_cast<int>(pose.size());
      run = pose.empty() ? run + 1 : 0;
      c.poses_without += pose.empty() ? 1 : 0;
      c.longest_without = std::max(c.longest_without, run);
    }
  }
  return c;
}

}  // namespace moslam
