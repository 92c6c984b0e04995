// The perception front-end as one stage chain (paper Section 2.1): an RGB-D frame in, object-pose
// measurements out.
//
//   detect    Detector (detection/detector.h): YOLO-style boxes, class probability >= 0.3, NMS;
//   segment   PrepareSegmentation once per frame, SegmentObject per box
//             (pose_estimation/segmentation.h): the object's points, scene planes removed;
//   register  RegisterTemplate (pose_estimation/registration.h) against the template of the
//             box's class: PFHRGB + SAC-IA, rejected with fewer than 12 inlier correspondences,
//             refined by GICP; camera_T_object and an information matrix.
// An accepted object becomes the measurement x_i^-1 o_k = BodyFromCamera() * camera_T_object
// (render/rgbd.h: the camera at the body origin looking along body x) with the registration's
// information (tangent order (w, v), CONVENTIONS.md).
//
// Templates: one per class the detector knows and `classes` describes, built once, when the
// class is first detected, from the class's procedural model (render/object_models.h,
// SampleVisibleSurface at template_spacing; the features from rendered views of it,
// template_views), or read from `templates_dir`/<label>.pcd when that
// file exists (your own scanned models; format in pose_estimation/object_template.h). With
// `template_cache_dir`, the built template (its PFHRGB features: 0.3-2.5 s per class) is stored
// there and read back at the next start (pose_estimation/template_cache.h: keyed by the model's
// points and the FeatureConfig; a damaged or stale entry is rebuilt, with a note in
// templateNotes()). A detected class without a template is reported (status kNoTemplate), never
// registered.
//
// Threads: the detections of a frame are segmented and registered on up to `threads` threads
// (results in detection order, identical for any thread count: the registration draws its random
// samples from its own seeded generator). SAC-IA (Consensus::kSacIa) draws with rand(), so with it
// the detections run one after another.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "moslam/detection/detector.h"
#include "moslam/perception/view_template.h"
#include "moslam/pose_estimation/object_template.h"
#include "moslam/pose_estimation/registration.h"
#include "moslam/pose_estimation/segmentation.h"
#include "moslam/render/rgbd.h"
#include "moslam/sim/sensing.h"
#include "moslam/sim/world.h"

namespace moslam {

struct PerceptionConfig {
  DetectorConfig detector;
  SegmentationConfig segmentation;
  RegistrationConfig registration;  // registration.features: the templates' feature parameters
  double template_spacing = 0.01;   // m between samples of a class model
  unsigned template_seed = 1;
  // The built-in models' features come from rendered views of the model, at the robots' camera
  // height (segmentation.camera_height; perception/view_template.h); 0 views: from the whole
  // model. A templates_dir PCD has no views: its features are the whole cloud's.
  TemplateViews template_views;
  std::string templates_dir;        // optional <label>.pcd overrides
  std::string template_cache_dir;   // optional on-disk cache of built templates ("" = none)
  int threads = 2;                  // detections of a frame registered in parallel (>= 1)
  // A registered pose is accepted only if the template's projection at it (its pixel bounding
  // box, clipped to the image) overlaps the detection box with IoU >= min_box_agreement: a
  // segment of another object (a nearer one in front of the detected object) registers well, to
  // the wrong object. An occluded object's box is part of its projection, so the IoU of a right
  // pose falls with occlusion. 0 turns the check off. Chosen on the simulations of seeds 11-13
  // (chairs25 and house, README).
  double min_box_agreement = 0.4;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

enum class PerceptionStatus {
  kAccepted,          // registered: a measurement
  kNoTemplate,        // the detected class has no template
  kSegmentationFailed,
  kTooFewPoints,      // registration: too few points after voxelling
  kTooFewInliers,     // registration: the 12-inlier gate
  kGicpFailed,
  kColourMismatch,    // registration: the best pose's colours disagree with the template's
  kShapeMismatch,     // registration: the best pose's points do not lie on the template
  kBoxMismatch,       // the template at the registered pose does not project onto the box
};
const char* ToString(PerceptionStatus status);

struct PerceivedObject {
  Detection detection;
  PerceptionStatus status = PerceptionStatus::kNoTemplate;
  SegmentationResult segmentation;  // its segment cloud is dropped (nullptr) to keep this small
  RegistrationResult registration;  // meaningful once segmentation succeeded
  SE3 body_T_object;                // the measurement x_i^-1 o_k (accepted only)
  // IoU of the detection box with the template's projection at the registered pose (computed
  // for every pose the registration accepted; PerceptionConfig::min_box_agreement).
  double box_agreement = 0.0;
  bool accepted() const { return status == PerceptionStatus::kAccepted; }
};

struct StageTimes {  // milliseconds
  double detect = 0.0;
  double prepare = 0.0;   // normals + planes of the frame
  double segment = 0.0;   // all boxes
  double register_ = 0.0; // all boxes
  double total() const { return detect + prepare + segment + register_; }
};

struct FramePerception {
  std::vector<PerceivedObject> objects;  // one per detection, in detection order
  StageTimes times;
};

class ObjectPerception {
 public:
  // Loads the detector. Throws InvalidInputError on a bad config or an unreadable model; an
  // unreadable template file throws from perceive() / findTemplate() when its class is needed.
  ObjectPerception(const PerceptionConfig& config, const std::vector<ObjectClass>& classes);

  // Runs the chain on one frame. Throws InvalidInputError when the frame is inconsistent with
  // its intrinsics.
  FramePerception perceive(const RgbdFrame& frame);

  const PerceptionConfig& config() const { return config_; }
  // The template of a class, built on first use; nullptr when the class has none.
  const ObjectTemplate* findTemplate(const std::string& label);
  // Time spent building (or reading) templates so far.
  double templateSeconds() const { return template_seconds_; }
  // Templates read from the cache so far, and why an entry could not be used or stored.
  int templatesFromCache() const { return templates_from_cache_; }
  const std::vector<std::string>& templateNotes() const { return template_notes_; }

 private:
  // The template of a class from the cache or built (and cached), without its feature index;
  // nullopt when the class has none.
  std::optional<ObjectTemplate> makeTemplate(const std::string& label);

  PerceptionConfig config_;
  std::vector<ObjectClass> classes_;
  Detector detector_;
  std::map<std::string, std::optional<ObjectTemplate>> templates_;  // nullopt: class has none
  double template_seconds_ = 0.0;
  int templates_from_cache_ = 0;
  std::vector<std::string> template_notes_;
};

// The accepted objects as SLAM measurements (sim/sensing.h; object_id = -1: unknown).
// The pixel bounding box of `cloud` (object frame) at camera_T_object, clipped to the image;
// empty when no point lies in front of the camera or inside the image.
cv::Rect2f ProjectedBox(const FeatureCloud& cloud, const SE3& camera_T_object,
                        const PinholeIntrinsics& intrinsics);

std::vector<ObjectDetection> ToObjectDetections(const FramePerception& frame);

}  // namespace moslam
