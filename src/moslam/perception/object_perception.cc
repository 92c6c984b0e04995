#include "moslam/perception/object_perception.h"

#include <chrono>
#include <cmath>
#include <filesystem>

#include "moslam/common/errors.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/object_models.h"

namespace moslam {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

PerceptionStatus FromRegistration(RegistrationStatus s) {
  switch (s) {
    case RegistrationStatus::kAccepted:
      return PerceptionStatus::kAccepted;
    case RegistrationStatus::kTooFewPoints:
      return PerceptionStatus::kTooFewPoints;
    case RegistrationStatus::kTooFewInliers:
      return PerceptionStatus::kTooFewInliers;
    case RegistrationStatus::kColourMismatch:
      return PerceptionStatus::kColourMismatch;
    case RegistrationStatus::kShapeMismatch:
      return PerceptionStatus::kShapeMismatch;
    case RegistrationStatus::kGicpFailed:
      break;
  }
  return PerceptionStatus::kGicpFailed;
}

}  // namespace

void PerceptionConfig::validate() const {
  detector.validate();
  segmentation.validate();
  registration.validate();
  if (!(template_spacing > 0.0) || !std::isfinite(template_spacing)) {
    throw InvalidInputError("PerceptionConfig: template_spacing must be positive and finite");
  }
  if (!templates_dir.empty() && !std::filesystem::is_directory(templates_dir)) {
    throw InvalidInputError("PerceptionConfig: templates_dir '" + templates_dir +
                            "' is not a directory");
  }
}

const char* ToString(PerceptionStatus status) {
  switch (status) {
    case PerceptionStatus::kAccepted:
      return "accepted";
    case PerceptionStatus::kNoTemplate:
      return "no_template";
    case PerceptionStatus::kSegmentationFailed:
      return "segmentation_failed";
    case PerceptionStatus::kTooFewPoints:
      return "too_few_points";
    case PerceptionStatus::kTooFewInliers:
      return "too_few_inliers";
    case PerceptionStatus::kGicpFailed:
      return "gicp_failed";
    case PerceptionStatus::kColourMismatch:
      return "colour_mismatch";
    case PerceptionStatus::kShapeMismatch:
      return "shape_mismatch";
  }
  return "unknown";
}

ObjectPerception::ObjectPerception(const PerceptionConfig& config,
                                   const std::vector<ObjectClass>& classes)
    : config_((config.validate(), config)), classes_(classes), detector_(config.detector) {}

const ObjectTemplate* ObjectPerception::findTemplate(const std::string& label) {
  auto it = templates_.find(label);
  if (it == templates_.end()) {
    const auto t0 = Clock::now();
    std::optional<ObjectTemplate> made;
    const std::filesystem::path pcd =
        config_.templates_dir.empty()
            ? std::filesystem::path()
            : std::filesystem::path(config_.templates_dir) / (label + ".pcd");
    if (!pcd.empty() && std::filesystem::exists(pcd)) {
      made = LoadObjectTemplate(pcd.string(), label, config_.registration.features);
    } else {
      for (const ObjectClass& c : classes_) {
        if (c.label != label) continue;
        const ColoredPointSet points = SampleVisibleSurface(
            MakeObjectMesh(c), config_.template_spacing, config_.template_seed);
        made = MakeObjectTemplate(label, points, config_.registration.features);
        break;
      }
    }
    template_seconds_ += MsSince(t0) / 1000.0;
    it = templates_.emplace(label, std::move(made)).first;
  }
  return it->second ? &*it->second : nullptr;
}

FramePerception ObjectPerception::perceive(const RgbdFrame& frame) {
  FramePerception out;
  auto t = Clock::now();
  const std::vector<Detection> detections = detector_.detect(frame.rgb);
  out.times.detect = MsSince(t);
  if (detections.empty()) return out;

  t = Clock::now();
  const OrganizedCloud::Ptr cloud = MakeOrganizedCloud(frame);
  const PreparedFrame prepared = PrepareSegmentation(cloud, config_.segmentation);
  out.times.prepare = MsSince(t);

  for (const Detection& d : detections) {
    PerceivedObject o;
    o.detection = d;
    const ObjectTemplate* tmpl = findTemplate(d.label);
    if (!tmpl) {
      out.objects.push_back(std::move(o));
      continue;
    }
    t = Clock::now();
    o.segmentation = SegmentObject(prepared, d.box, config_.segmentation);
    out.times.segment += MsSince(t);
    if (o.segmentation.status != SegmentationStatus::kOk) {
      o.status = PerceptionStatus::kSegmentationFailed;
      o.segmentation.segment.reset();
      out.objects.push_back(std::move(o));
      continue;
    }
    t = Clock::now();
    o.registration = RegisterTemplate(*o.segmentation.segment, *tmpl, config_.registration);
    out.times.register_ += MsSince(t);
    o.segmentation.segment.reset();
    o.status = FromRegistration(o.registration.status);
    if (o.accepted()) o.body_T_object = ObjectMeasurementInBody(o.registration.camera_T_object);
    out.objects.push_back(std::move(o));
  }
  return out;
}

std::vector<ObjectDetection> ToObjectDetections(const FramePerception& frame) {
  std::vector<ObjectDetection> out;
  for (const PerceivedObject& o : frame.objects) {
    if (!o.accepted()) continue;
    ObjectDetection d;
    d.label = o.detection.label;
    d.measurement = o.body_T_object;
    d.information = o.registration.information;
    d.object_id = -1;
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace moslam
