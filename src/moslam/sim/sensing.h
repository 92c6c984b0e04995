// Simulated sensing: a camera that detects objects (label and relative pose) and odometry, both
// with Gaussian noise on rotation and translation.
//
// Camera: the body frame of the robot (x forward, y left, z up). An object is visible from pose
// x when its centre p = x^-1 * t_object satisfies
//   min_range <= |p| <= max_range,  p.x > 0,
//   |atan2(p.y, p.x)| <= horizontal_fov / 2,  |atan2(p.z, p.x)| <= vertical_fov / 2.
// There is no occlusion and no false or missed detection: every visible object is detected.
//
// Noise (paper Section 3.1; defaults sigma_R = 5 deg, sigma_t = 0.2 m): a measurement of the
// true relative pose z (odometry z = x_i^-1 x_{i+1}; object z = x_i^-1 o_k) is z * Exp(n),
// n = (n_w, n_v) ~ N(0, diag(sigma_R^2 I3, sigma_t^2 I3)) in tangent order (w, v). Its
// information is diag(1/s_R^2 I3, 1/s_t^2 I3) with s = max(sigma, information_sigma_floor), so
// noise-free measurements still have a symmetric positive definite information.
//
// Randomness: each robot draws its noise from its own std::mt19937 seeded with (seed, robot), so
// a robot's measurements do not depend on how many robots there are.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "moslam/sim/robots.h"
#include "moslam/sim/world.h"

namespace moslam {

struct CameraModel {
  double horizontal_fov_deg = 90.0;
  double vertical_fov_deg = 60.0;
  double min_range = 0.3;  // m
  double max_range = 6.0;  // m
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  // Whether a point given in the body frame is inside the frustum and range.
  bool sees(const Vector3& point_in_body) const;
};

struct NoiseModel {
  double sigma_rotation_deg = 5.0;
  double sigma_translation = 0.2;  // m
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  // diag(1/s_R^2 I3, 1/s_t^2 I3), s = max(sigma, floor); floor in rad and m.
  Matrix6 information(double sigma_floor) const;
  // One draw of n = (n_w, n_v).
  Vector6 sample(std::mt19937& rng) const;
};

struct SensingConfig {
  CameraModel camera;
  NoiseModel odometry;
  NoiseModel objects;
  double information_sigma_floor = 1e-3;  // rad and m
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct OdometryReading {
  SE3 measurement;       // noisy x_i^-1 x_{i+1}
  Matrix6 information;
};

struct ObjectDetection {
  std::string label;
  SE3 measurement;       // noisy x_i^-1 o_k
  Matrix6 information;
  int object_id = -1;    // ground truth (the world object's id): for evaluation only, -1 unknown
};

struct RobotMeasurements {
  std::vector<OdometryReading> odometry;                // odometry[i]: pose i -> i + 1
  std::vector<std::vector<ObjectDetection>> detections;  // detections[i]: seen from pose i
};

// One RobotMeasurements per trajectory. Detections of each pose are in the world's object order.
// Throws InvalidInputError on a bad config or a world object whose label has no class.
std::vector<RobotMeasurements> SimulateSensing(const World& world,
                                               const std::vector<Trajectory>& trajectories,
                                               const SensingConfig& config);

// How densely the poses are measured: object measurements per pose and the poses with none.
// A pose without one is placed by odometry alone; with the paper's odometry noise (5 deg / 0.2 m a
// step) that is what a front-end accepting few views costs the map (README, Perception).
struct MeasurementCoverage {
  int poses = 0;
  int measurements = 0;        // object measurements (detections) over all poses
  int poses_without = 0;       // poses with no object measurement
  int longest_without = 0;     // most consecutive poses of one robot with none
  double perPose() const { return poses > 0 ? double(measurements) / poses : 0.0; }
  double fractionWithout() const { return poses > 0 ? double(poses_without) / poses : 0.0; }
};
MeasurementCoverage CoverageOf(const std::vector<RobotMeasurements>& measurements);

// Everything a multi-robot run needs: the world, ground-truth trajectories, measurements, and
// rendezvous events.
struct SimulationConfig {
  TrajectoryConfig trajectory;
  SensingConfig sensing;
  RendezvousDetectionConfig rendezvous;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The simulation of the experiments and of the robot processes alike (so that both simulate the
// same data by construction): `robots` robots of `poses_per_robot` poses, trajectories and
// measurements drawn from `seed`, odometry and object measurements with the same noise (sigma of
// the rotation in degrees, of the translation in metres); the rest at its defaults.
SimulationConfig NoiseSimulationConfig(int robots, int poses_per_robot, unsigned seed,
                                       double sigma_rotation_deg, double sigma_translation);

struct SimulationData {
  World world;
  std::vector<Trajectory> trajectories;  // ground truth; trajectories[r][0]: known initial pose
  std::vector<RobotMeasurements> measurements;
  std::vector<RendezvousEvent> rendezvous;
  int numRobots() const { return static_cast<int>(trajectories.size()); }
  int numSteps() const {
    return trajectories.empty() ? 0 : static_cast<int>(trajectories.front().size());
  }
};

SimulationData Simulate(const World& world, const SimulationConfig& config);

}  // namespace moslam
