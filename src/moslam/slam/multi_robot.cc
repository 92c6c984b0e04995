#include "moslam/slam/multi_robot.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <random>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/graph/robot_groups.h"

namespace moslam {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

std::set<int> MappedObjects(const ObjectSlam& robot) {
  std::set<int> out;
  for (const auto& lm : robot.landmarks()) {
    if (lm.true_object >= 0) out.insert(lm.true_object);
  }
  return out;
}

int TrueObject(const std::vector<ObjectSlam>& robots, const Key& k) {
  return robots.at(static_cast<std::size_t>(k.robot)).landmarks().at(k.index).true_object;
}

// Throws InvalidInputError unless every robot has a measurement set of the simulation's steps,
// every rendezvous event fits (two distinct robots, a step of the simulation), the events are in
// step order and leave_after names robots of the simulation: before any work.
void CheckSimulationFits(const SimulationData& data, const MultiRobotSlamConfig& config) {
  const int n = data.numRobots(), steps = data.numSteps();
  if (static_cast<int>(data.measurements.size()) != n) {
    throw InvalidInputError("RunMultiRobotObjectSlam: " + std::to_string(n) + " trajectories but " +
                            std::to_string(data.measurements.size()) + " measurement sets");
  }
  for (int r = 0; r < n; ++r) {
    const auto& m = data.measurements[static_cast<std::size_t>(r)];
    if (static_cast<int>(data.trajectories[static_cast<std::size_t>(r)].size()) != steps ||
        static_cast<int>(m.detections.size()) != steps ||
        static_cast<int>(m.odometry.size()) != std::max(steps - 1, 0)) {
      throw InvalidInputError("RunMultiRobotObjectSlam: robot " + std::to_string(r) +
                              " has measurements inconsistent with " + std::to_string(steps) +
                              " time steps");
    }
  }
  for (const auto& e : data.rendezvous) {
    if (e.alpha < 0 || e.alpha >= n || e.beta < 0 || e.beta >= n || e.alpha == e.beta ||
        e.step < 0 || e.step >= steps) {
      throw InvalidInputError("RunMultiRobotObjectSlam: rendezvous event at step " +
                              std::to_string(e.step) + " between robots " +
                              std::to_string(e.alpha) + " and " + std::to_string(e.beta) +
                              " does not fit the simulation");
    }
  }
  if (!std::is_sorted(
          data.rendezvous.begin(), data.rendezvous.end(),
          [](const RendezvousEvent& a, const RendezvousEvent& b) { return a.step < b.step; })) {
    throw InvalidInputError("RunMultiRobotObjectSlam: rendezvous events are not sorted by step");
  }
  for (const auto& [robot, step] : config.leave_after) {
    if (robot >= n) {
      throw InvalidInputError("RunMultiRobotObjectSlam: leave_after names robot " +
                              std::to_string(robot) + " of " + std::to_string(n));
    }
  }
}

// Wrong pairs at a rendezvous that found `new_pairs` new ones, label-consistent (an object of
// alpha with another object of beta), fraction / (1 - fraction) of them in expectation, appended
// to `shared` (never a pair it holds); returns how many.
int InjectWrongPairs(const ObjectSlam& alpha, const ObjectSlam& beta, std::size_t new_pairs,
                     double fraction, std::mt19937_64& rng, std::vector<SharedObject>& shared) {
  int injected = 0;
  const double expected = fraction / (1.0 - fraction) * static_cast<double>(new_pairs);
  int k = static_cast<int>(expected);
  if (std::uniform_real_distribution<double>(0.0, 1.0)(rng) < expected - k) ++k;
  const auto& la = alpha.landmarks();
  const auto& lb = beta.landmarks();
  for (int attempt = 0; k > 0 && attempt < 20 * k + 20 && !la.empty(); ++attempt) {
    const Landmark& x = la[std::uniform_int_distribution<std::size_t>(0, la.size() - 1)(rng)];
    std::vector<const Landmark*> other;
    for (const Landmark& y : lb) {
      if (y.label == x.label && y.true_object != x.true_object) other.push_back(&y);
    }
    if (other.empty()) continue;
    const Landmark& y =
        *other[std::uniform_int_distribution<std::size_t>(0, other.size() - 1)(rng)];
    const SharedObject wrong{y.key, x.key};
    const bool known = std::any_of(shared.begin(), shared.end(), [&](const SharedObject& z) {
      return z.alpha_object == wrong.alpha_object && z.beta_object == wrong.beta_object;
    });
    if (known) continue;
    shared.push_back(wrong);
    ++injected;
    --k;
  }
  return injected;
}

// The inter-robot association against ground truth: `possible` per robot pair (lower id first),
// the objects both had mapped at one of their rendezvous.
InterRobotAssociationStats InterRobotAssociation(
    const std::vector<ObjectSlam>& robots, const std::vector<SharedObject>& shared,
    const std::map<std::pair<int, int>, std::set<int>>& possible) {
  InterRobotAssociationStats stats;
  std::map<std::pair<int, int>, std::set<int>> found;
  for (const auto& s : shared) {
    ++stats.pairs;
    const int ta = TrueObject(robots, s.alpha_object);
    if (ta < 0 || ta != TrueObject(robots, s.beta_object)) continue;
    ++stats.correct;
    const int a = s.alpha_object.robot, b = s.beta_object.robot;
    found[{std::min(a, b), std::max(a, b)}].insert(ta);
  }
  for (const auto& [pair, objects] : possible) {
    stats.possible += static_cast<int>(objects.size());
    const auto it = found.find(pair);
    if (it == found.end()) continue;
    for (int o : it->second) stats.found += static_cast<int>(objects.count(o));
  }
  return stats;
}

}  // namespace

void MultiRobotSlamConfig::validate() const {
  slam.validate();
  rendezvous.validate();
  if (!(outlier_fraction >= 0.0 && outlier_fraction < 1.0)) {
    throw InvalidInputError("MultiRobotSlamConfig: outlier_fraction must be in [0, 1)");
  }
  if (final_iterations < 0) {
    throw InvalidInputError("MultiRobotSlamConfig: final_iterations must be >= 0");
  }
  for (const auto& [robot, step] : leave_after) {
    if (robot < 0 || step < 0) {
      throw InvalidInputError("MultiRobotSlamConfig: leave_after needs robot ids and steps >= 0");
    }
  }
}

MultiRobotSlamConfig MultiRobotSlamConfigForNoise(const SensingConfig& sensing) {
  sensing.validate();
  MultiRobotSlamConfig c;
  c.slam.association = AssociationGateForNoise(sensing.objects.sigma_rotation_deg,
                                               sensing.objects.sigma_translation);
  c.rendezvous.gate = AssociationGateForNoise(sensing.objects.sigma_rotation_deg,
                                              sensing.objects.sigma_translation);
  c.rendezvous.lambda_sigma_rotation_deg =
      std::max(sensing.objects.sigma_rotation_deg, sensing.information_sigma_floor * kRadToDeg);
  c.rendezvous.lambda_sigma_translation =
      std::max(sensing.objects.sigma_translation, sensing.information_sigma_floor);
  c.rendezvous.overlap.camera = sensing.camera;
  return c;
}

namespace {

// Whether `robot` has left the team by step t (MultiRobotSlamConfig::leave_after).
bool HasLeft(const MultiRobotSlamConfig& config, int robot, int t) {
  const auto it = config.leave_after.find(robot);
  return it != config.leave_after.end() && t > it->second;
}

// Every robot's pose of step t with its detections.
void AddPoses(const SimulationData& data, int t, std::vector<ObjectSlam>& robots) {
  for (std::size_t r = 0; r < robots.size(); ++r) {
    const auto& m = data.measurements[r];
    const auto ti = static_cast<std::size_t>(t);
    if (t == 0) {
      robots[r].addFirstPose(m.detections[0]);
    } else {
      robots[r].addPose(m.odometry[ti - 1], m.detections[ti]);
    }
  }
}

// One rendezvous of two robots still in the team: the exchange (RunRendezvous), the pairs it
// adds to and removes from out.shared, the wrong pairs injected, the bytes, and its record against
// the ground truth. Returns the objects both robots had mapped (the truly shared ones).
std::vector<int> Meet(const SimulationData& data, const RendezvousEvent& e,
                      const MultiRobotSlamConfig& config, std::mt19937_64& outlier_rng,
                      MultiRobotSlamResult& out) {
  auto& alpha = out.robots[static_cast<std::size_t>(e.alpha)];
  auto& beta = out.robots[static_cast<std::size_t>(e.beta)];
  std::optional<SE3> beta_T_alpha;
  if (config.known_initial_poses) {
    beta_T_alpha = BetaTAlpha(data.trajectories[static_cast<std::size_t>(e.alpha)].front(),
                              data.trajectories[static_cast<std::size_t>(e.beta)].front());
  }
  const RendezvousOutcome o =
      RunRendezvous(alpha, beta, beta_T_alpha, out.shared, config.rendezvous);
  RendezvousRecord rec;
  rec.event = e;
  rec.objects_sent = o.objects_sent;
  rec.new_shared = static_cast<int>(o.new_shared.size());
  rec.bytes_alpha_to_beta = o.bytes_alpha_to_beta;
  rec.bytes_beta_to_alpha = o.bytes_beta_to_alpha;
  const auto correct = [&](const SharedObject& s) {
    const int ta = TrueObject(out.robots, s.alpha_object);
    return ta >= 0 && ta == TrueObject(out.robots, s.beta_object);
  };
  for (const auto& s : o.removed_shared) {
    if (!EraseShared(out.shared, s)) {
      throw InvalidInputError("RunMultiRobotObjectSlam: a rendezvous removed a pair never shared");
    }
    ++rec.removed;
    rec.removed_correct += correct(s) ? 1 : 0;
  }
  for (const auto& s : o.new_shared) {
    if (correct(s)) ++rec.new_shared_correct;
    out.shared.push_back(s);
  }
  if (config.outlier_fraction > 0.0) {
    rec.injected = InjectWrongPairs(alpha, beta, o.new_shared.size(), config.outlier_fraction,
                                    outlier_rng, out.shared);
    out.injected += rec.injected;
  }
  out.bytes += static_cast<std::int64_t>(o.bytes_alpha_to_beta + o.bytes_beta_to_alpha);
  const std::set<int> ma = MappedObjects(alpha), mb = MappedObjects(beta);
  std::vector<int> now;
  std::set_intersection(ma.begin(), ma.end(), mb.begin(), mb.end(), std::back_inserter(now));
  rec.truly_shared = static_cast<int>(now.size());
  if (o.alignment) {
    rec.alignment = o.alignment->status;
    rec.alignment_support = o.alignment->support;
    rec.alignment_rival = o.alignment->rival;
    if (o.alignment->status == AlignmentStatus::kAligned) {
      int right = 0;
      for (const auto& [ka, kb] : o.alignment->pairs) {
        right += correct({Key::Object(e.beta, kb), Key::Object(e.alpha, ka)}) ? 1 : 0;
      }
      rec.alignment_wrong = 2 * right < static_cast<int>(o.alignment->pairs.size());
    }
  }
  out.rendezvous.push_back(rec);
  return now;
}

// The robots that met at step t, grouped by connection, each group handed to
// config.on_rendezvous.
void HandGroupsOn(int t, const std::vector<RendezvousEvent>& events_now,
                  const MultiRobotSlamConfig& config, MultiRobotSlamResult& out) {
  std::vector<int> robots;
  std::vector<std::pair<int, int>> links;
  for (const RendezvousEvent& e : events_now) {
    robots.insert(robots.end(), {e.alpha, e.beta});
    links.emplace_back(e.alpha, e.beta);
  }
  for (std::vector<int>& g : ConnectedRobots(robots, links)) {
    RendezvousGroup group{t, std::move(g), {}};
    for (int r : group.robots) {
      if (HasLeft(config, r, t)) group.gone.push_back(r);
    }
    config.on_rendezvous(group, out);
  }
}

}  // namespace

MultiRobotSlamResult RunMultiRobotObjectSlam(const SimulationData& data,
                                             const MultiRobotSlamConfig& config) {
  config.validate();
  const auto t0 = std::chrono::steady_clock::now();
  CheckSimulationFits(data, config);
  const int n = data.numRobots(), steps = data.numSteps();

  MultiRobotSlamResult out;
  out.robots.reserve(static_cast<std::size_t>(n));
  for (int r = 0; r < n; ++r) out.robots.emplace_back(r, config.slam);
  // Per pair of robots (lower id first): objects both had mapped at a rendezvous.
  std::map<std::pair<int, int>, std::set<int>> possible;
  std::mt19937_64 outlier_rng(config.outlier_seed);
  std::size_t next_event = 0;
  for (int t = 0; t < steps; ++t) {
    AddPoses(data, t, out.robots);
    std::vector<RendezvousEvent> events_now;
    for (; next_event < data.rendezvous.size() && data.rendezvous[next_event].step == t;
         ++next_event) {
      const RendezvousEvent& e = data.rendezvous[next_event];
      events_now.push_back(e);
      out.robots[static_cast<std::size_t>(e.alpha)].refresh(config.slam.iterations_per_update);
      out.robots[static_cast<std::size_t>(e.beta)].refresh(config.slam.iterations_per_update);
      if (HasLeft(config, e.alpha, t) || HasLeft(config, e.beta, t)) {  // nothing exchanged
        RendezvousRecord skipped;
        skipped.event = e;
        skipped.skipped = true;
        out.rendezvous.push_back(skipped);
        continue;
      }
      const std::vector<int> now = Meet(data, e, config, outlier_rng, out);
      auto& both = possible[{std::min(e.alpha, e.beta), std::max(e.alpha, e.beta)}];
      both.insert(now.begin(), now.end());
    }
    if (config.on_rendezvous) HandGroupsOn(t, events_now, config, out);
  }
  for (auto& robot : out.robots) {
    robot.optimize(config.final_iterations);
    out.intra += robot.associationStats();
  }
  out.inter = InterRobotAssociation(out.robots, out.shared, possible);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

JointProblem AssembleJointProblem(const std::vector<ObjectSlam>& robots,
                                  const std::vector<SharedObject>& shared, const Matrix6& lambda) {
  JointProblem p;
  p.num_robots = static_cast<int>(robots.size());
  for (const auto& robot : robots) {
    const PoseGraph g = robot.graph();
    for (const auto& f : g.factors()) p.graph.add(f);
    p.factor_objects.insert(p.factor_objects.end(), robot.factorObjects().begin(),
                            robot.factorObjects().end());
    for (const auto& [k, x] : robot.estimate()) p.initial.emplace(k, x);
    p.num_poses += robot.numPoses();
    p.num_landmarks += static_cast<int>(robot.landmarks().size());
  }
  for (const auto& s : shared) {
    for (const Key& k : {s.alpha_object, s.beta_object}) {
      if (!k.isObject() || p.initial.count(k) == 0) {
        throw InvalidInputError("AssembleJointProblem: shared object names " + ToString(k) +
                                ", which is not a landmark of any robot");
      }
    }
    p.graph.add(ObjectObjectFactor(s, lambda));
    p.factor_objects.push_back(ObjectSlam::kNoObservation);
    ++p.num_object_object;
  }
  if (!robots.empty() && robots.front().robot() == 0 && robots.front().numPoses() > 0) {
    std::set<int> unanchored;
    for (const Key& k : UnreachableFrom(p.graph, Key::Pose(0, 0))) unanchored.insert(k.robot);
    // A robot with a single pose and no detection has no factor: unanchored too.
    const std::set<Key> in_graph = p.graph.keys();
    for (const auto& [k, x] : p.initial) {
      if (k.robot != 0 && in_graph.count(k) == 0) unanchored.insert(k.robot);
    }
    p.unanchored_robots.assign(unanchored.begin(), unanchored.end());
  } else {
    for (const auto& robot : robots) p.unanchored_robots.push_back(robot.robot());
  }
  return p;
}

Values JointGroundTruth(const SimulationData& data, const std::vector<ObjectSlam>& robots) {
  if (robots.empty()) return {};
  if (static_cast<int>(robots.size()) > data.numRobots()) {
    throw InvalidInputError("JointGroundTruth: more robots than the simulation has");
  }
  const SE3 T0inv = data.trajectories.front().front().inverse();
  std::map<int, SE3> objects;
  for (const auto& o : data.world.objects) objects[o.id] = T0inv * o.pose;
  Values gt;
  for (const auto& robot : robots) {
    const auto r = static_cast<std::size_t>(robot.robot());
    if (r >= data.trajectories.size() ||
        robot.numPoses() > static_cast<int>(data.trajectories[r].size())) {
      throw InvalidInputError("JointGroundTruth: robot " + std::to_string(r) +
                              " does not match the simulation");
    }
    for (int i = 0; i < robot.numPoses(); ++i) {
      gt[Key::Pose(robot.robot(), static_cast<std::uint64_t>(i))] =
          T0inv * data.trajectories[r][static_cast<std::size_t>(i)];
    }
    for (const auto& lm : robot.landmarks()) {
      const auto it = objects.find(lm.true_object);
      if (it != objects.end()) gt[lm.key] = it->second;
    }
  }
  return gt;
}

}  // namespace moslam
