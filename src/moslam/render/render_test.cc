#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/core.h>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/render/dataset_export.h"
#include "moslam/render/renderer.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

// One generic block (render/object_models.h: a box over the full footprint up to 70% of the
// height) of extent (0.6, 0.8, 1.0) standing on the floor at (3, 0.2), yaw 0.
World BlockWorld() {
  World w;
  w.name = "block";
  w.classes = {{"block", Vector3(0.6, 0.8, 1.0)}};
  ObjectInstance o;
  o.id = 7;
  o.label = "block";
  o.pose = SE3(SO3(), Vector3(3.0, 0.2, 0.5));
  w.objects.push_back(o);
  return w;
}

RenderConfig ExactConfig() {
  RenderConfig c;
  c.depth_noise = false;
  c.quantize_depth = false;
  c.colour_noise_sigma = 0.0;
  return c;
}

// Camera at the origin, 0.5 m above the floor, looking along world x.
const SE3 kBody(SO3(), Vector3(0.0, 0.0, 0.5));

TEST(Intrinsics, FromHorizontalFovAndValidate) {
  const auto k = PinholeIntrinsics::FromHorizontalFov(320, 240, 90.0);
  EXPECT_NEAR(k.fx, 160.0, 1e-9);
  EXPECT_EQ(k.fx, k.fy);
  EXPECT_DOUBLE_EQ(k.cx, 159.5);
  EXPECT_DOUBLE_EQ(k.cy, 119.5);
  EXPECT_THROW(PinholeIntrinsics::FromHorizontalFov(320, 240, 180.0), InvalidInputError);
  PinholeIntrinsics bad = k;
  bad.fy = -1.0;
  EXPECT_TRUE(test::ThrowsNaming([&] { bad.validate(); }, "fy"));
}

TEST(Intrinsics, BodyFromCameraAxes) {
  const Matrix3 R = BodyFromCamera().rotation().matrix();
  EXPECT_TRUE(R.col(2).isApprox(Vector3::UnitX()));   // optical axis = body forward
  EXPECT_TRUE(R.col(0).isApprox(-Vector3::UnitY()));  // image right = body right
  EXPECT_TRUE(R.col(1).isApprox(-Vector3::UnitZ()));  // image down = body down
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
}

TEST(RenderConfig, ValidateNamesTheField) {
  using C = RenderConfig;
  EXPECT_TRUE(test::EachChangeIsRefused<C>({
      {"intrinsics: PinholeIntrinsics: width", [](C& c) { c.intrinsics.width = 0; }},
      {"min_depth", [](C& c) { c.min_depth = 0.0; }},
      {"max_depth", [](C& c) { c.max_depth = 0.1; }},
      {"max_depth", [](C& c) { c.max_depth = HUGE_VAL; }},
      {"wall_height", [](C& c) { c.wall_height = -1.0; }},
      {"door_width", [](C& c) { c.door_width = std::nan(""); }},
      {"style.floor_tile_m", [](C& c) { c.style.floor_tile_m = 0.0; }},
      {"style.light_direction", [](C& c) { c.style.light_direction = Vector3::Zero(); }},
      {"style.light_direction", [](C& c) { c.style.light_direction.x() = std::nan(""); }},
      {"style.ambient", [](C& c) { c.style.ambient = -0.1; }},
      {"style.ambient", [](C& c) { c.style.diffuse = HUGE_VAL; }},
      {"depth_noise_model.a", [](C& c) { c.depth_noise_model.a = -1.0; }},
      {"colour_noise_sigma", [](C& c) { c.colour_noise_sigma = -1.0; }},
  }));
}

TEST(Renderer, DepthMatchesTheGeometryItDrew) {
  const Renderer r(BlockWorld(), ExactConfig());
  const RenderedFrame f = r.render(kBody);
  const auto& K = f.rgbd.intrinsics;
  ASSERT_EQ(f.rgbd.depth.type(), CV_32FC1);
  ASSERT_EQ(f.rgbd.rgb.type(), CV_8UC3);
  // The block's -x face is the plane x = 2.7, facing the camera: depth (z along world x) is
  // 2.7 m at every pixel of it, e.g. the pixel nearest to the face centre (y = 0.2, z = 0.35).
  const double D = 2.7;
  const int u = static_cast<int>(std::lround(K.cx + K.fx * (-0.2) / D));
  const int v = static_cast<int>(std::lround(K.cy + K.fy * (0.5 - 0.35) / D));
  EXPECT_NEAR(f.rgbd.depth.at<float>(v, u), D, 1e-3);
  EXPECT_EQ(f.instance_ids.at<int>(v, u), 7);
  // Floor pixels: the ray through (u, v) meets z = 0 at depth h fy / (v - cy).
  for (const cv::Point p : {cv::Point(5, 235), cv::Point(300, 200), cv::Point(40, 150)}) {
    const double expected = 0.5 * K.fy / (p.y - K.cy);
    EXPECT_NEAR(f.rgbd.depth.at<float>(p), expected, 1e-4 * expected) << p;
    EXPECT_EQ(f.instance_ids.at<int>(p), -1) << p;
  }
  // Above the horizon nothing is hit (no walls in this world): no return.
  EXPECT_EQ(f.rgbd.depth.at<float>(5, 5), 0.0f);
  // A body pose that is not finite gives no frame.
  const SE3 lost(SO3(), Vector3(std::nan(""), 0.0, 0.5));
  EXPECT_TRUE(test::ThrowsNaming([&] { r.render(lost); }, "world_T_body is not finite"));
}

TEST(Renderer, InstanceImageAndBoxAgreeWithTheProjection) {
  const Renderer r(BlockWorld(), ExactConfig());
  const RenderedFrame f = r.render(kBody);
  const auto& K = f.rgbd.intrinsics;
  ASSERT_EQ(f.objects.size(), 1u);
  const VisibleObject& o = f.objects[0];
  EXPECT_EQ(o.id, 7);
  EXPECT_EQ(o.label, "block");
  // The box and count are those of the instance image.
  cv::Mat mask = f.instance_ids == 7;
  EXPECT_EQ(cv::countNonZero(mask), o.visible_pixels);
  EXPECT_EQ(cv::boundingRect(mask), o.box);
  // Analytic projection of the front face (x = 2.7, y in [-0.2, 0.6], z in [0, 0.7]):
  // u = cx - fx y / D. The top part (x >= 3, y <= 0.4, up to z = 1) projects inside in u.
  const double D = 2.7;
  const double u_left = K.cx - K.fx * 0.6 / D, u_right = K.cx + K.fx * 0.2 / D;
  EXPECT_NEAR(o.box.x, std::ceil(u_left), 1.0);
  EXPECT_NEAR(o.box.x + o.box.width - 1, std::floor(u_right), 1.0);
  const double v_bottom = K.cy + K.fy * 0.5 / D;  // the face's bottom edge on the floor
  EXPECT_NEAR(o.box.y + o.box.height - 1, std::floor(v_bottom), 1.0);
  const double v_top = K.cy - K.fy * 0.5 / 3.0;  // the top part's front top edge (x = 3, z = 1)
  EXPECT_NEAR(o.box.y, std::ceil(v_top), 1.0);
  // Ground-truth pose in the camera frame: the centre 3 m ahead, 0.2 m left (camera -x).
  EXPECT_TRUE(o.camera_T_object.translation().isApprox(Vector3(-0.2, 0.0, 3.0), 1e-12));
  EXPECT_DOUBLE_EQ(o.in_image_fraction, 1.0);
}

TEST(Renderer, ObjectPartlyOutsideTheImageHasSmallInImageFraction) {
  World w = BlockWorld();
  w.objects[0].pose = SE3(SO3(), Vector3(2.0, 1.3, 0.5));  // at the left border
  const Renderer r(w, ExactConfig());
  const RenderedFrame f = r.render(kBody);
  ASSERT_EQ(f.objects.size(), 1u);
  EXPECT_GT(f.objects[0].in_image_fraction, 0.0);
  EXPECT_LT(f.objects[0].in_image_fraction, 0.5);
  EXPECT_EQ(f.objects[0].box.x, 0);
}

TEST(Renderer, VisibleFractionCountsOcclusionAndTheImageBorder) {
  // Alone in view: its silhouette is what is seen.
  {
    const Renderer r(BlockWorld(), ExactConfig());
    const RenderedFrame f = r.render(kBody);
    ASSERT_EQ(f.objects.size(), 1u);
    EXPECT_EQ(f.objects[0].silhouette_pixels, f.objects[0].visible_pixels);
    EXPECT_DOUBLE_EQ(f.objects[0].visibleFraction(), 1.0);
  }
  // A second block halfway to it, 0.4 m to its left: it hides part of the first, not all.
  World w = BlockWorld();
  ObjectInstance front = w.objects[0];
  front.id = 8;
  front.pose = SE3(SO3(), Vector3(1.5, 0.5, 0.5));
  w.objects.push_back(front);
  const Renderer r(w, ExactConfig());
  const RenderedFrame f = r.render(kBody);
  ASSERT_EQ(f.objects.size(), 2u);
  const VisibleObject& back = f.objects[0];
  ASSERT_EQ(back.id, 7);
  EXPECT_EQ(f.objects[1].silhouette_pixels, f.objects[1].visible_pixels);
  // Its silhouette does not depend on what stands in front of it.
  EXPECT_EQ(back.silhouette_pixels, Renderer(BlockWorld(), ExactConfig())
                                        .render(kBody)
                                        .objects[0]
                                        .silhouette_pixels);
  EXPECT_LT(back.visible_pixels, back.silhouette_pixels);
  EXPECT_GT(back.visible_pixels, 0);
  EXPECT_DOUBLE_EQ(back.visibleFraction(), static_cast<double>(back.visible_pixels) /
                                               back.silhouette_pixels * back.in_image_fraction);
  // Cut by the border: the in-image share scales it.
  World edge = BlockWorld();
  edge.objects[0].pose = SE3(SO3(), Vector3(2.0, 1.3, 0.5));
  const RenderedFrame g = Renderer(edge, ExactConfig()).render(kBody);
  ASSERT_EQ(g.objects.size(), 1u);
  EXPECT_LT(g.objects[0].visibleFraction(), 0.5);
  // (Where the block stands on the floor a pixel may go to the floor: a share of a percent.)
  EXPECT_NEAR(g.objects[0].visibleFraction(), g.objects[0].in_image_fraction,
              0.01 * g.objects[0].in_image_fraction);
}

TEST(Renderer, DepthOutsideTheRangeHasNoReturn) {
  RenderConfig c = ExactConfig();
  c.max_depth = 2.5;  // the block's face at 2.7 m is beyond
  const Renderer r(BlockWorld(), c);
  const RenderedFrame f = r.render(kBody);
  const auto& K = f.rgbd.intrinsics;
  const int u = static_cast<int>(std::lround(K.cx + K.fx * (-0.2) / 2.7));
  const int v = static_cast<int>(std::lround(K.cy + K.fy * 0.15 / 2.7));
  EXPECT_EQ(f.rgbd.depth.at<float>(v, u), 0.0f);
  EXPECT_EQ(f.instance_ids.at<int>(v, u), 7);  // still seen in colour
}

bool SameBytes(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && a.isContinuous() && b.isContinuous() &&
         std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

TEST(Renderer, DeterministicNoiseSeededByFrameKey) {
  const World w = MakeHouseWorld();
  RenderConfig c;
  c.seed = 3;
  const Renderer r(w, c);
  const SE3 body(SO3::Exp(Vector3(0.0, 0.0, 1.2)), Vector3(1.5, 1.5, 0.5));
  const RenderedFrame a = r.render(body, 11), b = r.render(body, 11), d = r.render(body, 12);
  EXPECT_TRUE(SameBytes(a.rgbd.depth, b.rgbd.depth));
  EXPECT_TRUE(SameBytes(a.rgbd.rgb, b.rgbd.rgb));
  EXPECT_TRUE(SameBytes(a.instance_ids, b.instance_ids));
  EXPECT_FALSE(SameBytes(a.rgbd.depth, d.rgbd.depth));
  EXPECT_FALSE(SameBytes(a.rgbd.rgb, d.rgbd.rgb));
  EXPECT_TRUE(SameBytes(a.instance_ids, d.instance_ids));  // noise never changes the geometry
  // The noise has the documented size: sigma(z) = a + b (z - 0.4)^2, on floor pixels.
  RenderConfig exact = c;
  exact.depth_noise = false;
  exact.quantize_depth = false;
  const RenderedFrame e = Renderer(w, exact).render(body, 11);
  double sum = 0.0, sum_expected = 0.0;
  int n = 0;
  for (int v = 180; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const float z = e.rgbd.depth.at<float>(v, u);
      if (z <= 0.0f || e.instance_ids.at<int>(v, u) != -1) continue;
      const double err = a.rgbd.depth.at<float>(v, u) - z;
      const double s = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      sum += err * err;
      sum_expected += s * s;
      ++n;
    }
  }
  ASSERT_GT(n, 1000);
  EXPECT_NEAR(std::sqrt(sum / n), std::sqrt(sum_expected / n), 0.1 * std::sqrt(sum_expected / n));
}

TEST(Renderer, WallsHaveDoorsWhereRobotsDrive) {
  // House: the living room's east wall x = 7 has a door at y in [2, 3] (the navigation edge
  // from (6.3, 2.5) to (7.7, 2.5)); a camera at (5, 2.5) looking along +x sees through it.
  RenderConfig c = ExactConfig();
  const Renderer r(MakeHouseWorld(), c);
  const RenderedFrame through = r.render(SE3(SO3(), Vector3(5.0, 2.5, 0.5)));
  const float z_centre = through.rgbd.depth.at<float>(100, 160);  // above the horizon
  EXPECT_TRUE(z_centre == 0.0f || z_centre > 2.5f) << z_centre;
  const RenderedFrame wall = r.render(SE3(SO3(), Vector3(5.0, 1.0, 0.5)));
  EXPECT_NEAR(wall.rgbd.depth.at<float>(100, 160), 2.0, 1e-3);  // the wall x = 7
}

TEST(YoloLabels, LinesAreInRangeAndFollowTheFilters) {
  ScenarioViewsConfig vc;
  vc.scenario = "house";
  vc.num_robots = 2;
  vc.poses_per_robot = 12;
  vc.seed = 2;
  const ScenarioViews views = MakeScenarioViews(vc);
  ASSERT_EQ(views.views.size(), 24u);
  const Renderer r(views.world, RenderConfig());
  const auto classes = StandardObjectClasses();
  YoloLabelConfig lc;
  int total = 0, total_ignore = 0;
  for (std::size_t i = 0; i < views.views.size(); ++i) {
    const RenderedFrame f = r.render(views.views[i].world_T_body, i);
    const auto lines = YoloLabelLines(f, classes, lc);
    const auto ignore = YoloIgnoreLines(f, classes, lc);
    int expected = 0, expected_ignore = 0;
    for (const auto& o : f.objects) {
      const bool labelled =
          o.visible_pixels >= lc.min_visible_pixels && o.in_image_fraction >= 0.5;
      expected += labelled;
      const bool standard = std::any_of(classes.begin(), classes.end(),
                                        [&](const ObjectClass& c) { return c.label == o.label; });
      expected_ignore += standard && !labelled;
    }
    EXPECT_EQ(static_cast<int>(lines.size()), expected);
    EXPECT_EQ(static_cast<int>(ignore.size()), expected_ignore);
    total_ignore += static_cast<int>(ignore.size());
    for (const auto& l : ignore) {  // disjoint from the labels
      EXPECT_EQ(std::find(lines.begin(), lines.end(), l), lines.end()) << l;
    }
    for (const auto& l : lines) {
      std::istringstream s(l);
      int c = -1;
      double cx = -1, cy = -1, w = -1, h = -1;
      ASSERT_TRUE(s >> c >> cx >> cy >> w >> h) << l;
      EXPECT_GE(c, 0);
      EXPECT_LT(c, static_cast<int>(classes.size()));
      EXPECT_GT(w, 0.0);
      EXPECT_GT(h, 0.0);
      EXPECT_GE(cx - w / 2, -1e-6) << l;
      EXPECT_LE(cx + w / 2, 1.0 + 1e-6) << l;
      EXPECT_GE(cy - h / 2, -1e-6) << l;
      EXPECT_LE(cy + h / 2, 1.0 + 1e-6) << l;
    }
    total += static_cast<int>(lines.size());
  }
  EXPECT_GT(total, 5);
  EXPECT_GT(total_ignore, 0);  // small and border-cut objects exist in these views
  lc.min_visible_pixels = 0;
  EXPECT_THROW(lc.validate(), InvalidInputError);
}

TEST(YoloExport, WritesLabelsAndIgnoreFilesPerFrame) {
  ScenarioViewsConfig vc;
  vc.scenario = "house";
  vc.num_robots = 1;
  vc.poses_per_robot = 6;
  vc.seed = 2;
  const ScenarioViews views = MakeScenarioViews(vc);
  const Renderer r(views.world, RenderConfig());
  const std::filesystem::path dir = test::ScratchDir();
  YoloLabelConfig lc;
  lc.min_visible_pixels = 5000;  // few labels, so most visible objects become ignore lines
  const YoloExportSummary s = ExportYoloDataset(r, views, dir.string(), 7, lc);
  ASSERT_EQ(s.frames, 6);
  const auto classes = StandardObjectClasses();
  auto read = [](const std::filesystem::path& p) {
    std::vector<std::string> lines;
    std::ifstream f(p);
    EXPECT_TRUE(f.good()) << p;
    for (std::string l; std::getline(f, l);) lines.push_back(l);
    return lines;
  };
  int ignored = 0;
  for (int i = 0; i < s.frames; ++i) {
    const std::string name = fmt::format("{:06d}.txt", 7 + i);
    const RenderedFrame f = r.render(views.views[static_cast<std::size_t>(i)].world_T_body,
                                     static_cast<std::uint64_t>(7 + i));
    EXPECT_EQ(read(dir / "labels" / name), YoloLabelLines(f, classes, lc));
    const auto ignore = read(dir / "ignore" / name);
    EXPECT_EQ(ignore, YoloIgnoreLines(f, classes, lc));
    ignored += static_cast<int>(ignore.size());
  }
  EXPECT_EQ(ignored, s.ignored);
  EXPECT_GT(s.ignored, 0);
  std::filesystem::remove_all(dir);
}

TEST(ScenarioViews, JitterStaysWithinItsBounds) {
  ScenarioViewsConfig vc;
  vc.num_robots = 3;
  vc.poses_per_robot = 20;
  vc.frames_per_robot = 5;
  ScenarioViews plain = MakeScenarioViews(vc);
  vc.yaw_jitter_deg = 10.0;
  vc.height_jitter_m = 0.05;
  ScenarioViews jit = MakeScenarioViews(vc);
  ASSERT_EQ(plain.views.size(), 15u);
  ASSERT_EQ(jit.views.size(), 15u);
  for (std::size_t i = 0; i < plain.views.size(); ++i) {
    EXPECT_EQ(plain.views[i].step, jit.views[i].step);
    const SE3 d = plain.views[i].world_T_body.between(jit.views[i].world_T_body);
    EXPECT_LE(SO3::Log(d.rotation()).norm(), 10.0 * kPi / 180.0 + 1e-9);
    EXPECT_LE(std::abs(d.translation().z()), 0.05 + 1e-9);
  }
  vc.scenario = "kitchen";
  EXPECT_THROW(vc.validate(), InvalidInputError);
}

TEST(YoloDataset, BadLabelOptionsNameTheField) {
  using C = YoloLabelConfig;
  EXPECT_TRUE(test::EachChangeIsRefused<C>({
      {"min_visible_pixels", [](C& c) { c.min_visible_pixels = 0; }},
      {"min_in_image_fraction", [](C& c) { c.min_in_image_fraction = 1.5; }},
      {"min_in_image_fraction", [](C& c) { c.min_in_image_fraction = std::nan(""); }},
      {"min_labels_per_frame", [](C& c) { c.min_labels_per_frame = -1; }},
  }));
}

}  // namespace
}  // namespace moslam
