// Object measurements of a simulation made by the real front-end on rendered frames
// (`moslam simulate --perception rendered`), instead of sampled with Gaussian noise.
//
// For every robot and every `every`-th pose, the renderer (render/renderer.h) draws the RGB-D
// frame its camera sees (SimulationFrameKey(robot, pose): seeded, reproducible) and
// ObjectPerception (object_perception.h) turns it into object-pose measurements, which replace
// the sampled detections of that pose (other poses get none). Odometry stays as simulated.
//
// Evaluation against the renderer's ground truth: a detection is TRUE when its box overlaps the
// visible-pixel box of a rendered object of the same label with IoU >= 0.5 (the most overlapping
// one); its measurement then carries that object's id (ObjectDetection::object_id, used only by
// the association statistics), and, when accepted, its pose error against the true
// camera_T_object is recorded: translation |t - t*| and rotation angle of R*^T R.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "moslam/detection/evaluation.h"  // BoxIou
#include "moslam/perception/object_perception.h"
#include "moslam/render/renderer.h"
#include "moslam/sim/sensing.h"

namespace moslam {

struct RenderedSensingConfig {
  RenderConfig render;
  PerceptionConfig perception;
  int every = 1;  // perceive every `every`-th pose (1: all)
  // The true detections also counted apart for objects with at least this share of their
  // silhouette seen (VisibleObject::visibleFraction), the "30 % visible" population.
  double min_visible_fraction = 0.3;
  // Keep every detection's evaluation (RenderedSensingStats::records).
  bool record_detections = false;
  // m: an accepted view's ground-truth object (ObjectDetection::object_id, for evaluation only:
  // the robots' association precision, the rendezvous', the robust solve's wrong observations)
  // is the object its registered pose places, when a same-label object seen lies nearer it than
  // this; else the object of its box (MeasuredObject). Below half the least spacing of two
  // objects of one label in the worlds (house's kitchen chairs, 0.8 m); 0: always the box's.
  double same_object_radius = 0.25;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// True detections and accepted true ones, of all objects and of those seen enough
// (RenderedSensingConfig::min_visible_fraction).
struct AcceptanceCounts {
  int true_detections = 0, accepted = 0;
  int true_visible = 0, accepted_visible = 0;
};

// One detection as evaluated against the renderer's ground truth (record_detections).
struct DetectionRecord {
  int robot = 0;
  int pose = 0;                 // the trajectory index of the frame
  std::string label;
  PerceptionStatus status = PerceptionStatus::kNoTemplate;
  int object = -1;              // the true object's id (World::objects); -1: a false detection
  double visible_fraction = 0.0;  // the true object's (VisibleObject::visibleFraction); 0: false
  double depth = 0.0;           // the true object's centre z in the camera frame (m); 0: false
  // The pose the registration reported (accepted, or the rejected best or consensus pose) against
  // the true object's, as for the statistics; NaN when false or when no pose was registered
  // (no template, failed segmentation, too few points).
  double translation_error = std::numeric_limits<double>::quiet_NaN();
  double rotation_error_deg = std::numeric_limits<double>::quiet_NaN();
  // The registration's diagnostics (registration.h), of a registered detection.
  int inliers = 0, refined_inliers = -1, segment_points = 0;
  double geometric_agreement = 0.0, covered_agreement = 0.0, colour_agreement = 0.0;
};

struct RenderedSensingStats {
  int frames = 0;
  std::int64_t valid_depth_points = 0;     // pixels with a depth return, over the frames
  int detections = 0, accepted = 0;  // every detection, true or false
  // The true detections (IoU >= 0.5 with a same-label object) and the accepted ones, by label.
  std::map<std::string, AcceptanceCounts> by_class;
  // The same by the object's depth in the camera frame (the z of its centre), whole metres: bin k
  // holds [k, k + 1) m, the last bin (kDepthBins - 1) everything beyond. The sensor's depth
  // noise grows with it (render/rgbd.h: 1.4 cm at 3 m, 4.1 cm at 5 m, 8.4 cm at 7 m).
  static constexpr int kDepthBins = 8;
  std::map<int, AcceptanceCounts> by_depth;
  int rejected_inliers = 0, rejected_inliers_false = 0;  // the 12-inlier gate, and how many of
                                                         // those were false detections
  int segmentation_failed = 0, other_rejected = 0;
  std::vector<double> translation_errors;  // m, accepted true detections
  std::vector<double> rotation_errors_deg;
  // Accepted true detections more than 10 cm or 10 deg off, and of those the ones within 10 cm
  // of another same-label object seen (nearer it than the box's object): a measurement of
  // another object (a segment of a nearer object in front of the boxed one).
  int accepted_true_off = 0, accepted_true_other_object = 0;
  // Accepted detections that are not true (no same-label object box at IoU >= 0.5): the error of
  // their pose against the nearest same-label object seen in the frame, (m, deg); +inf when the
  // frame shows none. A small error is a real object whose box the detector drew otherwise (an
  // occluded object's full extent against its visible pixels), a large one a false measurement.
  std::vector<std::pair<double, double>> false_accepted_errors;
  std::vector<DetectionRecord> records;    // every detection, in order (record_detections)
  StageTimes times;                        // summed over the frames
  double render_ms = 0.0;
  double template_seconds = 0.0;
  // by_class summed over the classes.
  AcceptanceCounts total() const;
  // Medians of the errors (NaN when empty).
  double medianTranslationError() const;
  double medianRotationErrorDeg() const;
};

// The object seen with `label` whose true position (camera frame) lies nearest `camera_t_object`,
// and its distance (nullptr and infinity when none is seen).
std::pair<const VisibleObject*, double> NearestSeen(const std::vector<VisibleObject>& seen,
                                                    const std::string& label,
                                                    const Vector3& camera_t_object);

// The world object an accepted view measures, for evaluation: the object seen with the view's
// label nearest its registered position `camera_t_object` (NearestSeen), if nearer than
// `radius`; otherwise `box_object`, the object whose visible pixels the detection box matches
// (-1: none, a false detection). The box and the segment can disagree: a box drawn otherwise
// than the object's pixels counts as false though its segment registers to the object exactly,
// and the segment of a neighbour (another chair in the box) registers to that neighbour; both are
// views of the object their pose places, and the robots map them as such.
int MeasuredObject(const std::vector<VisibleObject>& seen, const std::string& label,
                   const Vector3& camera_t_object, int box_object, double radius);

// Replaces data.measurements[r].detections by the front-end's on rendered frames. Throws
// InvalidInputError on a bad config or data without measurements.
RenderedSensingStats PerceiveSimulation(SimulationData& data, const RenderedSensingConfig& config);

}  // namespace moslam
