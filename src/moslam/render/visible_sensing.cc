#include "moslam/render/visible_sensing.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "moslam/common/errors.h"

namespace moslam {

void VisibleSensingConfig::validate() const {
  render.validate();
  noise.validate();
  if (!(min_visible_fraction >= 0.0 && min_visible_fraction <= 1.0)) {
    throw InvalidInputError("VisibleSensingConfig: min_visible_fraction must be in [0, 1]");
  }
  if (!(information_sigma_floor > 0.0) || !std::isfinite(information_sigma_floor)) {
    throw InvalidInputError(
        "VisibleSensingConfig: information_sigma_floor must be positive and finite");
  }
  if (!(keep_probability > 0.0 && keep_probability <= 1.0)) {
    throw InvalidInputError("VisibleSensingConfig: keep_probability must be in (0, 1]");
  }
  if (every < 1) throw InvalidInputError("VisibleSensingConfig: every must be >= 1");
}

VisibleSensingStats MeasureVisibleObjects(SimulationData& data,
                                          const VisibleSensingConfig& config) {
  config.validate();
  if (data.measurements.size() != data.trajectories.size()) {
    throw InvalidInputError("MeasureVisibleObjects: the simulation has " +
                            std::to_string(data.measurements.size()) + " measurement sets for " +
                            std::to_string(data.trajectories.size()) + " robots");
  }
  const Renderer renderer(data.world, config.render);
  const Matrix6 information = config.noise.information(config.information_sigma_floor);
  const SE3 body_T_camera = BodyFromCamera();
  VisibleSensingStats stats;
  for (int r = 0; r < data.numRobots(); ++r) {
    RobotMeasurements& m = data.measurements[static_cast<std::size_t>(r)];
    const Trajectory& trajectory = data.trajectories[static_cast<std::size_t>(r)];
    for (const auto& pose : m.detections) stats.replaced += static_cast<int>(pose.size());
    m.detections.assign(trajectory.size(), {});
    for (std::size_t i = 0; i < trajectory.size(); i += static_cast<std::size_t>(config.every)) {
      const auto t0 = std::chrono::steady_clock::now();
      const RenderedFrame frame =
          renderer.render(trajectory[i], SimulationFrameKey(r, i), static_cast<double>(i));
      stats.render_ms +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      ++stats.frames;
      std::seed_seq seq{config.seed, static_cast<unsigned>(r), static_cast<unsigned>(i), 0x71u};
      std::mt19937 rng(seq);
      std::bernoulli_distribution keep(config.keep_probability);
      for (const VisibleObject& v : frame.objects) {
        const double depth = v.camera_T_object.translation().z();
        if (v.visibleFraction() < config.min_visible_fraction || !(depth > 0.0) ||
            depth > config.render.max_depth) {
          continue;
        }
        ++stats.seen_enough;
        // Both draws for every object, so that the keep probability does not move the noise.
        const Vector6 n = config.noise.sample(rng);
        if (!keep(rng)) continue;
        ++stats.measured;
        const SE3 truth = body_T_camera.compose(v.camera_T_object);
        m.detections[i].push_back({v.label, truth.retract(n), information, v.id});
      }
    }
  }
  return stats;
}

}  // namespace moslam
