#include "moslam/sim/robots.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>

#include "moslam/common/errors.h"

namespace moslam {

void TrajectoryConfig::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("TrajectoryConfig: " + m); };
  if (num_robots < 1) bad("num_robots must be >= 1");
  if (poses_per_robot < 1) bad("poses_per_robot must be >= 1");
  if (!(step_length > 0.0) || !std::isfinite(step_length)) {
    bad("step_length must be positive and finite");
  }
  if (!std::isfinite(camera_height)) bad("camera_height must be finite");
}

std::vector<Trajectory> GenerateTrajectories(const World& world, const TrajectoryConfig& config) {
  config.validate();
  const auto& nav = world.navigation;
  const auto neighbours = nav.neighbours();
  if (static_cast<int>(nav.nodes.size()) < config.num_robots) {
    throw InvalidInputError("world '" + world.name + "' has " + std::to_string(nav.nodes.size()) +
                            " navigation nodes: too few for " +
                            std::to_string(config.num_robots) + " distinct start poses");
  }
  for (std::size_t i = 0; i < neighbours.size(); ++i) {
    if (neighbours[i].empty()) {
      throw InvalidInputError("world '" + world.name + "': navigation node " + std::to_string(i) +
                              " has no edge (robots could not leave it)");
    }
  }
  std::mt19937 rng(config.seed);
  std::vector<int> starts(nav.nodes.size());
  std::iota(starts.begin(), starts.end(), 0);
  std::shuffle(starts.begin(), starts.end(), rng);

  auto pick = [&](const std::vector<int>& options) {
    return options[std::uniform_int_distribution<std::size_t>(0, options.size() - 1)(rng)];
  };
  auto node = [&](int i) { return nav.nodes[static_cast<std::size_t>(i)]; };

  std::vector<Trajectory> out(static_cast<std::size_t>(config.num_robots));
  for (int r = 0; r < config.num_robots; ++r) {
    int previous = -1;
    int current = starts[static_cast<std::size_t>(r)];
    int target = pick(neighbours[static_cast<std::size_t>(current)]);
    Vector2 p = node(current);
    auto& traj = out[static_cast<std::size_t>(r)];
    traj.reserve(static_cast<std::size_t>(config.poses_per_robot));
    auto advance_target = [&]() {
      previous = current;
      current = target;
      std::vector<int> options;
      for (int n : neighbours[static_cast<std::size_t>(current)]) {
        if (n != previous) options.push_back(n);
      }
      target = options.empty() ? previous : pick(options);
    };
    for (int i = 0; i < config.poses_per_robot; ++i) {
      if (i > 0) {
        double remaining = config.step_length;
        int hops = 0;
        while (remaining > 0.0) {
          if (++hops > 100000) {
            throw InvalidInputError("world '" + world.name +
                                    "': the navigation graph has edges of zero length around "
                                    "node " + std::to_string(current));
          }
          const Vector2 to = node(target) - p;
          const double d = to.norm();
          if (d <= remaining) {
            p = node(target);
            remaining -= d;
            advance_target();
          } else {
            p += remaining * to / d;
            remaining = 0.0;
          }
        }
      }
      // Heading along the edge being driven (at a node: the edge about to be driven).
      Vector2 dir = node(target) - p;
      if (dir.norm() < 1e-12) dir = node(target) - node(current);
      const double yaw = std::atan2(dir.y(), dir.x());
      traj.emplace_back(SO3::Exp(Vector3(0.0, 0.0, yaw)),
                        Vector3(p.x(), p.y(), config.camera_height));
    }
  }
  return out;
}

void RendezvousDetectionConfig::validate() const {
  auto bad = [](const std::string& m) {
    throw InvalidInputError("RendezvousDetectionConfig: " + m);
  };
  if (!(communication_range >= 0.0) || !std::isfinite(communication_range)) {
    bad("communication_range must be >= 0 and finite");
  }
  if (min_steps_between_events < 1) bad("min_steps_between_events must be >= 1");
}

std::vector<RendezvousEvent> DetectRendezvous(const std::vector<Trajectory>& trajectories,
                                              const RendezvousDetectionConfig& config) {
  config.validate();
  const int n = static_cast<int>(trajectories.size());
  const int steps = n > 0 ? static_cast<int>(trajectories.front().size()) : 0;
  for (const auto& t : trajectories) {
    if (static_cast<int>(t.size()) != steps) {
      throw InvalidInputError("DetectRendezvous: the trajectories differ in length");
    }
  }
  std::vector<RendezvousEvent> events;
  if (!config.schedule.empty()) {
    for (std::size_t e = 0; e < config.schedule.size(); ++e) {
      const auto& ev = config.schedule[e];
      const std::string at = "RendezvousDetectionConfig: schedule[" + std::to_string(e) + "] ";
      if (ev.alpha < 0 || ev.alpha >= n || ev.beta < 0 || ev.beta >= n) {
        throw InvalidInputError(at + "names a robot that does not exist (" + std::to_string(n) +
                                " robots)");
      }
      if (ev.alpha == ev.beta) throw InvalidInputError(at + "has a robot meeting itself");
      if (ev.step < 0 || ev.step >= steps) {
        throw InvalidInputError(at + "is at step " + std::to_string(ev.step) + ", outside 0.." +
                                std::to_string(steps - 1));
      }
      events.push_back(ev);
    }
  } else {
    std::map<std::pair<int, int>, int> last;
    const double range2 = config.communication_range * config.communication_range;
    for (int t = 0; t < steps; ++t) {
      for (int a = 0; a < n; ++a) {
        for (int b = a + 1; b < n; ++b) {
          const Vector3 d = trajectories[static_cast<std::size_t>(a)][static_cast<std::size_t>(t)]
                                .translation() -
                            trajectories[static_cast<std::size_t>(b)][static_cast<std::size_t>(t)]
                                .translation();
          if (d.squaredNorm() > range2) continue;
          const auto it = last.find({a, b});
          if (it != last.end() && t - it->second < config.min_steps_between_events) continue;
          last[{a, b}] = t;
          events.push_back({t, a, b});
        }
      }
    }
  }
  std::stable_sort(events.begin(), events.end(), [](const auto& x, const auto& y) {
    if (x.step != y.step) return x.step < y.step;
    if (x.alpha != y.alpha) return x.alpha < y.alpha;
    return x.beta < y.beta;
  });
  return events;
}

}  // namespace moslam
