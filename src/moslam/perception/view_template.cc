#include "moslam/perception/view_template.h"

#include <pcl/common/transforms.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/renderer.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kMinViewPoints = 30;  // a view with fewer prepared points adds nothing

// The object's pixels of a rendered frame (camera frame).
OrganizedCloud ObjectPixels(const RenderedFrame& frame, int object_id) {
  const OrganizedCloud::Ptr organized = MakeOrganizedCloud(frame.rgbd);
  const std::size_t width = static_cast<std::size_t>(frame.rgbd.intrinsics.width);
  OrganizedCloud object;
  for (std::size_t i = 0; i < organized->size(); ++i) {
    const Eigen::Vector2i px = PixelOfIndex(i, width);
    if (frame.instance_ids.at<int>(px.y(), px.x()) == object_id) {
      object.push_back(organized->points[i]);
    }
  }
  return object;
}

}  // namespace

void TemplateViews::validate() const {
  if (views < 0) throw InvalidInputError("TemplateViews: views must be >= 0");
  if (!(distance > 0.0) || !std::isfinite(distance)) {
    throw InvalidInputError("TemplateViews: distance must be positive and finite");
  }
  if (!(min_extent >= 0.0) || !std::isfinite(min_extent)) {
    throw InvalidInputError("TemplateViews: min_extent must be >= 0 and finite");
  }
}

bool UsesViews(const ObjectClass& cls, const TemplateViews& views) {
  return views.views > 0 && std::max(cls.extent.x(), cls.extent.y()) >= views.min_extent;
}

ObjectTemplate MakeViewTemplate(const ObjectClass& cls, const FeatureCloud& model_cloud,
                                const FeatureConfig& features, const TemplateViews& views,
                                double camera_height) {
  views.validate();
  features.validate();
  if (views.views < 1) {
    throw InvalidInputError("MakeViewTemplate(" + cls.label + "): views must be >= 1");
  }
  if (!std::isfinite(camera_height)) {
    throw InvalidInputError("MakeViewTemplate(" + cls.label + "): camera_height must be finite");
  }
  World world;
  world.name = "template-views";
  world.classes = {cls};
  const double half = views.distance + cls.extent.norm() + 1.0;
  world.rooms.push_back({"room", Vector2(-half, -half), Vector2(half, half)});
  world.objects.push_back({0, cls.label, SE3(SO3(), Vector3(0.0, 0.0, 0.5 * cls.extent.z()))});
  RenderConfig render;
  render.draw_walls = false;
  render.depth_noise = false;
  render.quantize_depth = false;
  render.colour_noise_sigma = 0.0;
  const Renderer renderer(world, render);

  auto keypoints = std::make_shared<FeatureCloud>();
  auto pooled = std::make_shared<PfhrgbCloud>();
  for (int k = 0; k < views.views; ++k) {
    const double azimuth = 2.0 * kPi * k / views.views;
    const Vector3 camera(-views.distance * std::cos(azimuth), -views.distance * std::sin(azimuth),
                         camera_height);
    const RenderedFrame frame = renderer.render(SE3(SO3::Exp(Vector3(0.0, 0.0, azimuth)), camera));
    if (frame.objects.empty()) continue;
    const FeatureCloud::Ptr surface =
        pose_detail::PrepareSurface(ObjectPixels(frame, frame.objects[0].id), features,
                                    kMinViewPoints);
    if (surface->size() < kMinViewPoints) continue;
    FeatureCloud::Ptr view_keypoints = pose_detail::Keypoints(*surface, features.keypoint_voxel);
    const PfhrgbCloud::Ptr view_features =
        pose_detail::ComputePfhrgb(surface, view_keypoints, features);
    FeatureCloud in_object;
    pcl::transformPointCloudWithNormals(
        *view_keypoints, in_object,
        frame.objects[0].camera_T_object.inverse().matrix().cast<float>());
    *keypoints += in_object;
    *pooled += *view_features;
  }
  return AssembleObjectTemplate(cls.label, model_cloud, keypoints, pooled, features);
}

std::uint64_t ViewDigest(std::uint64_t source_digest, const TemplateViews& views,
                         double camera_height) {
  // Bump when the rule (view placement, rendering, preparation) changes.
  constexpr std::uint32_t kViewRuleVersion = 1;
  std::uint64_t h = Fnv1a64(&source_digest, sizeof(source_digest));
  h = Fnv1a64(&kViewRuleVersion, sizeof(kViewRuleVersion), h);
  h = Fnv1a64(&views.views, sizeof(views.views), h);
  h = Fnv1a64(&views.distance, sizeof(views.distance), h);
  return Fnv1a64(&camera_height, sizeof(camera_height), h);
}

}  // namespace moslam
