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
#include <CLI/CLI.hpp>
#include <pcl/kdtree/kdtree_flann.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <random>
#include <vector>

#include "moslam/common/statistics.h"
#include "moslam/pose_estimation/registration.h"
#include "moslam/pose_estimation/segmentation.h"
#include "moslam/render/object_models.h"
#include "moslam/render/renderer.h"
#include "moslam/sim/world.h"

namespace {

using moslam::Mean;

constexpr double kPi = 3.14159265358979323846;

}  // namespace

int main(int argc, char** argv) {
  using namespace moslam;
  CLI::App app{"Measure segmentation + PFHRGB/SAC-IA/GICP registration on rendered frames"};
  std::string label = "chair";
  int views = 20;
  unsigned seed = 1;
  double template_spacing = 0.005;
  double min_distance = 1.5, max_distance = 3.0;
  RegistrationConfig config;
  app.add_option("--label", label, "object class (sim/world.h StandardObjectClasses)");
  app.add_option("--views", views, "number of rendered views");
  app.add_option("--seed", seed, "viewpoint seed");
  app.add_option("--template-spacing", template_spacing, "template surface sampling (m)");
  app.add_option("--min-distance", min_distance, "nearest viewpoint (m)");
  app.add_option("--max-distance", max_distance, "farthest viewpoint (m)");
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
  bool diagnose = false;
  bool dining = false;
  bool claim_truth = false;
  bool claim_segments = false;
  bool claim_registered = false;
  double claim_radius = 0.04;
  app.add_flag("--claim-others-registered", claim_registered,
               "leave out the pixels within --claim-radius of the other objects' templates at "
               "their registered poses (each segmented in its true box and registered)");
  app.add_option("--claim-radius", claim_radius, "m, with --claim-others-registered");
  app.add_flag("--claim-others-segments", claim_segments,
               "leave the other objects' segments (in their true boxes) out of the segment");
  app.add_flag("--claim-others-truth", claim_truth,
               "leave the other objects' pixels (ground truth) out of the segment");
  app.add_flag("--dining", dining,
               "four chairs around the object, as house's kitchen table (sim/world.cc)");
  app.add_flag("--diagnose", diagnose, "also run GICP from the true pose");
  CLI11_PARSE(app, argc, argv);
  if (!(claim_radius > 0.0)) {
    std::fprintf(stderr, "--claim-radius must be positive\n");
    return 2;
  }

  World world;
  world.name = "measure";
  world.classes = StandardObjectClasses();
  const ObjectClass* cls = world.findClass(label);
  if (cls == nullptr) {
    std::fprintf(stderr, "unknown class %s\n", label.c_str());
    return 2;
  }
  const double half_room = std::max(4.0, max_distance + 1.0);  // every viewpoint inside the room
  world.rooms.push_back({"room", Vector2(-half_room, -half_room), Vector2(half_room, half_room)});
  world.objects.push_back({0, label, SE3(SO3(), Vector3(0.0, 0.0, 0.5 * cls->extent.z()))});
  if (dining) {  // house's kitchen: chairs 0.4 m either side of the centre, 0.55 m out, backs out
    const double chair_z = 0.5 * world.findClass("chair")->extent.z();
    int id = 1;
    for (const double x : {-0.4, 0.4}) {
      for (const double y : {-0.55, 0.55}) {
        const SO3 facing = SO3::Exp(Vector3(0, 0, y < 0 ? kPi / 2 : -kPi / 2));
        world.objects.push_back({id++, "chair", SE3(facing, Vector3(x, y, chair_z))});
      }
    }
  }

  // The template of a class, sampled from its model (the measured class's and its neighbours').
  const auto make_template = [&](const ObjectClass& c) {
    return MakeObjectTemplate(c.label,
                              SampleMeshSurface(MakeObjectMesh(c), template_spacing, 1u),
                              config.features);
  };
  const auto t_template = std::chrono::steady_clock::now();
  const ObjectTemplate tmpl = make_template(*cls);
  std::printf("template %s: %zu points, %zu keypoints, built in %.0f ms\n", label.c_str(),
              tmpl.size(), tmpl.keypoints->size(),
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                        t_template).count());

  std::map<std::string, ObjectTemplate> other_templates;
  auto other_template = [&](const std::string& l) -> const ObjectTemplate& {
    auto it = other_templates.find(l);
    if (it == other_templates.end()) {
      it = other_templates.emplace(l, make_template(*world.findClass(l))).first;
    }
    return it->second;
  };
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> yaw_dist(-kPi, kPi),
      dist_dist(min_distance, max_distance), side_dist(-0.3, 0.3);
  const SegmentationConfig seg_config;
  std::vector<double> t_err, r_err, seg_ms, prep_ms, sac_ms, gate_ms, gicp_ms, total_ms,
      cpu_ms, seg_pts;
  int accepted = 0, attempted = 0;
  for (int k = 0; k < views; ++k) {
    World w = world;
    const SE3 turn(SO3::Exp(Vector3(0, 0, yaw_dist(rng))), Vector3::Zero());
    for (auto& o : w.objects) o.pose = turn * o.pose;
    const double bearing = yaw_dist(rng), d = dist_dist(rng), side = side_dist(rng);
    const Vector3 cam(-d * std::cos(bearing), -d * std::sin(bearing), 0.5);
    // Look at the object, with a small lateral offset so it is not always centred.
    const double heading = bearing + side / d;
    const SE3 world_T_body(SO3::Exp(Vector3(0, 0, heading)), cam);
    RenderConfig rc;
    Renderer renderer(w, rc);
    const RenderedFrame f = renderer.render(world_T_body, static_cast<std::uint64_t>(k));
    const auto seen = std::find_if(f.objects.begin(), f.objects.end(),
                                   [](const VisibleObject& o) { return o.id == 0; });
    if (seen == f.objects.end()) continue;
    const VisibleObject& truth = *seen;
    ++attempted;
    const double c0 = static_cast<double>(std::clock());
    const auto s0 = std::chrono::steady_clock::now();
    const PreparedFrame prepared = PrepareSegmentation(MakeOrganizedCloud(f.rgbd), seg_config);
    std::vector<int> claimed;
    if (claim_segments) {
      for (const VisibleObject& other : f.objects) {
        if (other.id == 0) continue;
        const SegmentationResult o = SegmentObject(prepared, cv::Rect2f(other.box), seg_config);
        claimed.insert(claimed.end(), o.indices.begin(), o.indices.end());
      }
    }
    int others_accepted = 0;
    if (claim_registered) {
      const OrganizedCloud& cloud = *prepared.cloud;
      for (const VisibleObject& other : f.objects) {
        if (other.id == 0) continue;
        const ObjectTemplate& ot = other_template(other.label);
        const SegmentationResult o = SegmentObject(prepared, cv::Rect2f(other.box), seg_config);
        if (o.status != SegmentationStatus::kOk) continue;
        const RegistrationResult orr = RegisterTemplate(*o.segment, ot, config);
        if (!orr.accepted()) continue;
        ++others_accepted;
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
              d2[0] < claim_radius * claim_radius)
            claimed.push_back(static_cast<int>(i));
        }
      }
    }
    if (claim_truth) {
      for (int v = 0; v < f.instance_ids.rows; ++v)
        for (int u = 0; u < f.instance_ids.cols; ++u)
          if (f.instance_ids.at<int>(v, u) > 0) claimed.push_back(v * f.instance_ids.cols + u);
    }
    const SegmentationResult seg =
        SegmentObject(prepared, cv::Rect2f(truth.box), seg_config, claimed);
    const double seg_time =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - s0).count();
    if (seg.status != SegmentationStatus::kOk) {
      std::printf("view %2d d %.2f: segmentation %s\n", k, d, ToString(seg.status));
      continue;
    }
    const RegistrationResult r = RegisterTemplate(*seg.segment, tmpl, config);
    int on_object = 0, object_pixels = 0;
    const int width = f.rgbd.intrinsics.width;
    for (int i : seg.indices) on_object += f.instance_ids.at<int>(i / width, i % width) == truth.id;
    for (int v = 0; v < f.instance_ids.rows; ++v)
      for (int u = 0; u < f.instance_ids.cols; ++u)
        object_pixels += f.instance_ids.at<int>(v, u) == truth.id &&
                         f.rgbd.depth.at<float>(v, u) > 0.0f;
    double truth_t = std::nan(""), truth_r = std::nan(""), truth_colour = std::nan("");
    const char* truth_status = "-";
    if (diagnose) {
      RegistrationConfig truth_config = config;
      truth_config.symmetry_turns = 1;
      const RegistrationResult g =
          RefinePose(*seg.segment, tmpl, truth.camera_T_object, truth_config);
      truth_colour = g.colour_agreement;
      truth_status = ToString(g.status);
      truth_t = (truth.camera_T_object.translation() - g.camera_T_object.translation()).norm();
      truth_r = SE3::Log(truth.camera_T_object.inverse() * g.camera_T_object).head<3>().norm() *
                180.0 / kPi;
    }
    const double sac_t = (truth.camera_T_object.translation() - r.sac_camera_T_object.translation()).norm();
    const double sac_r = SE3::Log(truth.camera_T_object.inverse() * r.sac_camera_T_object).head<3>().norm() * 180.0 / kPi;
    std::printf("  SAC-IA error %.3f m %.2f deg; fitness sac %.2g gicp %.2g\n", sac_t, sac_r, r.sac_fitness, r.fitness);
    std::printf("  segment precision %.3f recall %.3f; GICP from truth -> %.3f m %.2f deg colour "
                "%.2f, %s\n",
                static_cast<double>(on_object) / static_cast<double>(seg.indices.size()),
                static_cast<double>(on_object) / std::max(1, object_pixels), truth_t, truth_r,
                truth_colour, truth_status);
    {
      const Vector3 axis =
          SE3::Log(truth.camera_T_object.inverse() * r.camera_T_object).head<3>().normalized();
      std::printf("  error rotation axis (object frame) %.2f %.2f %.2f\n", axis.x(), axis.y(),
                  axis.z());
    }
    if (claim_registered) std::printf("  others accepted %d\n", others_accepted);
    std::printf("  hypothesis %d of %d, score %.2f, geometric %.2f, colour %.2f, refined "
                "inliers %d\n",
                r.hypothesis, r.hypotheses, r.score, r.geometric_agreement, r.colour_agreement,
                r.refined_inliers);
    const double cpu = (static_cast<double>(std::clock()) - c0) * 1000.0 / CLOCKS_PER_SEC;
    const Vector6 e = SE3::Log(truth.camera_T_object.inverse() * r.camera_T_object);
    const double te = (truth.camera_T_object.translation() - r.camera_T_object.translation()).norm();
    const double re = e.head<3>().norm() * 180.0 / kPi;
    std::printf("view %2d d %.2f: %zu seg pts (%d vox, %d kp), %-15s inliers %3d, err %.3f m "
                "%6.2f deg | seg %.0f prep %.0f sac %.0f gate %.0f gicp %.0f ms, cpu %.0f ms\n",
                k, d, seg.segment->size(), r.segment_points, r.segment_keypoints,
                ToString(r.status), r.inliers, te, re, seg_time, r.times.prepare,
                r.times.consensus, r.times.gate, r.times.gicp, cpu);
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
  int good = 0, flips = 0;
  for (std::size_t i = 0; i < t_err.size(); ++i) {
    good += (t_err[i] < 0.05 && r_err[i] < 5.0);
    flips += r_err[i] > 90.0;
  }
  std::printf("\n%s: %d views, %d accepted, %d of them within 5 cm / 5 deg, %d flipped (> 90 deg); "
              "median error %.3f m %.2f deg\n",
              label.c_str(), attempted, accepted, good, flips, Median(t_err), Median(r_err));
  std::printf("mean ms: segmentation %.0f, prepare %.0f, sac_ia %.0f, gate %.0f, gicp+info %.0f, "
              "total %.0f (process cpu %.0f); mean voxelled segment %.0f points\n",
              Mean(seg_ms), Mean(prep_ms), Mean(sac_ms), Mean(gate_ms), Mean(gicp_ms),
              Mean(total_ms), Mean(cpu_ms), Mean(seg_pts));
  return 0;
}
