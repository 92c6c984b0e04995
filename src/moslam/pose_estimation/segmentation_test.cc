#include "moslam/pose_estimation/segmentation.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/pose_estimation/test_shapes.h"

namespace moslam {
namespace {

// Camera 0.5 m above the floor, a 0.5 x 0.8 x 0.5 m box standing on the floor 1.5-2.0 m ahead,
// optionally a wall at 3 m. In pixels the box's front face spans about u 133-186, v 88-173.
const test::Box3 kObject{Vector3(-0.25, -0.3, 1.5), Vector3(0.25, 0.5, 2.0)};
const cv::Rect2f kBox(128.0f, 82.0f, 64.0f, 96.0f);

bool IsObjectColour(const OrganizedPoint& p) { return p.r == 200 && p.g == 30 && p.b == 30; }

int CountObjectPixels(const OrganizedCloud& cloud) {
  int n = 0;
  for (const auto& p : cloud.points) n += IsObjectColour(p) ? 1 : 0;
  return n;
}

TEST(Segmentation, IsolatesTheObjectFromFloorAndWall) {
  const PinholeIntrinsics K;
  // With the floor rule (b), and without it (the floor then goes by rule (a)).
  for (const auto& [wall_z, drop_floor] : {std::pair{0.0, true}, std::pair{3.0, true},
                                           std::pair{3.0, false}}) {
    SCOPED_TRACE(wall_z);
    SCOPED_TRACE(drop_floor);
    const RgbdFrame f = test::FloorAndBoxFrame(K, 0.5, kObject, wall_z);
    SegmentationConfig config;
    config.drop_floor = drop_floor;
    const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
    ASSERT_GE(prepared.planes.size(), 1u);
    const SegmentationResult r = SegmentObject(prepared, kBox, config);
    ASSERT_EQ(r.status, SegmentationStatus::kOk) << ToString(r.status);
    ASSERT_TRUE(r.segment);
    EXPECT_EQ(r.segment->size(), r.indices.size());
    EXPECT_GE(r.planes_dropped, 1);
    int not_object = 0;
    for (const auto& p : r.segment->points) not_object += IsObjectColour(p) ? 0 : 1;
    if (drop_floor) {
      EXPECT_EQ(not_object, 0);  // no floor or wall points
    } else {
      // Without the floor rule, the floor goes by rule (a): inliers and near-plane points with
      // invalid or floor-like normals; a few contact-line pixels with mixed normals may stay.
      EXPECT_LE(not_object, 0.005 * static_cast<double>(r.segment->size()));
    }
    const int object_pixels = CountObjectPixels(*prepared.cloud);
    EXPECT_GE(static_cast<double>(r.segment->size()), 0.95 * object_pixels);
    EXPECT_LE(static_cast<int>(r.segment->size()) - not_object, object_pixels);
  }
}

// The box 5 m away (about 16 x 26 pixels) with a depth camera's noise: neighbouring pixels'
// depths differ by sqrt(2) sigma(5 m) = 5.8 cm on average, more than the 5 cm clustering
// distance, so a fixed distance breaks the scene in the box into many components and the chosen
// one misses much of the object (measured: 223 of its 416 pixels, 96 components); the distance
// widened by the depth noise keeps it whole (403, 1 component).
TEST(Segmentation, ClusterDistanceWidensWithTheDepthNoise) {
  const PinholeIntrinsics K;
  const test::Box3 far_object{Vector3(-0.25, -0.3, 5.0), Vector3(0.25, 0.5, 5.5)};
  RgbdFrame f = test::FloorAndBoxFrame(K, 0.5, far_object);
  const AxialDepthNoise noise;
  cv::RNG rng(3);
  for (int v = 0; v < f.depth.rows; ++v) {
    for (int u = 0; u < f.depth.cols; ++u) {
      float& z = f.depth.at<float>(v, u);
      if (z > 0.0f) z = static_cast<float>(z + noise.sigma(z) * rng.gaussian(1.0));
    }
  }
  const cv::Rect2f box(148.0f, 106.0f, 23.0f, 33.0f);
  SegmentationConfig config;
  ASSERT_GT(config.cluster_depth_sigmas, 0.0);
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
  const int object_pixels = CountObjectPixels(*prepared.cloud);
  ASSERT_GT(object_pixels, 300);
  const SegmentationResult widened = SegmentObject(prepared, box, config);
  ASSERT_EQ(widened.status, SegmentationStatus::kOk) << ToString(widened.status);
  const int widened_object = CountObjectPixels(*widened.segment);
  std::printf("  widened: %d of %d object pixels, %zu points, %d components\n", widened_object,
              object_pixels, widened.segment->size(), widened.components);
  EXPECT_GE(widened_object, 0.8 * object_pixels);
  EXPECT_GE(widened_object, 0.8 * static_cast<double>(widened.segment->size()));

  config.cluster_depth_sigmas = 0.0;
  const SegmentationResult fixed = SegmentObject(prepared, box, config);
  const int fixed_object = fixed.segment ? CountObjectPixels(*fixed.segment) : 0;
  std::printf("  fixed: %s, %d object pixels, %d components\n", ToString(fixed.status),
              fixed_object, fixed.components);
  EXPECT_LT(fixed_object, 0.7 * object_pixels);
  EXPECT_GT(fixed.components, 5 * widened.components);
}

// The detection box of kObject with a nearer box (green, 0.8-1.0 m) standing in front of its
// left part and extending past the box (0.6 m tall, 0.25 m wide): the nearer box has more points in the box (measured in
// the test), and the rule of the most points took it, so the box's object was registered as the
// nearer one (on rendered chairs25 frames, far chairs measured as the chair in front). The box
// fit (its pixel extent against the box) keeps the object.
TEST(Segmentation, ANearerObjectInFrontOfPartOfTheBoxIsNotTakenForTheBoxedOne) {
  const PinholeIntrinsics K;
  // Its front face stays mostly inside the grown box (a plane mostly outside it would be taken
  // for a wall by rule (a) and removed).
  const test::Box3 nearer{Vector3(-0.2, -0.1, 0.8), Vector3(0.05, 0.5, 1.0)};
  const RgbdFrame f = test::FloorAndBoxesFrame(
      K, 0.5, {{kObject, cv::Vec3b(30, 30, 200)}, {nearer, cv::Vec3b(30, 200, 30)}});
  SegmentationConfig config;
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
  auto is_nearer = [](const OrganizedPoint& p) { return p.r == 30 && p.g == 200 && p.b == 30; };
  int nearer_in_box = 0, object_in_box = 0;
  for (int v = static_cast<int>(kBox.y); v < static_cast<int>(kBox.y + kBox.height); ++v) {
    for (int u = static_cast<int>(kBox.x); u < static_cast<int>(kBox.x + kBox.width); ++u) {
      nearer_in_box += is_nearer(prepared.cloud->at(u, v)) ? 1 : 0;
      object_in_box += IsObjectColour(prepared.cloud->at(u, v)) ? 1 : 0;
    }
  }
  ASSERT_GT(nearer_in_box, object_in_box);  // the case the rule of the most points gets wrong
  ASSERT_GT(object_in_box, 1000);

  ASSERT_EQ(config.selection, ComponentSelection::kBoxFit);  // the default
  const SegmentationResult fit = SegmentObject(prepared, kBox, config);
  ASSERT_EQ(fit.status, SegmentationStatus::kOk) << ToString(fit.status);
  EXPECT_EQ(CountObjectPixels(*fit.segment), static_cast<int>(fit.segment->size()));
  EXPECT_GE(CountObjectPixels(*fit.segment), 0.95 * object_in_box);

  config.selection = ComponentSelection::kMostPoints;
  const SegmentationResult most = SegmentObject(prepared, kBox, config);
  ASSERT_EQ(most.status, SegmentationStatus::kOk) << ToString(most.status);
  EXPECT_EQ(CountObjectPixels(*most.segment), 0);
}

// A surface behind the object filling the grown box (kept: a plane inside the grown box may be
// the object's own) fits the box better than an object in two parts (a plant's foliage and pot,
// the gap between them showing the surface): the box fit alone took the surface (rendered house
// plants, seeds 1-3: 148 -> 81 accepted). It spills out of the box, the object's parts do not.
TEST(Segmentation, ASurfaceBehindTheObjectFillingTheBoxIsNotTakenForIt) {
  const PinholeIntrinsics K;
  const test::Box3 upper{Vector3(-0.25, -0.3, 1.5), Vector3(0.25, 0.15, 2.0)};
  const test::Box3 lower{Vector3(-0.25, 0.25, 1.5), Vector3(0.25, 0.5, 2.0)};
  // In pixels the grown box spans u 121.6-198.4, v 72.4-187.6: at 2.5 m, x -0.59..0.6, y -0.74..
  const test::Box3 behind{Vector3(-0.59, -0.74, 2.5), Vector3(0.59, 0.5, 2.6)};
  const RgbdFrame f = test::FloorAndBoxesFrame(K, 0.5,
                                               {{upper, cv::Vec3b(30, 30, 200)},
                                                {lower, cv::Vec3b(30, 30, 200)},
                                                {behind, cv::Vec3b(200, 30, 30)}});
  SegmentationConfig config;
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
  const SegmentationResult r = SegmentObject(prepared, kBox, config);
  ASSERT_EQ(r.status, SegmentationStatus::kOk) << ToString(r.status);
  EXPECT_GE(r.components, 3);
  EXPECT_EQ(CountObjectPixels(*r.segment), static_cast<int>(r.segment->size()));
  EXPECT_GT(r.segment->size(), 1500u);  // the upper part (about 53 x 48 pixels)
}

// A box around the object and a neighbour touching it at the same depth (chairs at a table): one
// component, so the segment holds both. With the neighbour's pixels claimed (its own segment, in
// ObjectPerception's use; here by colour) the segment is the object's alone.
TEST(Segmentation, ClaimedPixelsOfAnotherObjectAreLeftOut) {
  const PinholeIntrinsics K;
  const test::Box3 neighbour{Vector3(0.25, -0.1, 1.5), Vector3(0.45, 0.5, 1.7)};
  const RgbdFrame f = test::FloorAndBoxesFrame(
      K, 0.5, {{kObject, cv::Vec3b(30, 30, 200)}, {neighbour, cv::Vec3b(30, 200, 30)}});
  const cv::Rect2f both(128.0f, 82.0f, 84.0f, 96.0f);
  const SegmentationConfig config;
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
  auto is_neighbour = [](const OrganizedPoint& p) { return p.r == 30 && p.g == 200 && p.b == 30; };
  std::vector<int> claimed;
  int neighbour_in_box = 0, object_in_box = 0;
  const int width = static_cast<int>(prepared.cloud->width);
  for (int v = 0; v < static_cast<int>(prepared.cloud->height); ++v) {
    for (int u = 0; u < width; ++u) {
      const OrganizedPoint& p = prepared.cloud->at(u, v);
      const bool inside = both.contains(cv::Point2f(static_cast<float>(u), static_cast<float>(v)));
      if (is_neighbour(p)) {
        claimed.push_back(v * width + u);
        neighbour_in_box += inside ? 1 : 0;
      }
      object_in_box += inside && IsObjectColour(p) ? 1 : 0;
    }
  }
  ASSERT_GT(neighbour_in_box, 500);
  ASSERT_GT(object_in_box, 1000);

  const SegmentationResult plain = SegmentObject(prepared, both, config);
  ASSERT_EQ(plain.status, SegmentationStatus::kOk) << ToString(plain.status);
  int neighbour_kept = 0;
  for (const auto& p : plain.segment->points) neighbour_kept += is_neighbour(p) ? 1 : 0;
  EXPECT_GT(neighbour_kept, neighbour_in_box / 2);  // the case claims are for
  EXPECT_EQ(plain.claimed_points_in_box, 0);

  const SegmentationResult r = SegmentObject(prepared, both, config, claimed);
  ASSERT_EQ(r.status, SegmentationStatus::kOk) << ToString(r.status);
  EXPECT_EQ(CountObjectPixels(*r.segment), static_cast<int>(r.segment->size()));
  EXPECT_GE(CountObjectPixels(*r.segment), 0.95 * object_in_box);
  EXPECT_EQ(r.claimed_points_in_box, neighbour_in_box);

  EXPECT_THROW(SegmentObject(prepared, both, config, {width * 240}), InvalidInputError);
  EXPECT_THROW(SegmentObject(prepared, both, config, {-1}), InvalidInputError);
}

TEST(Segmentation, ReportsEmptyBoxesAndTooFewPoints) {
  const PinholeIntrinsics K;
  const RgbdFrame f = test::FloorAndBoxFrame(K, 0.5, kObject);
  const SegmentationConfig config;
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f), config);
  // Outside the image.
  EXPECT_EQ(SegmentObject(prepared, cv::Rect2f(400, 10, 20, 20), config).status,
            SegmentationStatus::kEmptyBox);
  // Inside the image but above the horizon (no return).
  EXPECT_EQ(SegmentObject(prepared, cv::Rect2f(10, 10, 40, 30), config).status,
            SegmentationStatus::kEmptyBox);
  // Only floor: it is structure, so nothing is left.
  const SegmentationResult floor = SegmentObject(prepared, cv::Rect2f(10, 200, 60, 30), config);
  EXPECT_EQ(floor.status, SegmentationStatus::kTooFewPoints);
  EXPECT_GT(floor.valid_points_in_box, 1000);
  EXPECT_EQ(floor.structure_points_in_box, floor.valid_points_in_box);
  EXPECT_THROW(SegmentObject(prepared, cv::Rect2f(0, 0, -1, 5), config), InvalidInputError);
}

TEST(Segmentation, StructureRuleKeepsPlanesInsideTheBox) {
  SegmentationConfig config;
  const std::size_t width = 320;
  auto plane_over = [&](int u0, int u1, int v0, int v1, Eigen::Vector4d coefficients) {
    ScenePlane p;
    p.coefficients = coefficients;
    for (int v = v0; v < v1; ++v)
      for (int u = u0; u < u1; ++u) p.inliers.push_back(v * static_cast<int>(width) + u);
    return p;
  };
  const cv::Rect2f box(100, 100, 50, 50);
  // A horizontal table top 0.25 m below the camera (0.25 m above the floor), inside the box.
  const ScenePlane table = plane_over(105, 145, 110, 130, Eigen::Vector4d(0, -1, 0, 0.25));
  EXPECT_FALSE(IsStructuralPlane(table, width, box, config));
  // The same plane at floor height (0.5 m below the camera) is the floor.
  const ScenePlane floor_patch = plane_over(105, 145, 110, 130, Eigen::Vector4d(0, 1, 0, -0.5));
  EXPECT_TRUE(IsStructuralPlane(floor_patch, width, box, config));
  config.drop_floor = false;
  EXPECT_FALSE(IsStructuralPlane(floor_patch, width, box, config));
  // A vertical plane that extends well beyond the box (a wall).
  const ScenePlane wall = plane_over(0, 320, 0, 100, Eigen::Vector4d(0, 0, -1, 3.0));
  EXPECT_TRUE(IsStructuralPlane(wall, width, box, config));
}

TEST(Segmentation, ConfigValidationNamesTheField) {
  auto expect_bad = [](SegmentationConfig c, const std::string& field) {
    EXPECT_TRUE(test::ThrowsNaming([&] { c.validate(); }, field));
  };
  EXPECT_NO_THROW(SegmentationConfig{}.validate());
  SegmentationConfig c;
  c.min_plane_inliers = 0;
  expect_bad(c, "min_plane_inliers");
  c = {};
  c.structural_outside_fraction = 1.0;
  expect_bad(c, "structural_outside_fraction");
  c = {};
  c.up_in_camera = Vector3(0, 2, 0);
  expect_bad(c, "up_in_camera");
  c = {};
  c.cluster_distance = 0.0f;
  expect_bad(c, "cluster_distance");
  c = {};
  c.tie_ratio = 1.5;
  expect_bad(c, "tie_ratio");
  c = {};
  c.cluster_depth_sigmas = -1.0;
  expect_bad(c, "cluster_depth_sigmas");
  c = {};
  c.depth_noise.a = -0.1;
  expect_bad(c, "depth_noise.a");
  c = {};
  c.plane_angular_threshold_deg = 95.0;
  expect_bad(c, "plane_angular_threshold_deg");
}

}  // namespace
}  // namespace moslam
