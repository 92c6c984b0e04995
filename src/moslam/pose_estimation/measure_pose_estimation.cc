// Measures segmentation + registration on rendered frames (render/renderer.h): one object of a
// class at the centre of a room (8 x 8 m, larger with --max-distance beyond 3 m), seen from
// `--views` random viewpoints (1.5-3 m away by default, camera 0.5 m above the floor, random
// object yaw), segmented in its ground-truth box and registered to the template sampled from the
// same class model. --dining sets four chairs around it as around house's kitchen table; the
// chairs' pixels are left out of its segment with --claim-others-truth (by their ground-truth
// instance ids: what instance masks would give) or --claim-others-segments (the chairs' own
// segments in their true boxes) or --claim-others-registered (the pixels within --claim-radius
// of the chairs' templates where their registrations, each in its true box, put them). Prints
// per-view status, inliers, pose error against ground truth and per-stage times (wall clock; the
// process CPU time is printed too because the machine may be shared). Not a test: a measurement
// tool.
//
//   measure_pose_estimation --label chair --views 20 [--min-distance 1.5 --max-distance 3]
//     [--dining] [--claim-others-truth | --claim-others-segments | --claim-others-registered]
//     [--voxel 0.015 --keypoint-voxel 0.03 --feature-radius 0.05 --normal-radius 0.03
//     --sac-iterations 500 --seed 1]
#include <pcl/kdtree/kdtree_flann.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/statistics.h"
#include "moslam/pose_estimation/registration.h"
#include "moslam/pose_estimation/segmentation.h"
#include "moslam/render/object_models.h"
#include "moslam/render/renderer.h"
#include "moslam/sim/world.h"

namespace {

using namespace moslam;

constexpr double kPi = 3.14159265358979323846;

struct MeasureArgs {
  std::string label = "chair";
  int views = 20;
  unsigned seed = 1;
  double template_spacing = 0.005;
  double min_distance = 1.5, max_distance = 3.0;
  RegistrationConfig config;
  bool diagnose = false;
  bool dining = false;
  bool claim_truth = false;
  bool claim_segments = false;
  bool claim_registered = false;
  double claim_radius = 0.04;
};

void AddOptions(CLI::App& app, MeasureArgs& a) {
  RegistrationConfig& config = a.config;
  app.add_option("--label", a.label, "object class (sim/world.h StandardObjectClasses)");
  app.add_option("--views", a.views, "number of rendered views");
  app.add_option("--seed", a.seed, "viewpoint seed");
  app.add_option("--template-spacing", a.template_spacing, "template surface sampling (m)");
  app.add_option("--min-distance", a.min_distance, "nearest viewpoint (m)");
  app.add_option("--max-distance", a.max_distance, "farthest viewpoint (m)");
  app.add_option("--voxel", config.features.voxel_size, "segment/template voxel (m)");
  app.add_option("--keypoint-voxel", config.features.keypoint_voxel, "keypoint voxel (m)");
  app.add_option("--normal-radius", config.features.normal_radius, "normal radius (m)");
  app.add_option("--feature-radius", config.features.feature_radius, "PFHRGB radius (m)");
  app.add_option("--feature-surface-voxel", config.features.feature_surface_voxel,
                 "PFHRGB search surface voxel (m)");
  app.add_option("--sac-iterations", config.sac_iterations, "SAC-IA iterations");
  app.add_option("--consensus", config.consensus, "0 = prerejective, 1 = SAC-IA");
  app.add_option("--pre-iterations", config.prerejective_iterations, "prerejective iterations");
  app.add_option("--similarity", config.prerejective_similarity, "prerejective similarity");
  app.add_option("--inlier-fraction", config.prerejective_inlier_fraction,
                 "prerejective inlier fraction");
  app.add_option("--min-sample-distance", config.sac_min_sample_distance, "sample spread (m)");
  app.add_option("--upright-yaws", config.upright_yaws, "upright hypotheses (0: none)");
  app.add_option("--upright-min-extent", config.upright_min_extent, "upright: min extent (m)");
  app.add_option("--coarse-distance", config.gicp_coarse_max_correspondence_distance, "m");
  app.add_option("--feature-eps", config.feature_search_epsilon, "FLANN epsilon");
  app.add_option("--max-keypoints", config.max_segment_keypoints, "segment keypoint cap");
  app.add_option("--gicp-coarse-points", config.gicp_coarse_points, "coarse GICP points");
  app.add_option("--gicp-coarse-iterations", config.gicp_coarse_iterations, "coarse GICP its");
  app.add_option("--gicp-max-points", config.gicp_max_source_points, "GICP source cap");
  app.add_option("--sac-k", config.sac_correspondence_randomness, "SAC-IA k");
  app.add_option("--gicp-iterations", config.gicp_max_iterations, "GICP iterations");
  app.add_option("--gicp-distance", config.gicp_max_correspondence_distance, "GICP max dist (m)");
  app.add_option("--inlier-distance", config.inlier_distance, "gate distance (m)");
  app.add_option("--sac-distance", config.sac_max_correspondence_distance, "SAC-IA error (m)");
  app.add_option("--symmetry-turns", config.symmetry_turns, "symmetry hypotheses (1, 2, 4)");
  app.add_option("--min-colour-agreement", config.min_colour_agreement, "colour gate");
  app.add_option("--colour-tolerance", config.colour_tolerance, "chromaticity tolerance");
  app.add_flag("--claim-others-registered", a.claim_registered,
               "leave out the pixels within --claim-radius of the other objects' templates at "
               "their registered poses (each segmented in its true box and registered)");
  app.add_option("--claim-radius", a.claim_radius, "m, with --claim-others-registered");
  app.add_flag("--claim-others-segments", a.claim_segments,
               "leave the other objects' segments (in their true boxes) out of the segment");
  app.add_flag("--claim-others-truth", a.claim_truth,
               "leave the other objects' pixels (ground truth) out of the segment");
  app.add_flag("--dining", a.dining,
               "four chairs around the object, as house's kitchen table (sim/world.cc)");
  app.add_flag("--diagnose", a.diagnose, "also run GICP from the true pose");
}

// The measured object (id 0) at the centre of a room every viewpoint fits in; with `dining`,
// house's kitchen chairs around it: 0.4 m either side of the centre, 0.55 m out, backs out.
World MeasurementWorld(const ObjectClass& cls, double max_distance, bool dining) {
  World world;
  world.name = "measure";
  world.classes = StandardObjectClasses();
  const double half_room = std::max(4.0, max_distance + 1.0);
  world.rooms.push_back({"room", Vector2(-half_room, -half_room), Vector2(half_room, half_room)});
  world.objects.push_back({0, cls.label, SE3(SO3(), Vector3(0.0, 0.0, 0.5 * cls.extent.z()))});
  if (dining) {
    const double chair_z = 0.5 * world.findClass("chair")->extent.z();
    int id = 1;
    for (const double x : {-0.4, 0.4}) {
      for (const double y : {-0.55, 0.55}) {
        const SO3 facing = SO3::Exp(Vector3(0, 0, y < 0 ? kPi / 2 : -kPi / 2));
        world.objects.push_back({id++, "chair", SE3(facing, Vector3(x, y, chair_z))});
      }
    }
  }
  return world;
}

// The templates of the classes, sampled from their models, built when first asked for.
class Templates {
 public:
  Templates(const World& world, const MeasureArgs& a) : world_(world), a_(a) {}
  const ObjectTemplate& of(const std::string& label) {
    auto it = built_.find(label);
    if (it == built_.end()) it = built_.emplace(label, build(*world_.findClass(label))).first;
    return it->second;
  }

 private:
  ObjectTemplate build(const ObjectClass& c) const {
    return MakeObjectTemplate(
        c.label, SampleMeshSurface(MakeObjectMesh(c), a_.template_spacing, 1u), a_.config.features);
  }

  const World& world_;
  const MeasureArgs& a_;
  std::map<std::string, ObjectTemplate> built_;
};

// The pixels within `radius` of the other objects' templates where their registrations (each
// segmented in its true box) put them; `accepted`: how many of them were registered.
std::vector<int> ClaimedByRegistrations(const RenderedFrame& f, const PreparedFrame& prepared,
                                        const MeasureArgs& a, Templates& templates, int* accepted) {
  const SegmentationConfig seg_config;
  std::vector<int> claimed;
  const OrganizedCloud& cloud = *prepared.cloud;
  for (const VisibleObject& other : f.objects) {
    if (other.id == 0) continue;
    const ObjectTemplate& ot = templates.of(other.label);
    const SegmentationResult o = SegmentObject(prepared, cv::Rect2f(other.box), seg_config);
    if (o.status != SegmentationStatus::kOk) continue;
    const RegistrationResult orr = RegisterTemplate(*o.segment, ot, a.config);
    if (!orr.accepted()) continue;
    ++*accepted;
    pcl::PointCloud<pcl::PointXYZ>::Ptr placed(new pcl::PointCloud<pcl::PointXYZ>);
    for (const auto& q : ot.cloud->points) {
      const Vector3 c = orr.camera_T_object.transformFrom(Vector3(q.x, q.y, q.z));
      placed->push_back(pcl::PointXYZ(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                      static_cast<float>(c.z())));
    }
    pcl::KdTreeFLANN<pcl::PointXYZ> tree;
    tree.setInputCloud(placed);
    std::vector<int> nn(1);
    std::vector<float> d2(1);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const auto& p = cloud.points[i];
      if (!std::isfinite(p.z)) continue;
      if (tree.nearestKSearch(pcl::PointXYZ(p.x, p.y, p.z), 1, nn, d2) == 1 &&
          d2[0] < a.claim_radius * a.claim_radius) {
        claimed.push_back(static_cast<int>(i));
      }
    }
  }
  return claimed;
}

// The pixels left out of the measured object's segment (--claim-others-*).
std::vector<int> ClaimedPixels(const RenderedFrame& f, const PreparedFrame& prepared,
                               const MeasureArgs& a, Templates& templates, int* others_accepted) {
  const SegmentationConfig seg_config;
  std::vector<int> claimed;
  if (a.claim_segments) {
    for (const VisibleObject& other : f.objects) {
      if (other.id == 0) continue;
      const SegmentationResult o = SegmentObject(prepared, cv::Rect2f(other.box), seg_config);
      claimed.insert(claimed.end(), o.indices.begin(), o.indices.end());
    }
  }
  if (a.claim_registered) {
    const std::vector<int> c = ClaimedByRegistrations(f, prepared, a, templates, others_accepted);
    claimed.insert(claimed.end(), c.begin(), c.end());
  }
  if (a.claim_truth) {
    for (int v = 0; v < f.instance_ids.rows; ++v) {
      for (int u = 0; u < f.instance_ids.cols; ++u) {
        if (f.instance_ids.at<int>(v, u) > 0) claimed.push_back(v * f.instance_ids.cols + u);
      }
    }
  }
  return claimed;
}

double RotationErrorDeg(const SE3& truth, const SE3& estimate) {
  return SE3::Log(truth.inverse() * estimate).head<3>().norm() * 180.0 / kPi;
}

// The segment's precision and recall against the object's visible pixels.
std::pair<double, double> SegmentQuality(const RenderedFrame& f, const SegmentationResult& seg,
                                         int id) {
  int on_object = 0, object_pixels = 0;
  const int width = f.rgbd.intrinsics.width;
  for (int i : seg.indices) on_object += f.instance_ids.at<int>(i / width, i % width) == id;
  for (int v = 0; v < f.instance_ids.rows; ++v) {
    for (int u = 0; u < f.instance_ids.cols; ++u) {
      object_pixels += f.instance_ids.at<int>(v, u) == id && f.rgbd.depth.at<float>(v, u) > 0.0f;
    }
  }
  return {static_cast<double>(on_object) / static_cast<double>(seg.indices.size()),
          static_cast<double>(on_object) / std::max(1, object_pixels)};
}

// The lines printed before a view's line: the consensus' error, the segment's quality, GICP from
// the true pose (--diagnose), the error's axis, the others registered and the pose's scores.
void PrintViewDetails(const RenderedFrame& f, const VisibleObject& truth,
                      const SegmentationResult& seg, const RegistrationResult& r,
                      const ObjectTemplate& tmpl, const MeasureArgs& a, int others_accepted) {
  double truth_t = std::nan(""), truth_r = std::nan(""), truth_colour = std::nan("");
  const char* truth_status = "-";
  if (a.diagnose) {
    RegistrationConfig truth_config = a.config;
    truth_config.symmetry_turns = 1;
    const RegistrationResult g =
        RefinePose(*seg.segment, tmpl, truth.camera_T_object, truth_config);
    truth_colour = g.colour_agreement;
    truth_status = ToString(g.status);
    truth_t = (truth.camera_T_object.translation() - g.camera_T_object.translation()).norm();
    truth_r = RotationErrorDeg(truth.camera_T_object, g.camera_T_object);
  }
  const double sac_t =
      (truth.camera_T_object.translation() - r.sac_camera_T_object.translation()).norm();
  const double sac_r = RotationErrorDeg(truth.camera_T_object, r.sac_camera_T_object);
  std::printf("  SAC-IA error %.3f m %.2f deg; fitness sac %.2g gicp %.2g\n", sac_t, sac_r,
              r.sac_fitness, r.fitness);
  const auto [precision, recall] = SegmentQuality(f, seg, truth.id);
  std::printf(
      "  segment precision %.3f recall %.3f; GICP from truth -> %.3f m %.2f deg colour "
      "%.2f, %s\n",
      precision, recall, truth_t, truth_r, truth_colour, truth_status);
  const Vector3 axis =
      SE3::Log(truth.camera_T_object.inverse() * r.camera_T_object).head<3>().normalized();
  std::printf("  error rotation axis (object frame) %.2f %.2f %.2f\n", axis.x(), axis.y(),
              axis.z());
  if (a.claim_registered) std::printf("  others accepted %d\n", others_accepted);
  std::printf(
      "  hypothesis %d of %d, score %.2f, geometric %.2f, colour %.2f, refined "
      "inliers %d\n",
      r.hypothesis, r.hypotheses, r.score, r.geometric_agreement, r.colour_agreement,
      r.refined_inliers);
}

// What the views measured, for the summary.
struct Tally {
  std::vector<double> t_err, r_err;  // of the accepted views
  std::vector<double> seg_ms, prep_ms, sac_ms, gate_ms, gicp_ms, total_ms, cpu_ms, seg_pts;
  int accepted = 0, attempted = 0;

  void add(const RegistrationResult& r, double seg_time, double cpu, double te, double re) {
    seg_ms.push_back(seg_time);
    prep_ms.push_back(r.times.prepare);
    sac_ms.push_back(r.times.consensus);
    gate_ms.push_back(r.times.gate);
    gicp_ms.push_back(r.times.gicp + r.times.information);
    total_ms.push_back(seg_time + r.times.total());
    cpu_ms.push_back(cpu);
    seg_pts.push_back(r.segment_points);
    if (r.accepted()) {
      ++accepted;
      t_err.push_back(te);
      r_err.push_back(re);
    }
  }

  void print(const std::string& label) const {
    int good = 0, flips = 0;
    for (std::size_t i = 0; i < t_err.size(); ++i) {
      good += (t_err[i] < 0.05 && r_err[i] < 5.0);
      flips += r_err[i] > 90.0;
    }
    std::printf(
        "\n%s: %d views, %d accepted, %d of them within 5 cm / 5 deg, %d flipped (> 90 "
        "deg); median error %.3f m %.2f deg\n",
        label.c_str(), attempted, accepted, good, flips, Median(t_err), Median(r_err));
    std::printf(
        "mean ms: segmentation %.0f, prepare %.0f, sac_ia %.0f, gate %.0f, gicp+info "
        "%.0f, total %.0f (process cpu %.0f); mean voxelled segment %.0f points\n",
        Mean(seg_ms), Mean(prep_ms), Mean(sac_ms), Mean(gate_ms), Mean(gicp_ms), Mean(total_ms),
        Mean(cpu_ms), Mean(seg_pts));
  }
};

// View k: the world turned at random, the camera at a random bearing and distance looking at the
// object (with a small lateral offset so it is not always centred), the object segmented in its
// true box and registered.
void MeasureView(int k, const World& world, const ObjectTemplate& tmpl, const MeasureArgs& a,
                 std::mt19937& rng, Templates& templates, Tally& tally) {
  std::uniform_real_distribution<double> yaw_dist(-kPi, kPi),
      dist_dist(a.min_distance, a.max_distance), side_dist(-0.3, 0.3);
  World w = world;
  const SE3 turn(SO3::Exp(Vector3(0, 0, yaw_dist(rng))), Vector3::Zero());
  for (auto& o : w.objects) o.pose = turn * o.pose;
  const double bearing = yaw_dist(rng), d = dist_dist(rng), side = side_dist(rng);
  const Vector3 cam(-d * std::cos(bearing), -d * std::sin(bearing), 0.5);
  const double heading = bearing + side / d;
  const SE3 world_T_body(SO3::Exp(Vector3(0, 0, heading)), cam);
  RenderConfig rc;
  Renderer renderer(w, rc);
  const RenderedFrame f = renderer.render(world_T_body, static_cast<std::uint64_t>(k));
  const auto seen = std::find_if(f.objects.begin(), f.objects.end(),
                                 [](const VisibleObject& o) { return o.id == 0; });
  if (seen == f.objects.end()) return;
  const VisibleObject& truth = *seen;
  ++tally.attempted;
  const double c0 = static_cast<double>(std::clock());
  const auto s0 = std::chrono::steady_clock::now();
  const SegmentationConfig seg_config;
  const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f.rgbd), seg_config);
  int others_accepted = 0;
  const std::vector<int> claimed = ClaimedPixels(f, prepared, a, templates, &others_accepted);
  const SegmentationResult seg =
      SegmentObject(prepared, cv::Rect2f(truth.box), seg_config, claimed);
  const double seg_time =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - s0).count();
  if (seg.status != SegmentationStatus::kOk) {
    std::printf("view %2d d %.2f: segmentation %s\n", k, d, ToString(seg.status));
    return;
  }
  const RegistrationResult r = RegisterTemplate(*seg.segment, tmpl, a.config);
  PrintViewDetails(f, truth, seg, r, tmpl, a, others_accepted);
  const double cpu = (static_cast<double>(std::clock()) - c0) * 1000.0 / CLOCKS_PER_SEC;
  const double te = (truth.camera_T_object.translation() - r.camera_T_object.translation()).norm();
  const double re = RotationErrorDeg(truth.camera_T_object, r.camera_T_object);
  std::printf(
      "view %2d d %.2f: %zu seg pts (%d vox, %d kp), %-15s inliers %3d, err %.3f m "
      "%6.2f deg | seg %.0f prep %.0f sac %.0f gate %.0f gicp %.0f ms, cpu %.0f ms\n",
      k, d, seg.segment->size(), r.segment_points, r.segment_keypoints, ToString(r.status),
      r.inliers, te, re, seg_time, r.times.prepare, r.times.consensus, r.times.gate, r.times.gicp,
      cpu);
  tally.add(r, seg_time, cpu, te, re);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Measure segmentation + PFHRGB/SAC-IA/GICP registration on rendered frames"};
  MeasureArgs a;
  AddOptions(app, a);
  CLI11_PARSE(app, argc, argv);
  if (!(a.claim_radius > 0.0)) {
    std::fprintf(stderr, "--claim-radius must be positive\n");
    return 2;
  }
  const std::vector<ObjectClass> classes = StandardObjectClasses();
  const auto cls = std::find_if(classes.begin(), classes.end(),
                                [&](const ObjectClass& c) { return c.label == a.label; });
  if (cls == classes.end()) {
    std::fprintf(stderr, "unknown class %s\n", a.label.c_str());
    return 2;
  }
  const World world = MeasurementWorld(*cls, a.max_distance, a.dining);
  Templates templates(world, a);
  const auto t_template = std::chrono::steady_clock::now();
  const ObjectTemplate& tmpl = templates.of(a.label);  // shared with --dining's chairs
  std::printf(
      "template %s: %zu points, %zu keypoints, built in %.0f ms\n", a.label.c_str(), tmpl.size(),
      tmpl.keypoints->size(),
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_template)
          .count());
  std::mt19937 rng(a.seed);
  Tally tally;
  for (int k = 0; k < a.views; ++k) MeasureView(k, world, tmpl, a, rng, templates, tally);
  tally.print(a.label);
  return 0;
}
