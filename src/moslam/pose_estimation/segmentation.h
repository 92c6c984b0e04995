// Object segmentation in an organized RGB-D cloud: the points of the object inside one detection
// box, with the floor, walls and other scene structure removed.
//
// Pipeline (PCL organized-cloud tools), per frame then per box:
//   PrepareSegmentation (once per frame):
//     1. normals by pcl::IntegralImageNormalEstimation (COVARIANCE_MATRIX);
//     2. planes by pcl::OrganizedMultiPlaneSegmentation (each plane: coefficients n.p + d = 0 in
//        the camera frame, inlier indices, and the pixel bounding box of its inliers).
//   SegmentObject (per box):
//     3. STRUCTURE RULE: a plane is scene structure (its inliers are removed) if
//          (a) more than `structural_outside_fraction` of its inliers lie outside the box grown
//              by `box_margin_fraction` of its size on each side (floor, walls, a neighbouring
//              table: they extend well beyond the object's box), or
//          (b) `drop_floor` and it is horizontal (normal within `floor_max_tilt_deg` of
//              `up_in_camera`) at floor height (its height below the camera is within
//              `floor_height_tolerance` of `camera_height`).
//        Any other plane (a table top, a sofa seat, a chair back, mostly inside the box) is kept
//        as part of the object. A structural plane removes its inliers and, inside the grown box,
//        the points within plane_distance_threshold of it that are not plane inliers only
//        because their normals are unreliable (edges, contact lines): for a floor (b), every such
//        point (nothing lies beneath the floor); for an (a) plane, those whose integral-image
//        normal is invalid or within structure_normal_tolerance_deg of the plane's normal (so an
//        extended neighbouring plane does not slice the object).
//        Pixels the caller says other objects claim (SegmentObject's `claimed`) are left out
//        too, before the planes.
//     4. connected components (pcl::OrganizedConnectedComponentSegmentation with
//        pcl::EuclideanClusterComparator, its threshold `cluster_distance` widened by the depth
//        noise at the pixel's depth) over the valid,
//        non-structure points inside the grown box; the comparator's label cloud marks these
//        points 0 and every other point 1, and its "exclude labels" set is {0} (PCL joins only
//        points whose labels are IN that set).
//     5. the object is chosen among the components with min_segment_points points inside the box
//        (ComponentSelection::kBoxFit, the default): the detector drew the box around the
//        object's visible pixels, so the object spans the box and lies inside it. The winner has
//        the largest FIT x INSIDE: FIT the IoU of the component's pixel bounding box with the box,
//        INSIDE the share of its points (in the grown box) inside the box itself; ties: the most
//        points in the box. A nearer object standing in front of part of the box fits it worse
//        and spills out of it; a surface behind the object filling the grown box fits the box
//        well but spills out of it; of an object split in two (a plant's foliage and pot) the
//        part spanning more of the box wins. kMostPoints (the rule before, which took the nearer
//        object and, on rendered chairs25, far walls over chairs): the component with the most
//        points inside the (original) box; components within `tie_ratio` of the best count are
//        ties, won by the nearest (smallest mean z).
//        The segment keeps the winner's points in the grown box.
//     6. the segment's depths smoothed along their rays where the depth noise is large
//        (pose_estimation/depth_smoothing.h; `smoothing`, with `depth_noise`): far views.
//
// Units: metres, camera optical frame (z forward, x right, y down); boxes in pixels
// (x = column of the left edge, y = row of the top edge, width, height).
#pragma once

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "moslam/pose_estimation/depth_smoothing.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/rgbd.h"

namespace moslam {

// Step 5's rule (header comment).
enum class ComponentSelection { kMostPoints, kBoxFit };

struct SegmentationConfig {
  // Integral-image normals.
  float normal_max_depth_change_factor = 0.02f;  // m; depth jumps larger than this break normals
  float normal_smoothing_size = 10.0f;           // pixels
  // Multi-plane segmentation.
  int min_plane_inliers = 600;              // points (for 320x240; ~4x for 640x480)
  double plane_angular_threshold_deg = 3.0;  // normals of one plane agree to this
  double plane_distance_threshold = 0.02;    // m
  double plane_max_curvature = 0.01;         // points curvier than this are not plane seeds
  // Structure rule (see the header comment).
  double box_margin_fraction = 0.1;          // of the box width/height, each side
  double structural_outside_fraction = 0.5;  // (a)
  bool drop_floor = true;                    // (b)
  Vector3 up_in_camera = Vector3(0.0, -1.0, 0.0);  // unit "up" in the camera frame (level camera)
  double camera_height = 0.5;                // m above the floor (sim/robots.h camera height)
  double floor_height_tolerance = 0.1;       // m
  double floor_max_tilt_deg = 10.0;
  double structure_normal_tolerance_deg = 20.0;  // near-plane points joined to an (a) plane
  // Clustering and selection.
  // m between neighbouring pixels of one object, widened by the depth noise of the nearer pixel:
  // sqrt(cluster_distance^2 + (cluster_depth_sigmas sqrt(2) depth_noise.sigma(z))^2) (two noisy
  // depths differ by sqrt(2) sigma; at 5 m a Kinect's sigma is 4.1 cm, and a fixed 5 cm split far
  // objects into hundreds of components). 0 sigmas: a fixed cluster_distance.
  float cluster_distance = 0.05f;
  AxialDepthNoise depth_noise;
  // 3: on seed-7 rendered sequences (chairs25, house) detections failing segmentation 115 -> 18
  // of 468 and 118 -> 133 accepted (0 / 1 / 2 / 4 sigmas: 115 / 29 / 19 / 17 failing, 118 / 118 /
  // 123 / 131 accepted).
  double cluster_depth_sigmas = 3.0;
  int min_segment_points = 50;     // points of the chosen component inside the box
  ComponentSelection selection = ComponentSelection::kBoxFit;
  double tie_ratio = 0.9;          // in (0, 1], kMostPoints only
  DepthSmoothingConfig smoothing;  // step 6

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// A plane found in the frame.
struct ScenePlane {
  Eigen::Vector4d coefficients;  // (n, d), |n| = 1, n.p + d = 0 for p on the plane (camera frame)
  std::vector<int> inliers;      // indices into the organized cloud
};

// Per-frame intermediate results shared by all boxes of the frame.
struct PreparedFrame {
  OrganizedCloud::ConstPtr cloud;
  pcl::PointCloud<pcl::Normal>::ConstPtr normals;
  std::vector<ScenePlane> planes;
  double normals_ms = 0.0;
  double planes_ms = 0.0;
};

enum class SegmentationStatus {
  kOk,
  kEmptyBox,      // the box misses the image or holds no valid depth
  kTooFewPoints,  // fewer than min_segment_points non-structure points in the box
  kNoCluster,     // no component has min_segment_points points in the box
};
const char* ToString(SegmentationStatus status);

struct SegmentationResult {
  SegmentationStatus status = SegmentationStatus::kEmptyBox;
  OrganizedCloud::Ptr segment;  // unorganized, camera frame; empty unless status == kOk
  std::vector<int> indices;     // of the segment's points in the organized cloud
  int valid_points_in_box = 0;  // finite points inside the box
  int structure_points_in_box = 0;  // of those, removed as scene structure
  int claimed_points_in_box = 0;    // of those, claimed by other objects (SegmentObject's claimed)
  int planes_dropped = 0;
  int components = 0;           // components considered (with >= 1 point in the box)
  double time_ms = 0.0;         // this call (not PrepareSegmentation)
};

// Normals and planes of an organized cloud (throws InvalidInputError if the cloud is not
// organized or the config is invalid).
PreparedFrame PrepareSegmentation(const OrganizedCloud::ConstPtr& cloud,
                                  const SegmentationConfig& config);

// The object's points in `box` (pixels). Never throws on a box outside the image (status
// kEmptyBox); throws InvalidInputError on an invalid config or a non-finite box.
SegmentationResult SegmentObject(const PreparedFrame& frame, const cv::Rect2f& box,
                                 const SegmentationConfig& config);
// The same with the pixels of `claimed` (indices into the organized cloud: the segments of other
// objects seen inside this box) left out, as if they were scene structure. Throws
// InvalidInputError on an index outside the cloud.
SegmentationResult SegmentObject(const PreparedFrame& frame, const cv::Rect2f& box,
                                 const SegmentationConfig& config,
                                 const std::vector<int>& claimed);

// Why a plane is (or is not) scene structure for a box (rule of the header comment).
enum class PlaneRole { kObject, kFloor, kOutsideBox };
PlaneRole ClassifyPlane(const ScenePlane& plane, std::size_t cloud_width, const cv::Rect2f& box,
                        const SegmentationConfig& config);
// True if plane `plane` is scene structure for `box` (ClassifyPlane != kObject).
bool IsStructuralPlane(const ScenePlane& plane, std::size_t cloud_width, const cv::Rect2f& box,
                       const SegmentationConfig& config);

}  // namespace moslam
