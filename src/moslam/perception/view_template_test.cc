// Template features from rendered views (view_template.h).
#include "moslam/perception/view_template.h"

#include <gtest/gtest.h>

#include <pcl/kdtree/kdtree_flann.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/pose_estimation/registration.h"
#include "moslam/pose_estimation/segmentation.h"
#include "moslam/render/object_models.h"
#include "moslam/render/renderer.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

ObjectClass Chair() {
  World w;
  w.classes = StandardObjectClasses();
  return *w.findClass("chair");
}

FeatureCloud ModelOf(const ObjectClass& cls) {
  return ModelCloud(SampleVisibleSurface(MakeObjectMesh(cls), 0.01, 1u), cls.label);
}

TEST(ViewTemplate, PoolsTheViewsKeypointsOnTheModelSurfaceInTheObjectFrame) {
  const ObjectClass chair = Chair();
  const FeatureCloud model = ModelOf(chair);
  const FeatureConfig features;
  const ObjectTemplate one = MakeViewTemplate(chair, model, features, TemplateViews{1, 2.5}, 0.5);
  const ObjectTemplate eight = MakeViewTemplate(chair, model, features, TemplateViews{8, 2.5}, 0.5);
  ASSERT_EQ(eight.keypoints->size(), eight.features->size());
  // Eight views see more of the chair than one, and pool each view's keypoints.
  EXPECT_GT(eight.keypoints->size(), 3 * one.keypoints->size());
  // Every keypoint lies on the model in the object frame (a keypoint is a centroid of the
  // view's 2 cm voxels in a 3 cm cell: within a centimetre or two of the surface), not in the
  // camera frame it was computed in (2.5 m away).
  pcl::KdTreeFLANN<FeaturePoint> tree;
  tree.setInputCloud(eight.cloud);
  std::vector<double> distances;
  std::vector<int> index(1);
  std::vector<float> squared(1);
  for (const FeaturePoint& k : eight.keypoints->points) {
    ASSERT_EQ(tree.nearestKSearch(k, 1, index, squared), 1);
    distances.push_back(std::sqrt(static_cast<double>(squared[0])));
  }
  std::sort(distances.begin(), distances.end());
  EXPECT_LT(distances[distances.size() / 2], 0.01);
  EXPECT_LT(distances[distances.size() * 95 / 100], 0.02);
  // The cloud for GICP and scoring is the whole model's, voxelled as MakeObjectTemplate does.
  EXPECT_EQ(eight.cloud->size(), MakeObjectTemplate("chair", model, features).cloud->size());
}

TEST(ViewTemplate, RegistersRenderedChairViewsBetweenItsViewpoints) {
  const ObjectClass chair = Chair();
  const RegistrationConfig config;
  const ObjectTemplate tmpl =
      MakeViewTemplate(chair, ModelOf(chair), config.features, TemplateViews{}, 0.5);
  World world;
  world.name = "one chair";
  world.classes = {chair};
  world.rooms.push_back({"room", Vector2(-5.0, -5.0), Vector2(5.0, 5.0)});
  const SegmentationConfig segmentation;
  // Viewpoints between the template's (every 45 deg from 0) and at other distances.
  for (int k = 0; k < 4; ++k) {
    const double yaw = 0.4 + 1.7 * k;
    world.objects = {{3, "chair", SE3(SO3::Exp(Vector3(0.0, 0.0, yaw)),
                                      Vector3(0.0, 0.0, 0.5 * chair.extent.z()))}};
    const double bearing = 0.3 + 2.1 * k, distance = 1.6 + 0.4 * k;
    const SE3 body(SO3::Exp(Vector3(0.0, 0.0, bearing)),
                   Vector3(-distance * std::cos(bearing), -distance * std::sin(bearing), 0.5));
    const RenderedFrame frame = Renderer(world, RenderConfig{}).render(body, 10u + k);
    ASSERT_EQ(frame.objects.size(), 1u);
    const SegmentationResult segment =
        SegmentObject(PrepareSegmentation(MakeOrganizedCloud(frame.rgbd), segmentation),
                      cv::Rect2f(frame.objects[0].box), segmentation);
    ASSERT_EQ(segment.status, SegmentationStatus::kOk) << "view " << k;
    const RegistrationResult r = RegisterTemplate(*segment.segment, tmpl, config);
    ASSERT_TRUE(r.accepted()) << "view " << k << ": " << ToString(r.status);
    const SE3& truth = frame.objects[0].camera_T_object;
    EXPECT_LT((r.camera_T_object.translation() - truth.translation()).norm(), 0.05) << k;
    EXPECT_LT(SO3::Log(truth.rotation().inverse() * r.camera_T_object.rotation()).norm(),
              5.0 * kPi / 180.0)
        << "view " << k;
  }
}

TEST(ViewTemplate, RefusesABadConfig) {
  const ObjectClass chair = Chair();
  const FeatureCloud model = ModelOf(chair);
  EXPECT_THROW((TemplateViews{-1, 2.5}.validate()), InvalidInputError);
  EXPECT_THROW((TemplateViews{8, 0.0}.validate()), InvalidInputError);
  EXPECT_THROW((TemplateViews{8, std::nan("")}.validate()), InvalidInputError);
  EXPECT_NO_THROW((TemplateViews{0, 2.5}.validate()));  // 0: the whole model's features
  EXPECT_THROW(MakeViewTemplate(chair, model, FeatureConfig{}, TemplateViews{0, 2.5}, 0.5),
               InvalidInputError);
  EXPECT_THROW(MakeViewTemplate(chair, model, FeatureConfig{}, TemplateViews{}, std::nan("")),
               InvalidInputError);
}

TEST(ViewTemplate, LargeClassesOnlyByDefault) {
  World w;
  w.classes = StandardObjectClasses();
  const TemplateViews views;
  EXPECT_FALSE(UsesViews(*w.findClass("chair"), views));   // 0.5 x 0.5 m
  EXPECT_FALSE(UsesViews(*w.findClass("fridge"), views));  // 0.7 x 0.7 m
  EXPECT_TRUE(UsesViews(*w.findClass("shelf"), views));    // 0.35 x 0.8 m
  EXPECT_TRUE(UsesViews(*w.findClass("sofa"), views));
  EXPECT_TRUE(UsesViews(*w.findClass("chair"), TemplateViews{8, 2.5, 0.0}));
  EXPECT_FALSE(UsesViews(*w.findClass("sofa"), TemplateViews{0, 2.5, 0.8}));
  EXPECT_THROW((TemplateViews{8, 2.5, -0.1}.validate()), InvalidInputError);
}

TEST(ViewTemplate, TheDigestChangesWithEveryViewParameter) {
  const std::uint64_t base = ViewDigest(42, TemplateViews{}, 0.5);
  EXPECT_EQ(base, ViewDigest(42, TemplateViews{}, 0.5));
  EXPECT_NE(base, ViewDigest(43, TemplateViews{}, 0.5));
  EXPECT_NE(base, ViewDigest(42, TemplateViews{6, 2.5}, 0.5));
  EXPECT_NE(base, ViewDigest(42, TemplateViews{8, 3.0}, 0.5));
  EXPECT_NE(base, ViewDigest(42, TemplateViews{}, 0.6));
}

}  // namespace
}  // namespace moslam
