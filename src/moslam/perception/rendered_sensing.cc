#include "moslam/perception/rendered_sensing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include "moslam/common/errors.h"
#include "moslam/common/statistics.h"

namespace moslam {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

// Angle of truth^-1 est's rotation, degrees.
double RotationErrorDeg(const SE3& truth, const SE3& est) {
  return SO3::Log(truth.rotation().inverse() * est.rotation()).norm() * kRadToDeg;
}

// The object a detection's box shows: the same-label object whose visible-pixel box it overlaps
// most, at IoU >= 0.5 (nullptr: a false detection).
const VisibleObject* BoxTruth(const std::vector<VisibleObject>& seen, const Detection& detection) {
  const VisibleObject* truth = nullptr;
  double best = 0.5;
  for (const VisibleObject& v : seen) {
    if (v.label != detection.label) continue;
    const double iou = BoxIou(detection.box, cv::Rect2f(v.box));
    if (iou >= best) {
      best = iou;
      truth = &v;
    }
  }
  return truth;
}

void AddTimes(StageTimes& sum, const StageTimes& t) {
  sum.detect += t.detect;
  sum.prepare += t.prepare;
  sum.segment += t.segment;
  sum.register_ += t.register_;
}

// One detection as the record keeps it (record_detections).
DetectionRecord MakeRecord(int robot, int pose, const PerceivedObject& o,
                           const VisibleObject* truth, bool registered, double t_error,
                           double r_error) {
  DetectionRecord rec;
  rec.robot = robot;
  rec.pose = pose;
  rec.label = o.detection.label;
  rec.status = o.status;
  rec.translation_error = t_error;
  rec.rotation_error_deg = r_error;
  if (truth) {
    rec.object = truth->id;
    rec.visible_fraction = truth->visibleFraction();
    rec.depth = truth->camera_T_object.translation().z();
  }
  if (registered) {
    const RegistrationResult& g = o.registration;
    rec.inliers = g.inliers;
    rec.refined_inliers = g.refined_inliers;
    rec.segment_points = g.segment_points;
    rec.geometric_agreement = g.geometric_agreement;
    rec.covered_agreement = g.covered_agreement;
    rec.colour_agreement = g.colour_agreement;
  }
  return rec;
}

// Evaluates one perceived object of pose `pose` of `robot` against what the frame shows (`seen`)
// into `stats`; the measurement it makes when accepted.
std::optional<ObjectDetection> Evaluate(const PerceivedObject& o,
                                        const std::vector<VisibleObject>& seen, int robot, int pose,
                                        const RenderedSensingConfig& config,
                                        RenderedSensingStats& stats) {
  ++stats.detections;
  const VisibleObject* truth = BoxTruth(seen, o.detection);
  AcceptanceCounts* of_class = nullptr;  // the true detection's class
  AcceptanceCounts* of_depth = nullptr;  // and its depth bin
  const bool visible = truth != nullptr && truth->visibleFraction() >= config.min_visible_fraction;
  if (truth) {
    of_class = &stats.by_class[o.detection.label];
    const double z = truth->camera_T_object.translation().z();
    of_depth = &stats.by_depth[std::clamp(static_cast<int>(std::floor(z)), 0,
                                          RenderedSensingStats::kDepthBins - 1)];
    for (AcceptanceCounts* c : {of_class, of_depth}) {
      ++c->true_detections;
      if (visible) ++c->true_visible;
    }
  }
  // The reported pose's error against the true object's (NaN: false, or no pose).
  const RegistrationResult& g = o.registration;
  const bool registered = o.status != PerceptionStatus::kNoTemplate &&
                          o.status != PerceptionStatus::kSegmentationFailed &&
                          o.status != PerceptionStatus::kTooFewPoints;
  double t_error = std::numeric_limits<double>::quiet_NaN(), r_error = t_error;
  if (truth && registered) {
    t_error = (g.camera_T_object.translation() - truth->camera_T_object.translation()).norm();
    r_error = RotationErrorDeg(truth->camera_T_object, g.camera_T_object);
  }
  if (config.record_detections) {
    stats.records.push_back(MakeRecord(robot, pose, o, truth, registered, t_error, r_error));
  }
  switch (o.status) {
    case PerceptionStatus::kAccepted:
      break;
    case PerceptionStatus::kTooFewInliers:
      ++stats.rejected_inliers;
      if (!truth) ++stats.rejected_inliers_false;
      return std::nullopt;
    case PerceptionStatus::kSegmentationFailed:
      ++stats.segmentation_failed;
      return std::nullopt;
    default:
      ++stats.other_rejected;
      return std::nullopt;
  }
  ++stats.accepted;
  ObjectDetection d;
  d.label = o.detection.label;
  d.measurement = o.body_T_object;
  d.information = o.registration.information;
  // The same-label object seen nearest the pose, and the pose's error against it.
  const SE3& est = g.camera_T_object;
  const auto [nearest, nearest_t] = NearestSeen(seen, o.detection.label, est.translation());
  if (!truth) {
    stats.false_accepted_errors.emplace_back(
        nearest_t, nearest ? RotationErrorDeg(nearest->camera_T_object, est)
                           : std::numeric_limits<double>::infinity());
  } else {
    for (AcceptanceCounts* c : {of_class, of_depth}) {
      ++c->accepted;
      if (visible) ++c->accepted_visible;
    }
    stats.translation_errors.push_back(t_error);
    stats.rotation_errors_deg.push_back(r_error);
    if (t_error > 0.1 || r_error > 10.0) {
      ++stats.accepted_true_off;
      if (nearest != truth && nearest_t <= 0.1) ++stats.accepted_true_other_object;
    }
  }
  d.object_id = MeasuredObject(seen, d.label, est.translation(), truth ? truth->id : -1,
                               config.same_object_radius);
  return d;
}

}  // namespace

void RenderedSensingConfig::validate() const {
  render.validate();
  perception.validate();
  if (every < 1) throw InvalidInputError("RenderedSensingConfig: every must be >= 1");
  if (!(min_visible_fraction >= 0.0 && min_visible_fraction <= 1.0)) {
    throw InvalidInputError("RenderedSensingConfig: min_visible_fraction must be in [0, 1]");
  }
  if (!(same_object_radius >= 0.0) || !std::isfinite(same_object_radius)) {
    throw InvalidInputError("RenderedSensingConfig: same_object_radius must be finite and >= 0");
  }
}

std::pair<const VisibleObject*, double> NearestSeen(const std::vector<VisibleObject>& seen,
                                                    const std::string& label,
                                                    const Vector3& camera_t_object) {
  const VisibleObject* nearest = nullptr;
  double distance = std::numeric_limits<double>::infinity();
  for (const VisibleObject& v : seen) {
    if (v.label != label) continue;
    const double d = (v.camera_T_object.translation() - camera_t_object).norm();
    if (d < distance) {
      distance = d;
      nearest = &v;
    }
  }
  return {nearest, distance};
}

int MeasuredObject(const std::vector<VisibleObject>& seen, const std::string& label,
                   const Vector3& camera_t_object, int box_object, double radius) {
  const auto [nearest, distance] = NearestSeen(seen, label, camera_t_object);
  return nearest != nullptr && distance < radius ? nearest->id : box_object;
}

AcceptanceCounts RenderedSensingStats::total() const {
  AcceptanceCounts sum;
  for (const auto& [label, c] : by_class) {
    sum.true_detections += c.true_detections;
    sum.accepted += c.accepted;
    sum.true_visible += c.true_visible;
    sum.accepted_visible += c.accepted_visible;
  }
  return sum;
}

double RenderedSensingStats::medianTranslationError() const { return Median(translation_errors); }
double RenderedSensingStats::medianRotationErrorDeg() const { return Median(rotation_errors_deg); }


RenderedSensingStats PerceiveSimulation(SimulationData& data,
                                        const RenderedSensingConfig& config) {
  config.validate();
  if (data.measurements.size() != data.trajectories.size()) {
    throw InvalidInputError("PerceiveSimulation: the simulation has " +
                            std::to_string(data.measurements.size()) + " measurement sets for " +
                            std::to_string(data.trajectories.size()) + " robots");
  }
  const Renderer renderer(data.world, config.render);
  ObjectPerception perception(config.perception, data.world.classes);
  RenderedSensingStats stats;
  stats.template_seconds = perception.templateSeconds();

  for (int r = 0; r < data.numRobots(); ++r) {
    RobotMeasurements& m = data.measurements[static_cast<std::size_t>(r)];
    const Trajectory& trajectory = data.trajectories[static_cast<std::size_t>(r)];
    m.detections.assign(trajectory.size(), {});
    for (std::size_t i = 0; i < trajectory.size(); i += static_cast<std::size_t>(config.every)) {
      const auto t0 = std::chrono::steady_clock::now();
      const RenderedFrame frame =
          renderer.render(trajectory[i], SimulationFrameKey(r, i), static_cast<double>(i));
      stats.render_ms += std::chrono::duration<double, std::milli>(
                             std::chrono::steady_clock::now() - t0)
                             .count();
      const FramePerception seen = perception.perceive(frame.rgbd);
      ++stats.frames;
      stats.valid_depth_points += cv::countNonZero(frame.rgbd.depth > 0.0f);
      AddTimes(stats.times, seen.times);
      for (const PerceivedObject& o : seen.objects) {
        std::optional<ObjectDetection> d =
            Evaluate(o, frame.objects, r, static_cast<int>(i), config, stats);
        if (d) m.detections[i].push_back(std::move(*d));
      }
    }
  }
  return stats;
}

}  // namespace moslam
