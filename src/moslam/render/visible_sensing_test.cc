#include "moslam/render/visible_sensing.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {

// Generic blocks (render/object_models.h) of extent (0.6, 0.8, 1.0) on the floor, seen from a
// camera 0.5 m above the origin looking along world x: block 1 at 3 m in front, block 2 at 6 m
// straight behind it (hidden by it), block 3 at 4 m to the right, in view.
World ThreeBlocks() {
  World w;
  w.name = "blocks";
  w.classes = {{"block", Vector3(0.6, 0.8, 1.0)}};
  const Vector3 at[] = {{3.0, 0.2, 0.5}, {6.0, 0.2, 0.5}, {4.0, -1.5, 0.5}};
  for (int k = 0; k < 3; ++k) {
    ObjectInstance o;
    o.id = k + 1;
    o.label = "block";
    o.pose = SE3(SO3(), at[k]);
    w.objects.push_back(o);
  }
  return w;
}

const SE3 kBody(SO3(), Vector3(0.0, 0.0, 0.5));

// `poses` poses at kBody, each with a sampled detection of every block (replaced).
SimulationData StandingStill(int poses) {
  SimulationData data;
  data.world = ThreeBlocks();
  data.trajectories = {Trajectory(static_cast<std::size_t>(poses), kBody)};
  RobotMeasurements m;
  m.odometry.assign(static_cast<std::size_t>(poses - 1),
                    OdometryReading{SE3(), Matrix6::Identity()});
  std::vector<ObjectDetection> sampled;
  for (const ObjectInstance& o : data.world.objects) {
    sampled.push_back({o.label, kBody.between(o.pose), Matrix6::Identity(), o.id});
  }
  m.detections.assign(static_cast<std::size_t>(poses), sampled);
  data.measurements = {m};
  return data;
}

VisibleSensingConfig ExactFrames() {
  VisibleSensingConfig c;
  c.render.depth_noise = false;
  c.render.colour_noise_sigma = 0.0;
  return c;
}

std::vector<int> Ids(const std::vector<ObjectDetection>& detections) {
  std::vector<int> ids;
  for (const ObjectDetection& d : detections) ids.push_back(d.object_id);
  return ids;
}

TEST(VisibleSensing, MeasuresTheObjectsTheFrameShowsWithTheirNoise) {
  SimulationData data = StandingStill(2);
  VisibleSensingConfig c = ExactFrames();
  const VisibleSensingStats stats = MeasureVisibleObjects(data, c);
  EXPECT_EQ(stats.frames, 2);
  EXPECT_EQ(stats.replaced, 6);
  EXPECT_EQ(stats.seen_enough, 4);
  EXPECT_EQ(stats.measured, 4);
  for (const std::vector<ObjectDetection>& pose : data.measurements[0].detections) {
    EXPECT_EQ(Ids(pose), (std::vector<int>{1, 3}));  // block 2 is behind block 1
    for (const ObjectDetection& d : pose) {
      EXPECT_EQ(d.label, "block");
      const Vector6 n =
          kBody.between(data.world.object(d.object_id).pose).localCoordinates(d.measurement);
      EXPECT_LT(n.head<3>().norm(), 5 * 0.0873) << n.transpose();  // 5 deg: a few sigma
      EXPECT_LT(n.tail<3>().norm(), 5 * 0.2) << n.transpose();
      EXPECT_GT(n.norm(), 0.0);
      EXPECT_EQ(d.information, c.noise.information(c.information_sigma_floor));
    }
  }
  // Noise-free but for the information floor: the true relative pose.
  c.noise.sigma_rotation_deg = 0.0;
  c.noise.sigma_translation = 0.0;
  MeasureVisibleObjects(data, c);
  for (const ObjectDetection& d : data.measurements[0].detections[0]) {
    EXPECT_TRUE(d.measurement.matrix().isApprox(
        kBody.between(data.world.object(d.object_id).pose).matrix(), 1e-12));
  }
}

TEST(VisibleSensing, TheHiddenObjectIsMeasuredOnceItsBlockerIsGone) {
  SimulationData data = StandingStill(1);
  data.world.objects.erase(data.world.objects.begin());  // block 1, in front of block 2
  MeasureVisibleObjects(data, ExactFrames());
  EXPECT_EQ(Ids(data.measurements[0].detections[0]), (std::vector<int>{2, 3}));
}

TEST(VisibleSensing, ObjectsBeyondTheDepthRangeAreNotMeasured) {
  SimulationData data = StandingStill(1);
  data.world.objects.erase(data.world.objects.begin());
  VisibleSensingConfig c = ExactFrames();
  c.render.max_depth = 5.0;  // block 2's centre is 6 m away, block 3's 4 m
  MeasureVisibleObjects(data, c);
  EXPECT_EQ(Ids(data.measurements[0].detections[0]), (std::vector<int>{3}));
}

TEST(VisibleSensing, APartlyHiddenObjectCountsFromItsShareSeen) {
  SimulationData data = StandingStill(1);
  data.world.objects[1].pose = SE3(SO3(), Vector3(6.0, 1.0, 0.5));  // block 2 partly behind 1
  VisibleSensingConfig c = ExactFrames();
  const RenderedFrame frame = Renderer(data.world, c.render).render(kBody);
  double share = -1.0;
  for (const VisibleObject& v : frame.objects) {
    if (v.id == 2) share = v.visibleFraction();
  }
  ASSERT_GT(share, 0.0);
  ASSERT_LT(share, 0.9);
  const auto measured = [&](double min_share) {
    SimulationData d = data;
    c.min_visible_fraction = min_share;
    MeasureVisibleObjects(d, c);
    return Ids(d.measurements[0].detections[0]);
  };
  EXPECT_EQ(measured(share), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(measured(share + 0.05), (std::vector<int>{1, 3}));
}

TEST(VisibleSensing, PosesNotRenderedGetNoMeasurement) {
  SimulationData data = StandingStill(3);
  VisibleSensingConfig c = ExactFrames();
  c.every = 2;
  const VisibleSensingStats stats = MeasureVisibleObjects(data, c);
  EXPECT_EQ(stats.frames, 2);
  EXPECT_EQ(stats.replaced, 9);
  EXPECT_EQ(data.measurements[0].detections[0].size(), 2u);
  EXPECT_TRUE(data.measurements[0].detections[1].empty());
  EXPECT_EQ(data.measurements[0].detections[2].size(), 2u);
}

TEST(VisibleSensing, AKeepProbabilityMeasuresThatShareOfTheViewsWithTheSameNoise) {
  SimulationData all = StandingStill(400);
  SimulationData some = all;
  VisibleSensingConfig c = ExactFrames();
  MeasureVisibleObjects(all, c);
  c.keep_probability = 0.6;
  const VisibleSensingStats stats = MeasureVisibleObjects(some, c);
  EXPECT_EQ(stats.seen_enough, 800);           // blocks 1 and 3 at every pose
  EXPECT_NEAR(stats.measured, 480, 4 * 13.9);  // Binomial(800, 0.6): mean 480, sigma 13.9
  // A view kept has the measurement it has when every view is kept.
  for (std::size_t i = 0; i < 400; ++i) {
    for (const ObjectDetection& d : some.measurements[0].detections[i]) {
      const auto& full = all.measurements[0].detections[i];
      const ObjectDetection& same = d.object_id == 1 ? full[0] : full[1];
      ASSERT_EQ(same.object_id, d.object_id);
      EXPECT_EQ(same.measurement.matrix(), d.measurement.matrix());
    }
  }
  SimulationData again = StandingStill(400);
  EXPECT_EQ(MeasureVisibleObjects(again, c).measured, stats.measured);  // reproducible
}

TEST(VisibleSensing, BadInputIsRefusedNamingIt) {
  SimulationData data = StandingStill(2);
  const auto refused = [&](const VisibleSensingConfig& c, const std::string& field) {
    return test::ThrowsNaming([&] { MeasureVisibleObjects(data, c); }, field);
  };
  VisibleSensingConfig c = ExactFrames();
  c.every = 0;
  EXPECT_TRUE(refused(c, "every"));
  c = ExactFrames();
  c.min_visible_fraction = 1.5;
  EXPECT_TRUE(refused(c, "min_visible_fraction"));
  c = ExactFrames();
  c.keep_probability = 0.0;
  EXPECT_TRUE(refused(c, "keep_probability"));
  c = ExactFrames();
  c.information_sigma_floor = 0.0;
  EXPECT_TRUE(refused(c, "information_sigma_floor"));
  data.measurements.clear();
  EXPECT_TRUE(refused(ExactFrames(), "1 robots"));
}

}  // namespace
}  // namespace moslam
