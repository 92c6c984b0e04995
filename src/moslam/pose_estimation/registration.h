// Object pose from a segment: PFHRGB features + a sample-consensus initial alignment, an inlier
// gate (>= 12 agreeing feature correspondences, the paper's check), then GICP refinement.
//
// Frames: the segment is in the camera optical frame (z forward, x right, y down), the template
// in the object frame (centre, x forward, z up); metres. The result is camera_T_object
// (p_camera = camera_T_object * p_object). The robot's object-pose measurement x_i^-1 o_k is
// BodyFromCamera() * camera_T_object (ObjectMeasurementInBody).
//
// The hypotheses below are pose_hypotheses.h, the AGREEMENT and SHAPE RULES pose_score.h, the
// information matrix pose_information.h; this file runs the stages (registration.cc: every
// PFHRGB, consensus and GICP instantiation).
//
// Stages (times in RegistrationResult::times):
//   prepare : voxel the segment (FeatureConfig::voxel_size), normals (normal_radius, flipped
//             towards the camera), keypoints (keypoint_voxel, at most max_segment_keypoints),
//             PFHRGB at the keypoints (feature_radius, over a feature_surface_voxel copy of the
//             voxelled segment); fewer than min_segment_points points or
//             min_inliers keypoints -> kTooFewPoints;
//   consensus: the initial alignment, segment keypoints -> template keypoints (Consensus below):
//             by default PCL's prerejective sampler with RANSAC's most-inliers criterion
//             (prerejective_iterations samples, seeded by `seed`, thread-safe), or the paper's
//             pcl::SampleConsensusInitialAlignment (sac_iterations; srand(seed) first, PCL draws
//             with rand(), so a call is deterministic but not thread-safe against other rand()
//             users); both with sac_correspondence_randomness, sac_min_sample_distance and
//             sac_max_correspondence_distance (widened by the depth noise at the segment's median
//             keypoint depth: consensus_depth_sigmas);
//   gate    : each segment keypoint's nearest template feature (PFHRGB L2) is a correspondence;
//             it is an INLIER if the consensus transform maps the segment point within
//             inlier_distance of the template point, widened by the depth noise at the point's
//             depth (inlier_depth_sigmas) (RegistrationResult::inliers). With
//             gate_refined_pose (default), a segment failing this still goes through gicp/score,
//             and the inliers are counted again under the final pose (refined_inliers): the gate
//             passes if the refined count reaches min_inliers (SAC-IA often returns a flip of
//             tables and sofas, whose correct half turn has the inliers), or if the consensus
//             count does and the final pose is the consensus pose refined (hypothesis 0): a
//             turned or upright hypothesis is another pose and holds the gate on its own count
//             (PassesInlierGate). Otherwise kTooFewInliers;
//   gicp    : pcl::GeneralizedIterativeClosestPoint (voxel_size clouds; the plane covariances of
//             both clouds from their normals, I - (1 - 1e-3) n n^T), segment -> the template
//             points whose outward normals face the camera at the initial pose (back faces
//             removed). With several SYMMETRY HYPOTHESES (below), each is aligned coarsely
//             (gicp_coarse_points, gicp_coarse_iterations) and scored (on at most 1000 segment
//             points), and the best is refined
//             (gicp_max_source_points, gicp_max_iterations); kGicpFailed if no run converges to a
//             finite transform;
//   score   : the refined pose is scored (AGREEMENT RULE below);
//             kShapeMismatch if its shape does not agree (SHAPE RULE below), else
//             kColourMismatch if its colour agreement is below min_colour_agreement.
//
// Symmetry hypotheses (against the 180-degree flips of PFHRGB + SAC-IA, notes/frontend.md
// pitfall 6, which pass the inlier gate): hypothesis 0 is the consensus pose; then, for each
// j = 1 .. symmetry_turns - 1, the consensus pose turned by 360 j / symmetry_turns degrees about
// the object's z axis (a flip matches the segment to the wrong side of the object, so its centre is
// off by up to the object's size; measured 0.46 m on rendered chairs), three times:
//   index 3j - 2: about the vertical axis through the object origin;
//   index 3j - 1: about the vertical line through the segment's centroid (object frame);
//   index 3j    : as 3j - 1, then shifted horizontally so that the segment's centroid lands on
//                 the centroid of the template points facing the camera at that pose.
// symmetry_turns = 2 gives 4 hypotheses (half turn), 4 (default) gives 10 (quarter turns), 1
// disables them. Each costs one coarse GICP. Quarter turns: rendered chairs were accepted a
// quarter turn off (the right pose not among the half turns); on the simulations of seeds 11-13
// (chairs25 and house, 2 robots, 3 runs each, `simulate --perception rendered`) accepted poses
// more than 45 deg off 21 -> 12 (chairs25), registration time per frame +16-21 %.
//
// Upright hypotheses (large objects: the template's horizontal extent >= upright_min_extent; PFHRGB
// on a partial view of a sofa or a shelf rarely finds its pose, 2 and 5 of 16 rendered views):
// objects stand on the floor, whose up direction in the camera frame is camera_up (a level camera:
// -y of the optical frame). upright_yaws hypotheses follow the symmetry ones: yaw along the
// segment's principal horizontal axis and its turns by 360 / upright_yaws degrees, translated so
// that the template points facing the camera are centred on the segment. They go through the same
// coarse GICP, score and gates (the 12-inlier gate counted at the refined pose); when the
// consensus finds no pose, they are the only hypotheses (indices 0 .. upright_yaws - 1; the
// prerejective consensus then no longer ends the registration with kTooFewInliers).
//
// Agreement rule (RegistrationResult::score, geometric_agreement, colour_agreement): with the
// segment points y_i mapped into the object frame by the pose and T the template points facing
// the camera at that pose,
//   geometric(i) : some t in T lies within r(z_i) of y_i, z_i the point's depth in the camera
//                  frame, r(z) = sqrt(score_distance^2 + (score_depth_sigmas depth_noise.sigma(z))^2);
//   colour(i)    : one of those t has chromaticity within colour_tolerance (L2) of y_i's, where
//                  chromaticity(r, g, b) = (r + k, g + k, b + k) / (r + g + b + 3k),
//                  k = chroma_dark_offset (8-bit units). Chromaticity is invariant to the
//                  brightness scaling of Lambert shading and of the models' brightness gradient;
//                  k pulls dark, noisy pixels towards grey;
//   covered(i)   : geometric(i), or some t in T lies within score_distance / z_i of y_i's ray
//                  (normalised image coordinates x/z, y/z: the template covers that pixel);
//   geometric_agreement = #geometric / N,  colour_agreement = #(geometric and colour) / #geometric,
//   covered_agreement = #geometric / #covered,
//   score = #(geometric and colour) / N   (N = voxelled segment points).
// The hypothesis whose coarse alignment scores highest wins (ties: the lower index). A flip that
// still wins is caught by its shape or colour. SHAPE RULE: the shape agrees if
//   geometric_agreement >= min_geometric_agreement, or
//   covered_agreement >= min_covered_agreement
//     and geometric_agreement >= min_geometric_agreement_covered;
// otherwise kShapeMismatch, else colour_agreement < min_colour_agreement -> kColourMismatch (pose
// and scores filled, no information). The first clause's and the colour threshold were chosen on
// rendered chairs (measure_pose_estimation, seeds 1 and 2): correct poses had geometric 0.90-1.00
// and colour 0.71-0.97, flips colour 0.48-0.60 or geometric 0.83. The second clause excuses the
// segment points on pixels the posed template does not cover: clutter the segment kept beside
// the object (a table beside a chair, the wall beside a fridge) says nothing against the pose,
// while a point on a covered pixel that misses the template (seen through it, or in front of it)
// still counts against it. Chosen on the selection simulations (house and chairs25, 2 robots,
// seeds 11-13; true detections of objects seen enough; README): the first clause rejected 76
// right poses (within 10 cm / 10 deg) on house (geometric 0.42-0.85, covered 0.70-1.00) and 5 on
// chairs25; with 0.92 and 0.75, 45 of them pass (chairs 33, fridges 8, sofas 4) and no pose
// further off. Poses further off that passed the colour gate with geometric >= 0.75 were covered
// below 0.92 (at most 0.916, a fridge 11 cm off; half turns 0.90); with 0.5 instead of 0.75, two
// far chairs 26 and 33 cm off would pass (every miss off the template's pixels). RefinePose runs
// the same hypotheses, score and colour gate from its initial pose instead of the consensus pose
// (symmetry_turns = 1 to refine that pose alone).
//
// Information matrix (6x6, tangent order (w, v): rotation first, shared/CONVENTIONS.md), for a
// right perturbation camera_T_object * Exp(xi) (the same xi perturbs the body-frame measurement
// BodyFromCamera() * camera_T_object on the right). RULE: point-to-plane Fisher information of the
// final alignment, deflated for correlated points, plus a model-error floor:
//   for each voxelled segment point y_i (in the object frame after GICP) whose nearest GICP-target
//   point q_i (normal n_i) is within gicp_max_correspondence_distance:
//     J_i = [ (n_i x y_i)^T , -n_i^T ]   (d n_i.(y_i - q_i) / d xi),   H = sum J_i^T J_i;
//   s^2 = max(mean squared point-to-plane residual, information_sigma_point^2);
//   Sigma = ( H / s^2 * min(1, information_max_effective_points / N) + 1e-6 I )^-1
//           + k^2 diag(sigma_rotation_floor^2 I3, sigma_translation_floor^2 I3),
//   k = InformationFloorScale(mean depth of the voxelled segment) (>= 1: far views, below);
//   information = Sigma^-1 (symmetric positive definite; directions the segment does not
//   constrain, e.g. sliding along a flat face, get ~1e-6 information).
#pragma once

#include <string>

#include "moslam/geometry/se3.h"
#include "moslam/pose_estimation/object_template.h"
#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/rgbd.h"

namespace moslam {

// The sample-consensus initial alignment (feature correspondences -> a rigid pose).
enum class Consensus {
  // pcl::SampleConsensusPrerejective: a sample whose 3 segment points and their 3 template
  // matches do not form similar triangles (edge-length ratio < prerejective_similarity) is
  // rejected before any point is transformed; of the rest, the pose with the lowest mean squared
  // inlier distance among those putting >= prerejective_inlier_fraction of the segment keypoints
  // within sac_max_correspondence_distance of the template wins (none: kTooFewInliers).
  kPrerejective,
  // pcl::SampleConsensusInitialAlignment (the paper's SAC-IA): every sample is scored over all
  // segment keypoints (truncated error).
  kSacIa,
};

struct RegistrationConfig {
  FeatureConfig features;  // must equal the template's (checked)
  // Sample consensus (both methods: 3-point samples, each segment feature drawn to one of its
  // sac_correspondence_randomness nearest template features).
  Consensus consensus = Consensus::kPrerejective;
  int sac_correspondence_randomness = 5;   // k nearest template features to draw from
  double sac_max_correspondence_distance = 0.05;  // m, inlier / truncation distance
  double sac_min_sample_distance = 0.05;   // m between the 3 sampled segment points
  unsigned seed = 1;
  // SAC-IA only.
  int sac_iterations = 1000;  // 500 accepted 2/8 rendered chair views, 1000 5/8 (measured)
  // Approximation factor of the PFHRGB nearest-neighbour search (FLANN k-d tree; 0 = exact): a
  // neighbour returned is within (1 + epsilon) of the true one's squared distance. 1 against 0:
  // the consensus 2.7x faster on sofas, 1.5x on chairs, the same views accepted (16 each). 3
  // against 1, on the selection sequences (`moslam perceive --every 2`, house and chairs25, seeds
  // 11-13, 2 robots x 100 poses): registration median / p90 120 / 324 -> 96 / 231 ms (house) and
  // 63 / 137 -> 51 / 112 ms (chairs25); views accepted within 10 cm / 10 deg 239 -> 242 and 644 ->
  // 644, further off 42 -> 35 and 46 -> 32 (5: 89 / 218 ms on house, 241 and 38).
  double feature_search_epsilon = 3.0;
  // Prerejective only.
  int prerejective_iterations = 5000;
  double prerejective_similarity = 0.5;
  double prerejective_inlier_fraction = 0.25;
  // Inlier gate (paper: 12).
  double inlier_distance = 0.05;  // m; 0.04 accepted 5/16 rendered chair views, 0.05 13/16
  int min_inliers = 12;
  // The sensor's depth noise (depth_noise, below) widens the gate's inlier distance at each
  // keypoint's depth z, and the consensus' sac_max_correspondence_distance at the median depth of
  // the segment's keypoints, as it widens the agreement radius: sqrt(d^2 + (k sigma(z))^2), k these
  // sigmas (0: fixed). A correct correspondence of a chair 5 m away is off by its noise, 4 cm at
  // the median, against a fixed 5 cm. Chosen with the agreement radius' one sigma on the seed-7
  // selection sequences (468 detections, 2 robots of chairs25 and house): accepted 133 (fixed) ->
  // 148 (inlier, k 1) -> 149 (both, k 1), of them 3 / 4 / 2 more than 25 cm or 25 deg off; with
  // k 2 for the gate 185 accepted, 11 that far off.
  double inlier_depth_sigmas = 1.0;
  double consensus_depth_sigmas = 1.0;
  bool gate_refined_pose = true;  // also count the inliers under the refined pose (see above)
  int min_segment_points = 30;    // after voxelling; fewer -> kTooFewPoints
  // Cap on segment keypoints (evenly strided subset beyond it; 0 = no cap): PFHRGB and SAC-IA
  // cost grow linearly with it (a sofa segment had ~2500 keypoints, 6.6 s CPU uncapped).
  int max_segment_keypoints = 1000;
  // GICP.
  int gicp_max_source_points = 500;  // evenly strided subset of the segment beyond it (0: all)
  // With several symmetry hypotheses, each is first aligned with gicp_coarse_points of the
  // segment and gicp_coarse_iterations, and only the best-scoring one is refined in full.
  int gicp_coarse_points = 150;
  int gicp_coarse_iterations = 10;
  double gicp_coarse_max_correspondence_distance = 0.15;  // m: reaches from the upright guesses
  int gicp_max_iterations = 30;
  double gicp_max_correspondence_distance = 0.05;  // m
  double gicp_transformation_epsilon = 1e-6;
  // Symmetry hypotheses and agreement rule (see the header comment).
  int upright_yaws = 4;                // 0 = no upright hypotheses
  double upright_min_extent = 0.8;     // m, largest horizontal side of the template
  Vector3 camera_up = Vector3(0.0, -1.0, 0.0);  // floor normal in the camera frame
  int symmetry_turns = 4;  // 1 = consensus pose only, 2 = + half turn, 4 = + quarter turns
  double score_distance = 0.025;       // m, geometric agreement radius at no depth noise
  // The sensor's depth noise widens the radius with a point's depth (AGREEMENT RULE): far points
  // are noisier (sigma 1.4 cm at 3 m, 2.6 cm at 4 m for the default, a Kinect's). 0 sigmas: a
  // fixed score_distance.
  // One sigma: 118 of 468 detections accepted on held-out-free selection sequences (seed 7) against
  // 88 with none and 125 with two, of which 13 / 9 / 16 more than 10 cm or 10 deg off the truth.
  AxialDepthNoise depth_noise;
  double score_depth_sigmas = 1.0;
  double colour_tolerance = 0.05;      // chromaticity L2 distance
  double chroma_dark_offset = 10.0;    // 8-bit units
  double min_geometric_agreement = 0.85;  // SHAPE RULE, first clause
  // SHAPE RULE, second clause (1 and 1: off).
  double min_covered_agreement = 0.92;
  double min_geometric_agreement_covered = 0.75;
  double min_colour_agreement = 0.6;   // below -> kColourMismatch
  // Information matrix rule (see the header comment).
  double information_sigma_point = 0.005;           // m
  double information_max_effective_points = 50.0;
  double sigma_rotation_floor_deg = 2.0;
  double sigma_translation_floor = 0.02;             // m
  // The floors grow with the sensor's depth noise at the segment's mean depth beyond this (m):
  // both multiplied by max(1, depth_noise.sigma(z) / information_floor_noise); 0: fixed floors.
  // A Kinect's noise reaches 2 cm at 3.6 m; beyond it accepted views are less accurate (seed-7
  // selection sequences, median error 4 m 0.9 cm / 1.3 deg, 6 m 2.1 cm / 3.4 deg, 7 m and beyond
  // 6.4 cm / 15 deg with depth smoothing), and with the fixed floors a far view weighs as much as
  // a near one.
  double information_floor_noise = 0.02;

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

enum class RegistrationStatus {
  kAccepted,
  kTooFewPoints,
  kTooFewInliers,
  kGicpFailed,
  kColourMismatch,  // the best pose's colour_agreement < min_colour_agreement
  kShapeMismatch,   // the best pose's shape does not agree (SHAPE RULE)
};
const char* ToString(RegistrationStatus status);

struct RegistrationTimes {  // milliseconds
  double prepare = 0.0;     // voxel + normals + PFHRGB of the segment
  double consensus = 0.0;   // sample-consensus initial alignment
  double gate = 0.0;
  double gicp = 0.0;         // every hypothesis' GICP and its score
  double information = 0.0;
  double total() const { return prepare + consensus + gate + gicp + information; }
};

struct RegistrationResult {
  RegistrationStatus status = RegistrationStatus::kTooFewPoints;
  SE3 camera_T_object;            // valid if kAccepted (the consensus estimate if kGicpFailed or
                                  // kTooFewInliers, the rejected best pose if k*Mismatch)
  SE3 sac_camera_T_object;        // the consensus estimate (diagnostics; identity if none)
  int segment_points = 0;         // after voxelling (voxel_size), with a normal
  int segment_keypoints = 0;      // with a finite PFHRGB descriptor
  int correspondences = 0;        // feature correspondences examined by the gate
  int inliers = 0;                // of those, agreeing under the consensus transform
  int refined_inliers = -1;       // of those, agreeing under the final pose (-1: no GICP ran)
  double sac_fitness = 0.0;       // PCL fitness after the consensus (m^2)
  double fitness = 0.0;           // PCL's fitness score after GICP (m^2), winning hypothesis
  int hypotheses = 0;             // symmetry hypotheses refined by GICP
  int hypothesis = -1;            // the winner (0 = consensus pose; header comment for the others)
  // Agreement rule of the header comment, winning hypothesis (also filled when the refined pose
  // failed the inlier gate: kTooFewInliers with refined_inliers >= 0).
  double score = 0.0;
  double geometric_agreement = 0.0;
  double colour_agreement = 0.0;
  double covered_agreement = 0.0;
  Matrix6 information = Matrix6::Zero();  // valid if kAccepted
  RegistrationTimes times;
  bool accepted() const { return status == RegistrationStatus::kAccepted; }
};

// Registers the template to a segment (camera frame). Throws InvalidInputError on an invalid
// config, an empty template, or a template built with a different FeatureConfig; every other
// outcome is a status.
RegistrationResult RegisterTemplate(const OrganizedCloud& segment, const ObjectTemplate& tmpl,
                                    const RegistrationConfig& config);

// GICP refinement (and the information matrix) alone, from an initial camera_T_object (e.g. a
// predicted pose when tracking). Status kAccepted, kTooFewPoints, kGicpFailed, kShapeMismatch or
// kColourMismatch; inliers and correspondences are 0 (no feature stage); the symmetry hypotheses
// (symmetry_turns) are turns of the initial pose.
RegistrationResult RefinePose(const OrganizedCloud& segment, const ObjectTemplate& tmpl,
                              const SE3& initial_camera_T_object,
                              const RegistrationConfig& config);

// The factor k of the information floors for a segment at `mean_depth` (m, camera z):
// max(1, config.depth_noise.sigma(mean_depth) / config.information_floor_noise); 1 when
// information_floor_noise is 0 or the depth is not positive.
double InformationFloorScale(double mean_depth, const RegistrationConfig& config);

// The gate rule above for the pose a registration reports: `consensus_inliers` counted at the
// consensus pose (-1: the consensus found none), `refined_inliers` at the final pose, which came
// from symmetry or upright hypothesis `hypothesis` (0: the consensus pose itself). The consensus'
// count vouches for its own refinement only. Measured with 7 cm features (simulations of seed 11
// with rendered perception): turned hypotheses that held the gate on the consensus' count alone
// were 18 accepted views on chairs25 with 6 robots, 14 of them more than 10 cm / 10 deg off (of
// 53 such views), and 14 on house with 2 robots, 8 of them off (of 37).
bool PassesInlierGate(int consensus_inliers, int hypothesis, int refined_inliers,
                      int min_inliers);

// x_i^-1 o_k: the object's pose in the robot body frame = BodyFromCamera() * camera_T_object.
SE3 ObjectMeasurementInBody(const SE3& camera_T_object);

}  // namespace moslam
