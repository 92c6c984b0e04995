#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <queue>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/sim/robots.h"
#include "moslam/sim/sensing.h"
#include "moslam/sim/world.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

double PoseDistance(const SE3& a, const SE3& b) {
  return SE3::Log(a.between(b)).norm();
}

void ExpectSameWorld(const World& a, const World& b) {
  EXPECT_EQ(a.name, b.name);
  ASSERT_EQ(a.classes.size(), b.classes.size());
  for (std::size_t i = 0; i < a.classes.size(); ++i) {
    EXPECT_EQ(a.classes[i].label, b.classes[i].label);
    EXPECT_EQ(a.classes[i].extent, b.classes[i].extent);
  }
  ASSERT_EQ(a.objects.size(), b.objects.size());
  for (std::size_t i = 0; i < a.objects.size(); ++i) {
    EXPECT_EQ(a.objects[i].id, b.objects[i].id);
    EXPECT_EQ(a.objects[i].label, b.objects[i].label);
    EXPECT_EQ(a.objects[i].pose.translation(), b.objects[i].pose.translation());
    EXPECT_LT(PoseDistance(a.objects[i].pose, b.objects[i].pose), 1e-12);
  }
  ASSERT_EQ(a.rooms.size(), b.rooms.size());
  for (std::size_t i = 0; i < a.rooms.size(); ++i) {
    EXPECT_EQ(a.rooms[i].name, b.rooms[i].name);
    EXPECT_EQ(a.rooms[i].min, b.rooms[i].min);
    EXPECT_EQ(a.rooms[i].max, b.rooms[i].max);
  }
  EXPECT_EQ(a.navigation.nodes, b.navigation.nodes);
  EXPECT_EQ(a.navigation.edges, b.navigation.edges);
}

bool NavigationConnected(const NavigationGraph& nav) {
  if (nav.nodes.empty()) return true;
  const auto nb = nav.neighbours();
  std::vector<bool> seen(nav.nodes.size(), false);
  std::queue<int> q;
  q.push(0);
  seen[0] = true;
  std::size_t count = 1;
  while (!q.empty()) {
    const int i = q.front();
    q.pop();
    for (int j : nb[static_cast<std::size_t>(i)]) {
      if (!seen[static_cast<std::size_t>(j)]) {
        seen[static_cast<std::size_t>(j)] = true;
        ++count;
        q.push(j);
      }
    }
  }
  return count == nav.nodes.size();
}

double DistanceToNavigation(const NavigationGraph& nav, const Vector2& p) {
  double best = 1e300;
  for (const auto& [i, j] : nav.edges) {
    const Vector2 a = nav.nodes[static_cast<std::size_t>(i)];
    const Vector2 b = nav.nodes[static_cast<std::size_t>(j)];
    const double s = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + s * (b - a))).norm());
  }
  return best;
}

// ----------------------------------------------------------------------------------- worlds

TEST(World, Chairs25IsAGridOfChairsAtRandomYaws) {
  const World w = MakeChairs25World();
  ValidateWorld(w);
  ASSERT_EQ(w.objects.size(), 25u);
  std::set<std::pair<long, long>> cells;
  std::set<long> yaws;
  for (const auto& o : w.objects) {
    EXPECT_EQ(o.label, "chair");
    const Vector3 t = o.pose.translation();
    const double gx = t.x() / 2.5, gy = t.y() / 2.5;
    EXPECT_NEAR(gx, std::round(gx), 1e-12);
    EXPECT_NEAR(gy, std::round(gy), 1e-12);
    EXPECT_NEAR(t.z(), 0.45, 1e-12);  // chair centre: half its 0.9 m height
    cells.insert({std::lround(gx), std::lround(gy)});
    // Yaw only: the z axis stays up.
    EXPECT_NEAR(o.pose.rotation().matrix()(2, 2), 1.0, 1e-12);
    yaws.insert(std::lround(std::atan2(o.pose.rotation().matrix()(1, 0),
                                       o.pose.rotation().matrix()(0, 0)) / kDeg));
  }
  EXPECT_EQ(cells.size(), 25u);
  EXPECT_GT(yaws.size(), 20u);  // random yaws, not all equal
  EXPECT_EQ(w.navigation.nodes.size(), 36u);
  EXPECT_EQ(w.navigation.edges.size(), 60u);
  EXPECT_TRUE(NavigationConnected(w.navigation));
}

TEST(World, Chairs25IsSeeded) {
  Chairs25Config c;
  c.seed = 7;
  EXPECT_EQ(WorldToJson(MakeChairs25World(c)), WorldToJson(MakeChairs25World(c)));
  Chairs25Config d = c;
  d.seed = 8;
  EXPECT_NE(WorldToJson(MakeChairs25World(c)), WorldToJson(MakeChairs25World(d)));
  c.spacing = 0.0;
  EXPECT_THROW(MakeChairs25World(c), InvalidInputError);
}

TEST(World, HouseHasLivingRoomAndKitchenFurniture) {
  const World w = MakeHouseWorld();
  ValidateWorld(w);
  std::multiset<std::string> labels;
  for (const auto& o : w.objects) labels.insert(o.label);
  for (const char* l : {"sofa", "tv", "coffee_table", "armchair", "shelf", "plant", "fridge",
                        "counter", "table"}) {
    EXPECT_GE(labels.count(l), 1u) << l;
  }
  EXPECT_EQ(labels.count("chair"), 4u);
  ASSERT_EQ(w.rooms.size(), 2u);
  for (const auto& o : w.objects) {
    const Vector3 t = o.pose.translation();
    bool inside = false;
    for (const auto& r : w.rooms) {
      inside |= t.x() > r.min.x() && t.x() < r.max.x() && t.y() > r.min.y() && t.y() < r.max.y();
    }
    EXPECT_TRUE(inside) << o.label << " " << o.id;
  }
  EXPECT_TRUE(NavigationConnected(w.navigation));
}

TEST(World, GeneratedWorldIsConnectedSeededAndKeepsObjectsOffThePaths) {
  GeneratedWorldConfig c;
  c.rooms_x = 4;
  c.rooms_y = 3;
  c.seed = 3;
  const World w = MakeGeneratedWorld(c);
  ValidateWorld(w);
  EXPECT_EQ(WorldToJson(w), WorldToJson(MakeGeneratedWorld(c)));
  EXPECT_EQ(w.rooms.size(), 12u);
  EXPECT_TRUE(NavigationConnected(w.navigation));
  EXPECT_GE(w.objects.size(), 12u * 2u);
  for (const auto& o : w.objects) {
    const Vector2 p = o.pose.translation().head<2>();
    EXPECT_GE(DistanceToNavigation(w.navigation, p), c.object_clearance - 1e-12);
    for (const auto& q : w.objects) {
      if (q.id != o.id) {
        EXPECT_GE((q.pose.translation().head<2>() - p).norm(), c.object_separation - 1e-12);
      }
    }
  }
  GeneratedWorldConfig d = c;
  d.seed = 4;
  EXPECT_NE(WorldToJson(w), WorldToJson(MakeGeneratedWorld(d)));
  const GeneratedWorldConfig big = GeneratedWorldForTeam(128);
  EXPECT_GE(big.rooms_x * big.rooms_y, 64);
  d.max_objects_per_room = d.min_objects_per_room - 1;
  EXPECT_THROW(MakeGeneratedWorld(d), InvalidInputError);
  EXPECT_THROW(MakeScenarioWorld("office"), InvalidInputError);
}

TEST(World, JsonRoundTripIsExact) {
  for (const World& w : {MakeChairs25World(), MakeHouseWorld(), MakeGeneratedWorld()}) {
    ExpectSameWorld(w, WorldFromJson(WorldToJson(w), w.name));
  }
  const std::string path = (test::ScratchDir() / "roundtrip.json").string();
  const World house = MakeHouseWorld();
  SaveWorld(path, house);
  ExpectSameWorld(house, LoadWorld(path));
}

// A rotation is read whatever the norm of its quaternion, if finite and not zero: one of 1e200
// used to overflow to an infinite norm and escape the reader as std::invalid_argument
// (seen while writing fuzz/text_files_fuzz.cc).
TEST(World, QuaternionsOfAnyFiniteNormAreRead) {
  using nlohmann::json;
  json j = json::parse(WorldToJson(MakeHouseWorld()));
  j["objects"][0]["rotation"] = {0.0, 0.0, 1e200, 1e200};
  j["objects"][1]["rotation"] = {0.0, 0.0, 1e-200, 1e-200};
  const World w = WorldFromJson(j.dump(), "scaled.json");
  const Matrix3 quarter_turn = SO3::FromQuaternion(1.0, 0.0, 0.0, 1.0).matrix();
  EXPECT_LT((w.objects[0].pose.rotation().matrix() - quarter_turn).norm(), 1e-15);
  EXPECT_LT((w.objects[1].pose.rotation().matrix() - quarter_turn).norm(), 1e-15);
}

TEST(World, JsonRejectsBadFilesNamingTheProblem) {
  using nlohmann::json;
  const json good = json::parse(WorldToJson(MakeHouseWorld()));
  struct Case {
    std::string expect;  // a substring of the message
    std::function<void(json&)> mutate;
  };
  const std::vector<Case> cases = {
      {"unknown key 'colour'", [](json& j) { j["objects"][0]["colour"] = "red"; }},
      {"missing key 'navigation'", [](json& j) { j.erase("navigation"); }},
      {"version", [](json& j) { j["version"] = 2; }},
      {"format", [](json& j) { j["format"] = "other"; }},
      {"objects[3].label 'chiar' is not a declared class",
       [](json& j) { j["objects"][3]["label"] = "chiar"; }},
      {"objects[1].id 0 is used twice", [](json& j) { j["objects"][1]["id"] = 0; }},
      {"zero quaternion", [](json& j) { j["objects"][2]["rotation"] = {0, 0, 0, 0}; }},
      {"objects[2].translation", [](json& j) { j["objects"][2]["translation"] = {1, 2}; }},
      {"expected a number", [](json& j) { j["objects"][2]["translation"][0] = "x"; }},
      {"classes[0].extent must be three positive", [](json& j) { j["classes"][0]["extent"][1] = -1; }},
      {"declared twice", [](json& j) { j["classes"][1]["label"] = j["classes"][0]["label"]; }},
      {"rooms[0] needs finite min < max", [](json& j) { j["rooms"][0]["max"] = {-1, 3}; }},
      {"joins a node that does not exist", [](json& j) { j["navigation"]["edges"][0] = {0, 999}; }},
      {"self-loop", [](json& j) { j["navigation"]["edges"][0] = {2, 2}; }},
      {"duplicated", [](json& j) { j["navigation"]["edges"][1] = j["navigation"]["edges"][0]; }},
      {"expected an integer", [](json& j) { j["objects"][0]["id"] = 1.5; }},
  };
  for (const auto& c : cases) {
    json j = good;
    c.mutate(j);
    const auto read = [&] { WorldFromJson(j.dump(), "bad.json"); };
    EXPECT_TRUE(test::ThrowsNaming(read, c.expect));
    EXPECT_TRUE(test::ThrowsNaming(read, "bad.json")) << c.expect;
  }
  EXPECT_THROW(WorldFromJson("{ not json", "x"), InvalidInputError);
  EXPECT_THROW(LoadWorld(testing::TempDir() + "/no/such/world.json"), InvalidInputError);
}

// ------------------------------------------------------------------------------ trajectories

TEST(Robots, TrajectoriesFollowTheNavigationGraphFromDistinctStarts) {
  const World w = MakeChairs25World();
  TrajectoryConfig c;
  c.num_robots = 6;
  c.poses_per_robot = 80;
  const auto trajs = GenerateTrajectories(w, c);
  ASSERT_EQ(trajs.size(), 6u);
  std::set<std::pair<double, double>> starts;
  for (const auto& t : trajs) {
    ASSERT_EQ(t.size(), 80u);
    starts.insert({t[0].translation().x(), t[0].translation().y()});
    for (std::size_t i = 0; i < t.size(); ++i) {
      EXPECT_NEAR(t[i].translation().z(), c.camera_height, 1e-12);
      EXPECT_LT(DistanceToNavigation(w.navigation, t[i].translation().head<2>()), 1e-9);
      EXPECT_NEAR(t[i].rotation().matrix()(2, 2), 1.0, 1e-12);  // yaw only
      if (i > 0) {
        const double step = (t[i].translation() - t[i - 1].translation()).norm();
        EXPECT_LE(step, c.step_length + 1e-9);  // a chord of step_length of path
        EXPECT_GT(step, 0.0);
      }
    }
  }
  EXPECT_EQ(starts.size(), 6u);
  // Seeded.
  const auto again = GenerateTrajectories(w, c);
  for (std::size_t r = 0; r < trajs.size(); ++r) {
    for (std::size_t i = 0; i < trajs[r].size(); ++i) {
      EXPECT_EQ(trajs[r][i].translation(), again[r][i].translation());
    }
  }
  c.num_robots = 37;  // more robots than the 36 nodes
  EXPECT_THROW(GenerateTrajectories(w, c), InvalidInputError);
}

TEST(Robots, RendezvousWhenWithinRangeEveryMinGapSteps) {
  // Robot 0 stands still at the origin; robot 1 drives past it along x from -10 to +10 m.
  std::vector<Trajectory> t(3);
  for (int i = 0; i <= 20; ++i) {
    t[0].push_back(SE3());
    t[1].push_back(SE3(SO3(), Vector3(-10.0 + i, 0.0, 0.0)));
    t[2].push_back(SE3(SO3(), Vector3(100.0, 0.0, 0.0)));  // far from everybody
  }
  RendezvousDetectionConfig c;
  c.communication_range = 2.5;
  c.min_steps_between_events = 3;
  // In range at steps 8..12 (|x| <= 2): events at 8 and 11.
  const auto events = DetectRendezvous(t, c);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0], (RendezvousEvent{8, 0, 1}));
  EXPECT_EQ(events[1], (RendezvousEvent{11, 0, 1}));

  c.schedule = {{15, 2, 0}, {4, 1, 2}};
  const auto planned = DetectRendezvous(t, c);
  ASSERT_EQ(planned.size(), 2u);
  EXPECT_EQ(planned[0], (RendezvousEvent{4, 1, 2}));
  EXPECT_EQ(planned[1], (RendezvousEvent{15, 2, 0}));
  c.schedule = {{21, 0, 1}};
  EXPECT_THROW(DetectRendezvous(t, c), InvalidInputError);
  c.schedule = {{3, 1, 1}};
  EXPECT_THROW(DetectRendezvous(t, c), InvalidInputError);
  c.schedule = {{3, 0, 3}};
  EXPECT_THROW(DetectRendezvous(t, c), InvalidInputError);
}

// Bad trajectory and rendezvous settings are input errors that name the field, before any work.
TEST(Robots, BadConfigsThrowNamingTheField) {
  const World world = MakeChairs25World();
  auto trajectories = [&](auto change, const char* field) {
    TrajectoryConfig t;
    change(t);
    return test::ThrowsNaming([&] { GenerateTrajectories(world, t); }, field);
  };
  EXPECT_TRUE(trajectories([](TrajectoryConfig& t) { t.step_length = 0.0; }, "step_length"));
  EXPECT_TRUE(trajectories([](TrajectoryConfig& t) { t.poses_per_robot = 0; }, "poses_per_robot"));
  EXPECT_TRUE(
      trajectories([](TrajectoryConfig& t) { t.camera_height = std::nan(""); }, "camera_height"));
  const std::vector<Trajectory> paths(2, Trajectory(3, SE3()));
  RendezvousDetectionConfig r;
  EXPECT_NO_THROW(DetectRendezvous(paths, r));
  r.communication_range = -1.0;
  EXPECT_TRUE(test::ThrowsNaming([&] { DetectRendezvous(paths, r); }, "communication_range"));
  r = RendezvousDetectionConfig();
  r.min_steps_between_events = 0;
  EXPECT_TRUE(test::ThrowsNaming([&] { DetectRendezvous(paths, r); }, "min_steps_between_events"));
}

// ---------------------------------------------------------------------------------- sensing

TEST(Sensing, CameraFrustumAndRange) {
  CameraModel cam;
  cam.horizontal_fov_deg = 90.0;
  cam.vertical_fov_deg = 60.0;
  cam.min_range = 0.3;
  cam.max_range = 6.0;
  EXPECT_TRUE(cam.sees(Vector3(3.0, 0.0, 0.0)));
  EXPECT_TRUE(cam.sees(Vector3(3.0, 2.9, 0.0)));    // 44 deg left
  EXPECT_FALSE(cam.sees(Vector3(3.0, 3.1, 0.0)));   // 46 deg left
  EXPECT_FALSE(cam.sees(Vector3(3.0, -3.1, 0.0)));  // 46 deg right
  EXPECT_TRUE(cam.sees(Vector3(3.0, 0.0, 1.7)));    // 29.5 deg up
  EXPECT_FALSE(cam.sees(Vector3(3.0, 0.0, -1.8)));  // 31 deg down
  EXPECT_FALSE(cam.sees(Vector3(-3.0, 0.0, 0.0)));  // behind
  EXPECT_FALSE(cam.sees(Vector3(6.1, 0.0, 0.0)));   // too far
  EXPECT_FALSE(cam.sees(Vector3(0.2, 0.0, 0.0)));   // too close
  cam.max_range = 0.1;
  EXPECT_THROW(cam.validate(), InvalidInputError);
}

TEST(Sensing, NoiseFreeMeasurementsAreTheTrueRelativePoses) {
  const World w = MakeHouseWorld();
  SimulationConfig c;
  c.trajectory.num_robots = 3;
  c.trajectory.poses_per_robot = 40;
  c.sensing.odometry = {0.0, 0.0};
  c.sensing.objects = {0.0, 0.0};
  const SimulationData d = Simulate(w, c);
  Vector6 floor_info;
  floor_info.setConstant(1.0 / (c.sensing.information_sigma_floor * c.sensing.information_sigma_floor));
  int detections = 0;
  for (int r = 0; r < 3; ++r) {
    const auto& t = d.trajectories[static_cast<std::size_t>(r)];
    const auto& m = d.measurements[static_cast<std::size_t>(r)];
    ASSERT_EQ(m.odometry.size(), t.size() - 1);
    ASSERT_EQ(m.detections.size(), t.size());
    for (std::size_t i = 0; i + 1 < t.size(); ++i) {
      EXPECT_LT(PoseDistance(m.odometry[i].measurement, t[i].between(t[i + 1])), 1e-12);
      EXPECT_EQ(m.odometry[i].information.diagonal(), floor_info);
    }
    for (std::size_t i = 0; i < t.size(); ++i) {
      std::set<int> expected;
      for (const auto& o : w.objects) {
        if (c.sensing.camera.sees(t[i].inverse().transformFrom(o.pose.translation()))) {
          expected.insert(o.id);
        }
      }
      std::set<int> seen;
      for (const auto& det : m.detections[i]) {
        seen.insert(det.object_id);
        const auto& o = w.object(det.object_id);
        EXPECT_EQ(det.label, o.label);
        EXPECT_LT(PoseDistance(det.measurement, t[i].between(o.pose)), 1e-12);
        ++detections;
      }
      EXPECT_EQ(seen, expected);
    }
  }
  EXPECT_GT(detections, 100);
}

TEST(Sensing, NoiseHasTheConfiguredSigmasOnTheRight) {
  const World w = MakeChairs25World();
  SimulationConfig c;
  c.trajectory.num_robots = 6;
  c.trajectory.poses_per_robot = 200;
  c.sensing.odometry = {5.0, 0.2};
  c.sensing.objects = {2.0, 0.1};
  const SimulationData d = Simulate(w, c);
  // n = Log(z_true^-1 z_noisy) must have per-axis RMS sigma and mean ~0.
  auto check = [](const std::vector<Vector6>& n, double sr, double st) {
    ASSERT_GT(n.size(), 1000u);
    Vector6 mean = Vector6::Zero(), sq = Vector6::Zero();
    for (const auto& v : n) {
      mean += v;
      sq += v.cwiseAbs2();
    }
    mean /= static_cast<double>(n.size());
    sq /= static_cast<double>(n.size());
    for (int k = 0; k < 6; ++k) {
      const double sigma = k < 3 ? sr : st;
      // Relative standard error of an RMS over > 1000 samples is < 2.3%: 8% is > 3.5 of them.
      EXPECT_NEAR(std::sqrt(sq[k]), sigma, 0.08 * sigma) << "axis " << k;
      EXPECT_NEAR(mean[k], 0.0, 4.0 * sigma / std::sqrt(static_cast<double>(n.size())));
    }
  };
  std::vector<Vector6> odo, obj;
  for (std::size_t r = 0; r < d.trajectories.size(); ++r) {
    const auto& t = d.trajectories[r];
    for (std::size_t i = 0; i + 1 < t.size(); ++i) {
      odo.push_back(SE3::Log(t[i].between(t[i + 1]).between(d.measurements[r].odometry[i].measurement)));
    }
    for (std::size_t i = 0; i < t.size(); ++i) {
      for (const auto& det : d.measurements[r].detections[i]) {
        obj.push_back(SE3::Log(t[i].between(w.object(det.object_id).pose).between(det.measurement)));
      }
    }
  }
  check(odo, 5.0 * kDeg, 0.2);
  check(obj, 2.0 * kDeg, 0.1);
  const Matrix6 info = d.measurements[0].odometry[0].information;
  EXPECT_NEAR(info(0, 0), 1.0 / std::pow(5.0 * kDeg, 2), 1e-9);
  EXPECT_NEAR(info(5, 5), 1.0 / 0.04, 1e-9);
  EXPECT_EQ(info(0, 1), 0.0);
}

TEST(Sensing, SimulationIsSeededPerRobot) {
  const World w = MakeChairs25World();
  SimulationConfig c;
  c.trajectory.num_robots = 3;
  c.trajectory.poses_per_robot = 30;
  const SimulationData a = Simulate(w, c), b = Simulate(w, c);
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t i = 0; i < a.measurements[r].odometry.size(); ++i) {
      EXPECT_EQ(a.measurements[r].odometry[i].measurement.translation(),
                b.measurements[r].odometry[i].measurement.translation());
    }
  }
  EXPECT_EQ(a.rendezvous.size(), b.rendezvous.size());
  // A robot's trajectory and noise do not depend on the team size (its own noise stream).
  SimulationConfig more = c;
  more.trajectory.num_robots = 4;
  const SimulationData m = Simulate(w, more);
  for (std::size_t r = 0; r < 3; ++r) {
    EXPECT_EQ(m.trajectories[r].back().translation(), a.trajectories[r].back().translation());
    EXPECT_EQ(m.measurements[r].odometry.back().measurement.translation(),
              a.measurements[r].odometry.back().measurement.translation());
  }
  SensingConfig s = c.sensing;
  s.objects.sigma_translation = -1.0;
  EXPECT_THROW(SimulateSensing(w, a.trajectories, s), InvalidInputError);
}

TEST(Sensing, CoverageCountsThePosesWithoutMeasurementAndTheLongestStretchPerRobot) {
  const ObjectDetection d{"chair", SE3(), Matrix6::Identity(), 0};
  RobotMeasurements a, b;
  a.detections = {{d, d}, {}, {}, {d}, {}};  // stretches of 2 and 1
  b.detections = {{}, {}, {d, d, d}};        // 2; robot a's last stretch does not run into b
  const MeasurementCoverage c = CoverageOf({a, b});
  EXPECT_EQ(c.poses, 8);
  EXPECT_EQ(c.measurements, 6);
  EXPECT_EQ(c.poses_without, 5);
  EXPECT_EQ(c.longest_without, 2);
  EXPECT_DOUBLE_EQ(c.perPose(), 0.75);
  EXPECT_DOUBLE_EQ(c.fractionWithout(), 5.0 / 8.0);
  const MeasurementCoverage none = CoverageOf({});
  EXPECT_EQ(none.poses, 0);
  EXPECT_EQ(none.perPose(), 0.0);
  EXPECT_EQ(none.fractionWithout(), 0.0);
}

TEST(Sensing, BadInformationFloorIsNamed) {
  using C = SensingConfig;
  EXPECT_TRUE(test::EachChangeIsRefused<C>({
      {"information_sigma_floor", [](C& c) { c.information_sigma_floor = 0.0; }},
      {"information_sigma_floor", [](C& c) { c.information_sigma_floor = INFINITY; }},
  }));
}

}  // namespace
}  // namespace moslam

namespace moslam {
namespace {

TEST(Sensing, NoiseSimulationConfigSetsTheTeamTheSeedAndOneNoiseForBothSensors) {
  const SimulationConfig c = NoiseSimulationConfig(4, 30, 17, 2.5, 0.1);
  EXPECT_EQ(c.trajectory.num_robots, 4);
  EXPECT_EQ(c.trajectory.poses_per_robot, 30);
  EXPECT_EQ(c.trajectory.seed, 17u);
  EXPECT_EQ(c.sensing.seed, 17u);
  for (const NoiseModel& n : {c.sensing.odometry, c.sensing.objects}) {
    EXPECT_EQ(n.sigma_rotation_deg, 2.5);
    EXPECT_EQ(n.sigma_translation, 0.1);
  }
  const SimulationConfig defaults;  // everything else as a default config has it
  EXPECT_EQ(c.sensing.camera.max_range, defaults.sensing.camera.max_range);
  EXPECT_NO_THROW(c.validate());
}

}  // namespace
}  // namespace moslam
