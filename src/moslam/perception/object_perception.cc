#include "moslam/perception/object_perception.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>

#include "moslam/common/errors.h"
#include "moslam/common/workers.h"
#include "moslam/detection/evaluation.h"
#include "moslam/pose_estimation/feature_index.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/pose_estimation/template_cache.h"
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

// Everything SampleVisibleSurface reads from a model, with the sampling parameters and a version
// of the sampler (bump kSamplerVersion when SampleVisibleSurface or ModelCloud changes).
std::uint64_t MeshDigest(const Mesh& mesh, double spacing, unsigned seed) {
  constexpr std::uint32_t kSamplerVersion = 1;
  std::uint64_t h = Fnv1a64(&kSamplerVersion, sizeof(kSamplerVersion));
  h = Fnv1a64(mesh.vertices.data(), mesh.vertices.size() * sizeof(Vector3), h);
  h = Fnv1a64(mesh.triangles.data(), mesh.triangles.size() * sizeof(Eigen::Vector3i), h);
  h = Fnv1a64(mesh.triangle_material.data(), mesh.triangle_material.size() * sizeof(int), h);
  for (const Material& m : mesh.materials) {
    h = Fnv1a64(m.colour_bgr.val, 3, h);
    h = Fnv1a64(m.secondary_bgr.val, 3, h);
    const auto pattern = static_cast<int>(m.pattern);
    h = Fnv1a64(&pattern, sizeof(pattern), h);
    h = Fnv1a64(&m.axis, sizeof(m.axis), h);
    h = Fnv1a64(&m.period_m, sizeof(m.period_m), h);
  }
  h = Fnv1a64(mesh.gradient.data(), 3 * sizeof(double), h);
  const unsigned char closed = mesh.closed ? 1 : 0;
  h = Fnv1a64(&closed, 1, h);
  h = Fnv1a64(&spacing, sizeof(spacing), h);
  return Fnv1a64(&seed, sizeof(seed), h);
}

// A template's source: a PCD override (`cloud`), or the class model, sampled only on a cache miss
// (`sample`: sampling with visibility costs as much as the features), whose views give the
// features when the class uses them (`model_class`). `digest` identifies it for the cache. Neither
// cloud nor sample: the class has no template.
struct TemplateSource {
  std::optional<FeatureCloud> cloud;
  std::function<FeatureCloud()> sample;
  const ObjectClass* model_class = nullptr;
  std::uint64_t digest = 0;
};

TemplateSource FindTemplateSource(const std::string& label, const PerceptionConfig& config,
                                  const std::vector<ObjectClass>& classes) {
  TemplateSource source;
  const std::filesystem::path pcd =
      config.templates_dir.empty() ? std::filesystem::path()
                                   : std::filesystem::path(config.templates_dir) / (label + ".pcd");
  if (!pcd.empty() && std::filesystem::exists(pcd)) {
    source.cloud = ReadTemplateCloud(pcd.string());
    source.digest = CloudDigest(*source.cloud);
    return source;
  }
  for (const ObjectClass& c : classes) {
    if (c.label != label) continue;
    const Mesh mesh = MakeObjectMesh(c);
    source.digest = MeshDigest(mesh, config.template_spacing, config.template_seed);
    if (UsesViews(c, config.template_views)) {
      source.model_class = &c;
      source.digest =
          ViewDigest(source.digest, config.template_views, config.segmentation.camera_height);
    }
    const double spacing = config.template_spacing;
    const unsigned seed = config.template_seed;
    source.sample = [mesh, label, spacing, seed] {
      return ModelCloud(SampleVisibleSurface(mesh, spacing, seed), label);
    };
    break;
  }
  return source;
}

// One detection through segmentation and registration against its class's template, then the
// agreement of the registered template's projected box with the detection's box; the stages'
// thread times in milliseconds.
void PerceiveDetection(const PreparedFrame& prepared, const ObjectTemplate& object_template,
                       const PinholeIntrinsics& intrinsics, const PerceptionConfig& config,
                       PerceivedObject& o, double* segment_ms, double* register_ms) {
  auto t0 = Clock::now();
  o.segmentation = SegmentObject(prepared, o.detection.box, config.segmentation);
  *segment_ms = MsSince(t0);
  if (o.segmentation.status != SegmentationStatus::kOk) {
    o.status = PerceptionStatus::kSegmentationFailed;
    o.segmentation.segment.reset();
    return;
  }
  t0 = Clock::now();
  o.registration = RegisterTemplate(*o.segmentation.segment, object_template, config.registration);
  *register_ms = MsSince(t0);
  o.segmentation.segment.reset();
  o.status = FromRegistration(o.registration.status);
  if (o.registration.status == RegistrationStatus::kAccepted) {
    o.box_agreement =
        BoxIou(o.detection.box,
               ProjectedBox(*object_template.cloud, o.registration.camera_T_object, intrinsics));
    if (o.box_agreement < config.min_box_agreement) o.status = PerceptionStatus::kBoxMismatch;
  }
  if (o.accepted()) o.body_T_object = ObjectMeasurementInBody(o.registration.camera_T_object);
}

}  // namespace

cv::Rect2f ProjectedBox(const FeatureCloud& cloud, const SE3& camera_T_object,
                        const PinholeIntrinsics& k) {
  double u0 = k.width, v0 = k.height, u1 = 0.0, v1 = 0.0;
  for (const FeaturePoint& p : cloud) {
    const auto uv = Project(k, camera_T_object.transformFrom(Vector3(p.x, p.y, p.z)));
    if (!uv) continue;
    u0 = std::min(u0, uv->x());
    v0 = std::min(v0, uv->y());
    u1 = std::max(u1, uv->x());
    v1 = std::max(v1, uv->y());
  }
  u0 = std::max(u0, 0.0);
  v0 = std::max(v0, 0.0);
  u1 = std::min(u1, static_cast<double>(k.width));
  v1 = std::min(v1, static_cast<double>(k.height));
  if (u1 <= u0 || v1 <= v0) return {};
  return cv::Rect2f(static_cast<float>(u0), static_cast<float>(v0), static_cast<float>(u1 - u0),
                    static_cast<float>(v1 - v0));
}

void PerceptionConfig::validate() const {
  detector.validate();
  segmentation.validate();
  registration.validate();
  if (!(template_spacing > 0.0) || !std::isfinite(template_spacing)) {
    throw InvalidInputError("PerceptionConfig: template_spacing must be positive and finite");
  }
  template_views.validate();
  if (threads < 1) throw InvalidInputError("PerceptionConfig: threads must be >= 1");
  if (!(min_box_agreement >= 0.0 && min_box_agreement <= 1.0)) {
    throw InvalidInputError("PerceptionConfig: min_box_agreement must be in [0, 1]");
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
    case PerceptionStatus::kBoxMismatch:
      return "box_mismatch";
  }
  return "unknown";
}

ObjectPerception::ObjectPerception(const PerceptionConfig& config,
                                   const std::vector<ObjectClass>& classes)
    : config_((config.validate(), config)), classes_(classes), detector_(config.detector) {}

const ObjectTemplate* ObjectPerception::findTemplate(const std::string& label) {
  auto it = templates_.find(label);
  if (it != templates_.end()) return it->second ? &*it->second : nullptr;
  const auto t0 = Clock::now();
  std::optional<ObjectTemplate> made = makeTemplate(label);
  // A template from the cache has no feature index yet (the decoder stays free of PCL's k-d
  // trees); every registration of this class shares the one built here on first use.
  if (made && !made->feature_index) {
    made->feature_index = std::make_shared<const TemplateFeatureIndex>(made->features);
  }
  template_seconds_ += MsSince(t0) / 1000.0;
  it = templates_.emplace(label, std::move(made)).first;
  return it->second ? &*it->second : nullptr;
}

std::optional<ObjectTemplate> ObjectPerception::makeTemplate(const std::string& label) {
  const TemplateSource source = FindTemplateSource(label, config_, classes_);
  if (!source.cloud && !source.sample) return std::nullopt;
  const FeatureConfig& features = config_.registration.features;
  auto build = [&] {
    if (source.model_class != nullptr) {
      return MakeViewTemplate(*source.model_class, source.sample(), features,
                              config_.template_views, config_.segmentation.camera_height);
    }
    return MakeObjectTemplate(label, source.cloud ? *source.cloud : source.sample(), features);
  };
  if (config_.template_cache_dir.empty()) return build();
  const TemplateCache cache(config_.template_cache_dir);
  const std::uint64_t key = TemplateFingerprint(label, source.digest, features);
  std::string why_not;
  std::optional<ObjectTemplate> made = cache.load(label, key, features, &why_not);
  if (made) {
    ++templates_from_cache_;
    return made;
  }
  if (!why_not.empty()) template_notes_.push_back(why_not);
  made = build();
  try {
    cache.store(*made, key);
  } catch (const InvalidInputError& e) {
    template_notes_.push_back(e.what());  // perception goes on without the cache
  }
  return made;
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

  // Templates first (building one mutates the map), then the detections on the worker threads.
  out.objects.resize(detections.size());
  std::vector<const ObjectTemplate*> templates(detections.size());
  for (std::size_t i = 0; i < detections.size(); ++i) {
    out.objects[i].detection = detections[i];
    templates[i] = findTemplate(detections[i].label);
  }
  std::vector<double> segment_ms(detections.size(), 0.0), register_ms(detections.size(), 0.0);
  auto run = [&](std::size_t i) {
    if (!templates[i]) return;
    PerceiveDetection(prepared, *templates[i], frame.intrinsics, config_, out.objects[i],
                      &segment_ms[i], &register_ms[i]);
  };
  const std::size_t workers =
      config_.registration.consensus == Consensus::kSacIa
          ? 1
          : std::min(detections.size(), static_cast<std::size_t>(config_.threads));
  t = Clock::now();
  ForEachOnWorkers(detections.size(), workers, run);
  // Wall clock of the parallel section, split between the stages by their summed thread times.
  const double wall = MsSince(t);
  double seg_sum = 0.0, reg_sum = 0.0;
  for (std::size_t i = 0; i < detections.size(); ++i) {
    seg_sum += segment_ms[i];
    reg_sum += register_ms[i];
  }
  const double scale = seg_sum + reg_sum > 0.0 ? wall / (seg_sum + reg_sum) : 0.0;
  out.times.segment = seg_sum * scale;
  out.times.register_ = reg_sum * scale;
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
