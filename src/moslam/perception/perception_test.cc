// The front-end chain on rendered frames, with the committed detector model.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/perception/object_perception.h"
#include "moslam/perception/rendered_sensing.h"
#include "moslam/render/renderer.h"

namespace moslam {
namespace {

PerceptionConfig CommittedModel() {
  PerceptionConfig c;
  c.detector.model_path = std::string(MOSLAM_MODELS_DIR) + "/detector/moslam_yolo.onnx";
  c.detector.class_names_file = std::string(MOSLAM_MODELS_DIR) + "/detector/classes.txt";
  return c;
}

// One object of `label` at (x, 0) with yaw `yaw`, on the floor; the robot at the origin looking
// along +x at the simulation's camera height.
World OneObject(const std::string& label, double x, double yaw) {
  World w;
  w.name = "one";
  w.classes = StandardObjectClasses();
  ObjectInstance o;
  o.id = 7;
  o.label = label;
  const double half_height = 0.5 * w.findClass(label)->extent.z();
  o.pose = SE3(SO3::Exp(Vector3(0.0, 0.0, yaw)), Vector3(x, 0.0, half_height));
  w.objects.push_back(o);
  return w;
}

const SE3 kBody(SO3(), Vector3(0.0, 0.0, 0.5));

TEST(Perception, RecoversTheChairPoseFromARenderedFrame) {
  const World w = OneObject("chair", 2.0, 0.6);
  const Renderer renderer(w, RenderConfig{});
  const RenderedFrame frame = renderer.render(kBody, 1);
  ASSERT_EQ(frame.objects.size(), 1u);
  ObjectPerception perception(CommittedModel(), w.classes);
  const FramePerception seen = perception.perceive(frame.rgbd);
  ASSERT_EQ(seen.objects.size(), 1u);
  const PerceivedObject& o = seen.objects.front();
  EXPECT_EQ(o.detection.label, "chair");
  EXPECT_GE(o.detection.confidence, 0.3f);
  EXPECT_GE(BoxIou(o.detection.box, cv::Rect2f(frame.objects.front().box)), 0.5);
  ASSERT_TRUE(o.accepted()) << ToString(o.status) << ", inliers " << o.registration.inliers;
  EXPECT_GE(o.registration.inliers, 12);
  // The measurement x^-1 o in the body frame against the truth.
  const SE3 truth = kBody.inverse() * w.objects.front().pose;
  EXPECT_LT((o.body_T_object.translation() - truth.translation()).norm(), 0.05);
  EXPECT_LT(SO3::Log(truth.rotation().inverse() * o.body_T_object.rotation()).norm(),
            5.0 * M_PI / 180.0);
  // The information is symmetric positive definite.
  const Matrix6 info = o.registration.information;
  EXPECT_LT((info - info.transpose()).norm(), 1e-9 * info.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6>(info).eigenvalues().minCoeff(), 0.0);
  // The SLAM measurement carries it.
  const std::vector<ObjectDetection> m = ToObjectDetections(seen);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m.front().label, "chair");
  EXPECT_EQ(m.front().object_id, -1);
  EXPECT_GT(seen.times.register_, 0.0);
  // The template at the registered pose projects onto the box; a check demanding a perfect
  // overlap turns the same pose away.
  EXPECT_GE(o.box_agreement, 0.6);
  PerceptionConfig strict = CommittedModel();
  strict.min_box_agreement = 1.0;
  ObjectPerception strict_perception(strict, w.classes);
  const FramePerception strictly = strict_perception.perceive(frame.rgbd);
  ASSERT_EQ(strictly.objects.size(), 1u);
  EXPECT_EQ(strictly.objects.front().status, PerceptionStatus::kBoxMismatch);
  EXPECT_DOUBLE_EQ(strictly.objects.front().box_agreement, o.box_agreement);
  EXPECT_TRUE(ToObjectDetections(strictly).empty());
}

// With a template cache: the first front-end builds the chair's template and stores it, the next
// one loads it and measures the same pose; a cache file that does not decode, or a cache that
// cannot be written, is a note, and the template is built as without a cache.
TEST(Perception, ATemplateFromTheCacheMeasuresAsTheOneBuilt) {
  const World w = OneObject("chair", 2.0, 0.6);
  const RenderedFrame frame = Renderer(w, RenderConfig{}).render(kBody, 1);
  const std::filesystem::path cache = test::ScratchDir("templates");
  PerceptionConfig config = CommittedModel();
  config.template_cache_dir = cache.string();
  auto perceive = [&](const PerceptionConfig& c, int from_cache, std::size_t notes) {
    ObjectPerception perception(c, w.classes);
    const FramePerception seen = perception.perceive(frame.rgbd);
    EXPECT_EQ(perception.templatesFromCache(), from_cache);
    EXPECT_EQ(perception.templateNotes().size(), notes)
        << (perception.templateNotes().empty() ? "" : perception.templateNotes().front());
    EXPECT_EQ(seen.objects.size(), 1u);
    return seen.objects.empty() ? PerceivedObject{} : seen.objects.front();
  };
  const PerceivedObject built = perceive(config, 0, 0);
  ASSERT_TRUE(built.accepted()) << ToString(built.status);
  std::vector<std::filesystem::path> stored;
  for (const auto& entry : std::filesystem::directory_iterator(cache)) stored.push_back(entry);
  ASSERT_EQ(stored.size(), 1u);
  auto same = [&](const PerceivedObject& o) {
    EXPECT_EQ(o.status, built.status);
    EXPECT_EQ(o.registration.inliers, built.registration.inliers);
    EXPECT_EQ(o.body_T_object.matrix(), built.body_T_object.matrix());
  };
  same(perceive(config, 1, 0));
  std::ofstream(stored.front(), std::ios::binary | std::ios::trunc) << "not a template";
  same(perceive(config, 0, 1));  // and stored again:
  same(perceive(config, 1, 0));
  PerceptionConfig unwritable = config;
  unwritable.template_cache_dir = stored.front().string() + "/below_a_file";
  same(perceive(unwritable, 0, 1));
}

// The statuses' names are what `moslam perceive --json` and the detection logs write, and what
// scripts select on (scripts/bench-perception.sh): one name each, fixed.
TEST(Perception, EveryStatusHasItsOwnName) {
  using P = PerceptionStatus;
  const std::vector<std::pair<P, std::string>> perception = {
      {P::kAccepted, "accepted"},
      {P::kNoTemplate, "no_template"},
      {P::kSegmentationFailed, "segmentation_failed"},
      {P::kTooFewPoints, "too_few_points"},
      {P::kTooFewInliers, "too_few_inliers"},
      {P::kGicpFailed, "gicp_failed"},
      {P::kColourMismatch, "colour_mismatch"},
      {P::kShapeMismatch, "shape_mismatch"},
      {P::kBoxMismatch, "box_mismatch"},
  };
  for (const auto& [status, name] : perception) EXPECT_EQ(ToString(status), name);
  using R = RegistrationStatus;
  const std::vector<std::pair<R, std::string>> registration = {
      {R::kAccepted, "accepted"},
      {R::kTooFewPoints, "too_few_points"},
      {R::kTooFewInliers, "too_few_inliers"},
      {R::kGicpFailed, "gicp_failed"},
      {R::kColourMismatch, "colour_mismatch"},
      {R::kShapeMismatch, "shape_mismatch"},
  };
  for (const auto& [status, name] : registration) EXPECT_EQ(ToString(status), name);
}

// A unit cube 2 m ahead: its pixel box by the pinhole model; behind the camera, empty; partly
// outside the image, clipped.
TEST(Perception, ProjectedBoxIsThePinholeBoxClippedToTheImage) {
  FeatureCloud cube;
  for (double x : {-0.5, 0.5}) {
    for (double y : {-0.5, 0.5}) {
      for (double z : {-0.5, 0.5}) {
        FeaturePoint p;
        p.x = static_cast<float>(x);
        p.y = static_cast<float>(y);
        p.z = static_cast<float>(z);
        cube.push_back(p);
      }
    }
  }
  const PinholeIntrinsics k;  // 320 x 240, f 160, centre (159.5, 119.5)
  const cv::Rect2f ahead = ProjectedBox(cube, SE3(SO3(), Vector3(0.0, 0.0, 2.0)), k);
  // The near face (z 1.5) spans +-0.5 / 1.5 * 160 = +-53.3 pixels about the centre.
  EXPECT_NEAR(ahead.x, 159.5 - 160.0 / 3.0, 1e-3);
  EXPECT_NEAR(ahead.y, 119.5 - 160.0 / 3.0, 1e-3);
  EXPECT_NEAR(ahead.width, 320.0 / 3.0, 1e-3);
  EXPECT_NEAR(ahead.height, 320.0 / 3.0, 1e-3);
  EXPECT_TRUE(ProjectedBox(cube, SE3(SO3(), Vector3(0.0, 0.0, -2.0)), k).empty());
  const cv::Rect2f right = ProjectedBox(cube, SE3(SO3(), Vector3(2.0, 0.0, 2.0)), k);
  EXPECT_NEAR(right.x + right.width, 320.0, 1e-3);
  EXPECT_NEAR(right.x, 159.5 + 160.0 * 1.5 / 2.5, 1e-3);
}

TEST(RenderedSensing, CountsTrueDetectionsOfObjectsSeenEnoughByClassAndDepth) {
  // One robot, two poses: the chair in full view, then the robot turned away from it.
  SimulationData data;
  data.world = OneObject("chair", 2.0, 0.6);
  data.trajectories = {{kBody, SE3(SO3::Exp(Vector3(0.0, 0.0, M_PI)), kBody.translation())}};
  data.measurements.resize(1);
  RenderedSensingConfig config;
  config.perception = CommittedModel();
  const RenderedSensingStats stats = PerceiveSimulation(data, config);
  EXPECT_EQ(stats.frames, 2);
  const AcceptanceCounts all = stats.total();
  ASSERT_EQ(all.true_detections, 1);
  EXPECT_EQ(all.true_visible, 1);  // nothing hides it, nothing cuts it
  ASSERT_EQ(stats.by_class.size(), 1u);  // only true detections have a class entry
  ASSERT_EQ(stats.by_class.count("chair"), 1u);
  const AcceptanceCounts& chair = stats.by_class.at("chair");
  EXPECT_EQ(chair.true_detections, 1);
  EXPECT_EQ(chair.true_visible, 1);
  EXPECT_EQ(chair.accepted, all.accepted);
  EXPECT_EQ(chair.accepted_visible, all.accepted_visible);
  EXPECT_EQ(all.accepted_visible, all.accepted);
  EXPECT_LE(all.accepted, stats.accepted);
  // The same counts by depth: the chair's centre 2 m ahead, bin [2, 3) m.
  ASSERT_EQ(stats.by_depth.size(), 1u);
  ASSERT_EQ(stats.by_depth.count(2), 1u);
  EXPECT_EQ(stats.by_depth.at(2).true_detections, chair.true_detections);
  EXPECT_EQ(stats.by_depth.at(2).accepted, chair.accepted);
  EXPECT_EQ(stats.by_depth.at(2).true_visible, chair.true_visible);
  EXPECT_EQ(stats.by_depth.at(2).accepted_visible, chair.accepted_visible);
  // Every accepted detection that is not true has its error to the nearest same-label object.
  EXPECT_EQ(stats.false_accepted_errors.size(),
            static_cast<std::size_t>(stats.accepted - all.accepted));
  EXPECT_LE(stats.accepted_true_other_object, stats.accepted_true_off);
  EXPECT_LE(stats.accepted_true_off, all.accepted);
  EXPECT_TRUE(stats.records.empty());  // kept on request only
  // Every detection's evaluation on request, the same detections and counts.
  config.record_detections = true;
  SimulationData again = data;
  const RenderedSensingStats kept = PerceiveSimulation(again, config);
  ASSERT_EQ(kept.records.size(), static_cast<std::size_t>(kept.detections));
  EXPECT_EQ(kept.accepted, stats.accepted);
  int true_records = 0, accepted_true_records = 0;
  for (const DetectionRecord& d : kept.records) {
    EXPECT_EQ(d.robot, 0);
    EXPECT_TRUE(d.pose == 0 || d.pose == 1) << d.pose;
    if (d.object < 0) continue;
    ++true_records;
    EXPECT_EQ(d.label, "chair");
    EXPECT_EQ(d.pose, 0);  // the robot faces the chair at pose 0 only
    EXPECT_GE(d.depth, 2.0);  // the bin above
    EXPECT_LT(d.depth, 3.0);
    EXPECT_GE(d.visible_fraction, config.min_visible_fraction);
    if (d.status == PerceptionStatus::kAccepted) {
      ++accepted_true_records;
      EXPECT_LT(d.translation_error, 0.1);
      EXPECT_TRUE(d.inliers >= 12 || d.refined_inliers >= 12);  // the gate (registration.h)
      EXPECT_GT(d.geometric_agreement, 0.0);
    }
  }
  EXPECT_EQ(true_records, all.true_detections);
  EXPECT_EQ(accepted_true_records, all.accepted);
  config.record_detections = false;
  config.min_visible_fraction = 1.5;  // a share
  EXPECT_THROW(PerceiveSimulation(data, config), InvalidInputError);
}

TEST(Perception, AnEmptyRoomGivesNoMeasurement) {
  World w = OneObject("chair", 2.0, 0.0);
  w.objects.clear();
  const Renderer renderer(w, RenderConfig{});
  ObjectPerception perception(CommittedModel(), w.classes);
  const FramePerception seen = perception.perceive(renderer.render(kBody, 2).rgbd);
  EXPECT_TRUE(ToObjectDetections(seen).empty());
}

TEST(Perception, ADetectedClassWithoutTemplateIsReportedNotRegistered) {
  const World w = OneObject("chair", 2.0, 0.6);
  const Renderer renderer(w, RenderConfig{});
  // No class description for "chair": no template can be built for it.
  std::vector<ObjectClass> classes;
  for (const ObjectClass& c : StandardObjectClasses()) {
    if (c.label != "chair") classes.push_back(c);
  }
  ObjectPerception perception(CommittedModel(), classes);
  EXPECT_EQ(perception.findTemplate("chair"), nullptr);
  EXPECT_NE(perception.findTemplate("sofa"), nullptr);
  const FramePerception seen = perception.perceive(renderer.render(kBody, 1).rgbd);
  ASSERT_FALSE(seen.objects.empty());
  EXPECT_EQ(seen.objects.front().status, PerceptionStatus::kNoTemplate);
  EXPECT_TRUE(ToObjectDetections(seen).empty());
}

// The object a view measures, for evaluation: the one its registered pose places when a
// same-label object seen lies within the radius, else the box's (MeasuredObject).
TEST(RenderedSensing, AViewMeasuresTheObjectItsPosePlaces) {
  auto seen_object = [](int id, const std::string& label, double x) {
    VisibleObject v;
    v.id = id;
    v.label = label;
    v.camera_T_object = SE3(SO3(), Vector3(x, 0.0, 3.0));
    return v;
  };
  const std::vector<VisibleObject> seen = {seen_object(1, "chair", 0.0),
                                           seen_object(2, "chair", 0.8),
                                           seen_object(3, "table", 0.4)};
  // A box of chair 1 whose segment registered to chair 2 (the neighbour in the box).
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.78, 0.0, 3.02), 1, 0.25), 2);
  // A false box (no object's pixels) that registered to chair 1.
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.03, 0.0, 2.98), -1, 0.25), 1);
  // Far from every chair: the box decides, right or false; the table does not count.
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.4, 0.0, 3.0), 1, 0.25), 1);
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.4, 0.0, 3.0), -1, 0.25), -1);
  // Radius 0: always the box.
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.8, 0.0, 3.0), 1, 0.0), 1);
  EXPECT_EQ(MeasuredObject(seen, "chair", Vector3(0.8, 0.0, 3.0), -1, 0.0), -1);
}

TEST(Perception, ValidatesItsConfig) {
  PerceptionConfig c = CommittedModel();
  c.template_spacing = 0.0;
  EXPECT_THROW(c.validate(), InvalidInputError);
  c = CommittedModel();
  c.templates_dir = "/nonexistent/templates";
  EXPECT_THROW(c.validate(), InvalidInputError);
  c = CommittedModel();
  c.min_box_agreement = 1.5;  // an IoU
  EXPECT_THROW(c.validate(), InvalidInputError);
  c = CommittedModel();
  c.detector.model_path = "/nonexistent/model.onnx";
  EXPECT_THROW(ObjectPerception(c, StandardObjectClasses()), InvalidInputError);
  RenderedSensingConfig r;
  r.perception = CommittedModel();
  r.every = 0;
  EXPECT_THROW(r.validate(), InvalidInputError);
}

// (A default config is refused for its empty model path: the changes start from a valid one.)
TEST(RenderedSensing, BadOptionsNameTheField) {
  using C = RenderedSensingConfig;
  C valid;
  valid.perception = CommittedModel();
  EXPECT_TRUE(test::EachChangeIsRefused<C>(
      {
          {"every", [](C& c) { c.every = 0; }},
          {"min_visible_fraction", [](C& c) { c.min_visible_fraction = -0.1; }},
          {"same_object_radius", [](C& c) { c.same_object_radius = std::nan(""); }},
          {"same_object_radius", [](C& c) { c.same_object_radius = -1.0; }},
      },
      valid));
}

}  // namespace
}  // namespace moslam
