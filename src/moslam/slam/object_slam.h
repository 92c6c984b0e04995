// Single-robot object SLAM (paper Section 2, "Object-based SLAM").
//
// The robot works in its own frame: its first pose is the identity (the gauge of its own graph;
// in a multi-robot graph this is its initial estimate, and robot 0's first pose is the gauge of
// the whole team). For each new pose i it
//   1. adds the odometry factor x_{i-1} -> x_i and predicts x_i = x_{i-1} * odometry;
//   2. associates each object detection (label, z) of pose i: its predicted object pose is
//      x_i * z; its candidates are the landmarks with the same label that pass the gate (below);
//      it joins the nearest candidate, else it creates a new landmark Key::Object(robot, k)
//      initialised at x_i * z (unless it falls within ObjectSlamConfig::exclusion_radius of a
//      landmark of its label: then it is discarded). The detections of one pose are distinct
//      objects: they are matched jointly, nearest (detection, landmark) pair first, no landmark
//      taking two of them;
//   3. localisation (`localization_iterations` > 0, an addition to the paper): when some
//      detections matched, x_i is refined by Gauss-Newton on its odometry factor and their
//      object-pose factors (previous pose and landmarks held), and step 2 is redone from there;
//      with `leave_one_out_check` (an addition too), each match of a pose with two or more is
//      then tested against x_i localised on the others (below) and refused when it disagrees;
//      with `ambiguity_ratio` (an addition too), a match nearly as near another landmark of its
//      label that no detection of the pose took is refused (ObjectSlamConfig::ambiguity_ratio);
//   4. adds one object-pose factor x_i -> o_k per detection (measurement z, its information);
//   5. every `update_every` poses, runs at most `iterations_per_update` Gauss-Newton iterations on
//      its whole graph from the current estimate (cheap: the graph is one robot's).
//
// Association gate ("within 2 sigma", paper). With dt the distance between the predicted and the
// estimated object positions and da the angle of the rotation between them, a candidate passes
// when dt <= num_sigmas * sigma and (if sigma_rotation_deg > 0) da <= num_sigmas *
// sigma_rotation_deg; "nearest" is the smallest (dt/sigma)^2 + (da/sigma_rotation)^2. The object
// measurement is a full pose, so its orientation is part of the distance (the simulated objects
// have no symmetry; set sigma_rotation_deg <= 0 for a position-only gate).
// AssociationGateForNoise(sigma_R, sigma_t) derives the sigmas from the measurement noise: the
// discrepancy adds the measurement noise, the landmark's estimation error and the predicted
// pose's error, about twice the measurement noise per axis together, whose 3D norm has RMS
// 2 sqrt(3) times it. In position the pose's heading error (~sigma_R) acts through the range, so
// the per-axis noise taken is max(sigma_t, 2 m * sigma_R):
//   sigma = 2 sqrt(3) max(sigma_t, 2 m sigma_R) (>= 0.1 m),  sigma_rotation = 2 sqrt(3) sigma_R
// (>= 2 deg): 0.69 m and 17 deg for the paper's 0.2 m and 5 deg. (Measured on chairs25 with 6
// robots, 5 deg / 0.2 m: the distance of a detection to its true landmark was 0.32 m at the
// median and 0.96 m at the 95th percentile, to the nearest other chair 1.7 m at the 5th
// percentile; over 5 seeds position sigmas of 0.7-0.9 m gave the best precision and recall at
// 5 deg with 0.1 or 0.2 m, 0.35-0.5 m at 1 deg / 0.1 m.)
// This is a gate with fixed sigmas, the paper's; the covariance gate below is the Mahalanobis test.
//
// Covariance gate (ObjectSlamConfig::covariance_gate, an addition; off by default). The fixed gate
// is the same at every pose, though the robot's drift since it last saw an object is not: a robot
// that comes back to a room after a stretch on odometry alone predicts its objects further than
// the gate's 1.4 m and maps them again (the loop is never closed), and a pose that just saw its
// neighbours is allowed 1.4 m whatever the noise of its sensors. With the gate on, each new
// pose i takes the joint marginal covariance Sigma of (x_i, o_k), over the landmarks o_k of its
// detections' labels, from the robot's graph at its current estimate (solver/marginals.h: one
// sparse factorisation per pose, the first pose held, so it is relative to the robot's own frame),
// and a detection (z, Omega) passes for o_k when its residual r = Log(z^-1 x_i^-1 o_k) (the
// object-pose factor's) has r^T S^-1 r <= covariance_gate, S = J Sigma J^T + Omega^-1 with J the
// factor's Jacobian in (x_i, o_k): the chi-square test of a 6-dof measurement, 22.46 its 99.9 %.
// A pose's detections are matched jointly (ObjectSlam::matchJointly: joint compatibility branch
// and bound, Neira and Tardos 2001): a drifted pose moves all its predictions alike, so the right
// pairs agree with one another and a wrong one beside them does not; the assignment with the most
// jointly compatible pairs wins, then the lowest joint chi-square. The pose is then localised on
// its matches. The ambiguity test (below) compares the gate's own r^T S^-1 r, its rivals within
// the gate; the leave-one-out check and the exclusion radius keep the fixed gate's sigmas. Where
// the factorisation fails (a graph the first pose does not anchor, H not positive definite) the
// pose is matched with the fixed gate.
// Measured (`moslam simulate --runs 10 --seed 11 --scenario S --robots 2 4 6 --robust
// --skip-unlinked --table robust`, without -> with `--covariance-gate 22.46`; README, Robustness):
// the robots' wrong observations per run chairs25 1.8 / 8.4 / 8.3 -> 0.4 / 0.4 / 3.0, house 13.3 /
// 24.3 / 33.0 -> 6.5 / 11.8 / 15.7; least-squares GT ATE at the mean generated 1.04 / 0.85 / 0.84
// -> 0.31 / 0.31 / 0.34 m (the loops it closes), chairs25 0.86 / 0.85 / 0.79 -> 0.28 / 0.27 / 0.39
// m, house the same (0.20-0.21 m). Matched one pair at a time, nearest first (the gate before
// joint matching), a robot drifted by about the spacing of objects of one label joined an object
// it never mapped to a mapped neighbour (chairs25 wrong observations 3.6 / 10.3 / 18.0). Not
// caught (by construction): a drift that moves every prediction of a pose onto a neighbour of its
// object alike, as in a grid seen all at one spacing, is jointly compatible. The wrong observations
// left (chairs25 with 6 robots, 3.0 per run) were not diagnosed.
//
// Leave-one-out check (ObjectSlamConfig::leave_one_out_check). A robot that drifts by about the
// spacing of its objects predicts a detection onto a neighbour's landmark, joins it, pulls the
// landmark over and keeps joining it: one wrong match starts a chain of them (measured on chairs25,
// 6 robots, seeds 11-20: 32 of 33 such chains began at a pose with two or more matches, where the
// pose localised on the other matches put the detection 1.4 m from its landmark at the median,
// the right matches 0.45 m, 1.15 m at the 99th percentile). So with two or more matches, each
// match is checked against x_i localised (as in step 3) on the other matches alone: its
// normalised squared distance there (AssociationGate::score) must be within the gate taken
// jointly, <= num_sigmas^2; a match that fails while another landmark of its label lies within
// leave_one_out_rival_radii gate radii of that prediction (an object it may be instead) is
// refused and its detection discarded (neither joined nor mapped: it lies near a landmark of its
// label). With no such rival the match is kept: the only object of its label around, in a map
// bent by drift. The pose stays localised on every match. Failure modes: with two matches, one
// wrong, both are refused (each disagrees with the pose the other gives); a chain whose every
// pose has a single match is not seen; right matches in a bent map with a rival near are refused
// too. Measured (`moslam simulate --robust`, seeds 11-20, 2 / 4 / 6 robots): chairs25 wrong
// observations per run 1.8 / 8.4 / 8.3 -> 0.0 / 3.6 / 4.2, GT ATE least squares 0.86 / 0.85 /
// 0.79 -> 0.85 / 0.83 / 0.71 m (the same with rival radii 3 as without the rival rule);
// generated (no wrong observation to find) 1.0 / 0.85 / 0.84 -> 1.2 / 0.80 / 0.87 m (1.3 / 0.96
// / 0.94 m without the rival rule). Off by default.
//
// Loop closure by object constellations (ObjectSlamConfig::loop_closure, an addition; off by
// default). With few object measurements per pose (a front-end that accepts some views only), a
// pose is placed by odometry over stretches of several poses, and where the robot comes back to
// a room it mapped before its predicted detections fall outside the gate (measured on house with
// rendered perception, 2 robots, seeds 11-13: of 114 new landmarks for objects already mapped,
// the predicted pose was 2.0 m / 37 deg from the object's landmark at the median; 11 failed the
// gate on the orientation alone): it maps the room a second time and never closes the loop.
// So at each update (every update_every poses), when landmarks were created since the last
// attempt, the robot aligns the constellation of its recent landmarks (created within the last
// loop_closure_window poses, not yet closed) with that of its older ones (created before the
// window) by AlignConstellations (constellation.h: label-consistent pairs, pairwise consistency
// of relative poses, maximum clique, refusal when too few or ambiguous). Each pair of an
// alignment must then pass the robot's association gate with the drift corrected (b_T_a applied
// to the recent landmark): the match the robot would have made had it not drifted. The others
// are dropped, and fewer than the alignment's min_support pairs left refuse it (chosen on
// chairs25 and house with rendered perception, 2 robots, seeds 11-13: the pairwise tolerances,
// made for two robots' maps, took two wrong alignments of four chairs and four wrong pairs
// inside right alignments; their pairs lay 0.5-3.1 m from their partners after the correction,
// the right ones at most 0.89 m / 17 deg). Pairs of one label must be at least
// loop_closure_one_label_min_support (6; the alignment is then asked for as many): a
// constellation of one label is told apart by its geometry and orientations alone, and on
// chairs25 (a grid of chairs) four were not enough (sampled measurements, 6 robots, seeds 11-19:
// 7.9 wrong pairs per run with 4, GT ATE 0.83 -> 0.97 m; with 6, none wrong and 0.83 -> 0.32 m; 8
// gave 0.33 m; with objects of two labels or more 6 lost a third of generated's pairs, 0.35 ->
// 0.37 m, and 8 nearly all; the robots' Laplace covariances did not tell wrong alignments apart
// either: right pairs reached chi-square 275, wrong ones came down to 8.5); with too few recent
// landmarks no alignment is tried. Each pair (recent k, older j) left becomes an object-object
// factor o_j -> o_k with measurement identity and information diag(1/s_R^2 I3, 1/s_t^2 I3)
// (loop_closure_sigma_*), the recent landmark is marked closed (Landmark::closed_with = j; never
// aligned again), and the graph is optimised with at least loop_closure_iterations iterations.
// Both landmarks stay (the factor joins them): later detections join the nearer one. The factors
// are the robot's own (graph(); evaluation marks them ObjectSlam::kNoObservation, as odometry):
// the robust solve does not weigh them.
// Failure modes: a wrong alignment (a layout the refusal rules cannot tell from another one)
// joins two rooms; a loop closed with fewer than min_support recent objects (6 when they hold one
// label) is not found; a right alignment can still leave the robot's own association worse
// (chairs25 rendered, 2 robots, seed 13: no wrong pair, intra precision 0.957 -> 0.935).
//
// Ground truth: a detection may carry the id of the world object it saw (simulation); a landmark
// then records the object of the detection that created it. This only feeds the association
// statistics and the evaluation; it never influences the estimate.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "moslam/graph/pose_graph.h"
#include "moslam/sim/sensing.h"
#include "moslam/slam/constellation.h"

namespace moslam {

struct AssociationGate {
  // Defaults: AssociationGateForNoise(5 deg, 0.2 m), the paper's noise.
  double sigma = 0.6928203230275509;             // m: std. dev. of the position discrepancy
  double sigma_rotation_deg = 17.320508075688775;  // deg: of the orientation; <= 0: not tested
  double num_sigmas = 2.0;          // the paper's 2 sigma
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  double radius() const { return num_sigmas * sigma; }
  // Whether a candidate at `candidate` passes the gate for a predicted pose `predicted`, and its
  // normalised squared distance (|dt|/sigma)^2 + (angle/sigma_rotation)^2 (the rotation term
  // only when tested). Ranking by this score is "nearest".
  bool accepts(const SE3& predicted, const SE3& candidate, double* score = nullptr) const;
  // The normalised squared distance alone, with no limit per term.
  double score(const SE3& predicted, const SE3& candidate) const;
};

// The gate for object measurements with noise (sigma_R, sigma_t), as documented above.
AssociationGate AssociationGateForNoise(double sigma_rotation_deg, double sigma_translation,
                                        double num_sigmas = 2.0);

struct LandmarkCandidate {
  std::string label;
  SE3 pose;               // estimated (candidates) or predicted (queries) object pose
  bool available = true;  // false: excluded from matching (e.g. already taken)
};

// The nearest available candidate with `label` that passes the gate for `predicted` (ties: the
// lowest index), or nullopt.
std::optional<std::size_t> NearestWithinGate(const std::string& label, const SE3& predicted,
                                             const std::vector<LandmarkCandidate>& candidates,
                                             const AssociationGate& gate);

struct GatedPair {
  std::size_t query = 0;      // index into the queries
  std::size_t candidate = 0;  // index into the candidates
  double score = 0.0;         // normalised squared distance (AssociationGate::accepts)
};

// Joint nearest-neighbour matching of several queries: every (query, available candidate) pair
// with equal labels that passes the gate, accepted nearest first, each query and each candidate
// at most once. Returned in the order accepted (increasing score).
std::vector<GatedPair> MatchWithinGate(const std::vector<LandmarkCandidate>& queries,
                                       const std::vector<LandmarkCandidate>& candidates,
                                       const AssociationGate& gate);

struct Landmark {
  Key key;                // Key::Object(robot, k), k = index in landmarks()
  std::string label;
  int true_object = -1;   // evaluation only: world object of the detection that created it
  int observations = 0;   // detections associated with it (the creating one included)
  int first_pose = 0;     // pose index of the creating detection
  // Loop closure (ObjectSlamConfig::loop_closure): the index of the older landmark this one was
  // found to be, joined by an object-object factor; -1: none.
  int closed_with = -1;
};

// Association against ground truth (detections that carry object ids only).
struct AssociationStats {
  int detections = 0;          // processed
  int associated = 0;          // joined an existing landmark
  int correct = 0;             // ... whose true object is the detection's
  int new_landmarks = 0;
  int duplicate_landmarks = 0; // new landmarks for an object that already had one
  int discarded = 0;           // detections discarded (ObjectSlamConfig::exclusion_radius)
  int refused = 0;             // matches refused by the leave-one-out check or as ambiguous
                               // (ObjectSlamConfig::ambiguity_ratio; detections discarded)
  int associable = 0;          // detections whose object already had a landmark
  int loop_closures = 0;       // object-object factors of loop closures (landmark pairs)
  int wrong_loop_closures = 0; // ... whose landmarks were created for two world objects
  double precision() const { return associated > 0 ? double(correct) / associated : 1.0; }
  double recall() const { return associable > 0 ? double(correct) / associable : 1.0; }
  AssociationStats& operator+=(const AssociationStats& o);
};

struct ObjectSlamConfig {
  AssociationGate association;
  int update_every = 3;           // poses between Gauss-Newton updates of the estimate
  int iterations_per_update = 2;  // Gauss-Newton iterations per update
  // Gauss-Newton iterations localising a new pose on the landmarks first matched, before the
  // detections are matched again from the refined pose; 0: match once from the prediction.
  int localization_iterations = 3;
  // Exclusion radius (m; 0: off, the paper's rule): a detection that joins no landmark but whose
  // predicted position lies within this distance of a landmark of its label creates no landmark
  // and adds no factor: it is discarded (AssociationStats::discarded, lastAssociations() kDiscarded).
  // Two objects of one label do not stand that close, so it is a view of that landmark's object
  // that the gate refused for its orientation, the signature of a front-end's symmetric confusion
  // (a chair registered turned 90 or 180 degrees about its vertical axis, which passes the shape
  // and colour checks), which would otherwise map the object a second time, turned. Failure
  // mode: when the landmark itself came from such a view, later right views are discarded too.
  double exclusion_radius = 0.0;
  // The leave-one-out check of a pose's matches (above; off: the paper's rule). Needs
  // localization_iterations >= 1.
  bool leave_one_out_check = false;
  // Its rivals: other landmarks of the label within this many gate radii (AssociationGate::
  // radius()) of the match's localised prediction; 3 was chosen on chairs25 and generated, seeds
  // 11-20 (2: chairs25's wrong observations 3.6 / 4.2 -> 6.1 / 6.7 per run at 4 / 6 robots).
  double leave_one_out_rival_radii = 3.0;
  // Ambiguous matches refused (0: off): a match whose prediction is nearly as near another
  // landmark of its label, one the pose's other detections did not take, is refused and its
  // detection discarded: sqrt(score / rival score) > ambiguity_ratio (AssociationGate::score,
  // the rival within the gate). Two objects of one label side by side, seen one at a time, are
  // told apart by the prediction only when the pose's drift is well below half their spacing.
  double ambiguity_ratio = 0.0;
  // The covariance gate (above): the chi-square bound on a match's r^T S^-1 r (22.46: 6 dof at
  // 99.9 %); 0: off, the fixed gate of `association` (the paper's rule).
  double covariance_gate = 0.0;
  // Simulation only, for ablations: a detection joins the landmark created for its true object
  // (ObjectDetection::object_id, required >= 0), else creates it; neither the gate, the
  // exclusion radius nor the leave-one-out check is used.
  bool ground_truth_association = false;
  // Loop closure by object constellations (above; off: the paper's rule).
  bool loop_closure = false;
  int loop_closure_window = 20;  // poses: landmarks created within the last ones are "recent"
  ConstellationConfig loop_closure_alignment;
  double loop_closure_sigma_rotation_deg = 5.0;  // the object-object factor's information
  double loop_closure_sigma_translation = 0.2;   // m
  int loop_closure_iterations = 10;  // Gauss-Newton iterations after a loop is closed (at least)
  int loop_closure_one_label_min_support = 6;  // pairs of an alignment of one label (above)
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

class ObjectSlam {
 public:
  // Throws InvalidInputError on a bad config or robot id (must be in [0, 65535];
  // g2o files hold at most kMaxRobotsWithObjects robots with objects, memory any number).
  explicit ObjectSlam(int robot, const ObjectSlamConfig& config = {});

  // Pose 0 (the identity) and what it sees. Must be called once, first (InvalidInputError).
  void addFirstPose(const std::vector<ObjectDetection>& detections);
  // The next pose. Throws InvalidInputError before addFirstPose or on a bad measurement (a
  // non-finite pose or an information that is not SPD), leaving the state unchanged.
  void addPose(const OdometryReading& odometry, const std::vector<ObjectDetection>& detections);
  // At most `max_iterations` Gauss-Newton iterations on the whole graph from the current estimate
  // (first pose held); returns the cost after them. No-op (cost 0) while the graph is empty.
  double optimize(int max_iterations);
  // optimize(max_iterations) when factors were added (or the team factors or the estimate
  // replaced) since the last optimize(); else the cost.
  double refresh(int max_iterations);

  // Online mapping (online/group_solve.h). Team factors tie the robot's landmarks to other
  // robots' landmarks held fixed in this robot's frame: each is a factor between this robot's
  // first pose and one of its landmarks (keys of this robot). optimize() and refresh() include
  // them; graph() does not (the joint graph of a batch solve has the object-object factors
  // instead). Replaces the previous set. Throws InvalidInputError on a factor that is not between
  // pose 0 and an existing landmark of this robot (nothing changes then).
  void setTeamFactors(const std::vector<RelativePoseFactor>& factors);
  const std::vector<RelativePoseFactor>& teamFactors() const { return team_factors_; }
  // Replaces the estimate (keys of this robot; every variable present, finite, first pose the
  // identity to 1e-9: the robot's own frame). Throws InvalidInputError otherwise (nothing
  // changes then). The next pose is predicted from the new estimate of the last one.
  void setEstimate(const Values& estimate);
  // Online robust mapping (online/online_team.h): weights of the robot's own factors, in the
  // order of graph() (a group solve's verdicts), each in (0, 1]; optimize() and refresh() scale
  // each factor's information by its weight, factors added later (or beyond `weights`) weigh 1.
  // graph() stays unweighted, so a later group solve judges every factor again. Replaces the
  // previous weights. Throws InvalidInputError on more weights than factors or a weight outside
  // (0, 1] (nothing changes then).
  void setFactorWeights(std::vector<double> weights);
  const std::vector<double>& factorWeights() const { return factor_weights_; }

  int robot() const { return robot_; }
  int numPoses() const { return num_poses_; }
  // The robot's graph (odometry and object-pose factors) and estimate, keyed with this robot.
  PoseGraph graph() const;
  std::size_t numFactors() const { return local_graph_.factors().size(); }  // graph()'s, no copy
  Values estimate() const;
  SE3 pose(int i) const;
  SE3 landmarkPose(std::size_t k) const;
  const std::vector<Landmark>& landmarks() const { return landmarks_; }
  const AssociationStats& associationStats() const { return stats_; }
  // Evaluation only, per factor of graph(): the world object of the detection behind an
  // object-pose factor (ObjectDetection::object_id, -1 unknown), kNoObservation for odometry.
  static constexpr int kNoObservation = -2;
  const std::vector<int>& factorObjects() const { return factor_objects_; }
  // For each detection of the last pose added: the index of the landmark it joined or created,
  // kDiscarded for one discarded (ObjectSlamConfig::exclusion_radius, leave_one_out_check).
  static constexpr std::size_t kDiscarded = static_cast<std::size_t>(-1);
  const std::vector<std::size_t>& lastAssociations() const { return last_associations_; }

 private:
  // The joint matching's search (matchJointly) stops after this many nodes.
  static constexpr long kMaxJointNodes = 20000;
  void addDetections(const std::vector<ObjectDetection>& detections,
                     const RelativePoseFactor* odometry);
  // Whether a landmark of `label` other than landmark `except` lies within `radius` of `position`.
  bool nearLandmark(const std::string& label, const Vector3& position, double radius,
                    std::size_t except = kDiscarded) const;
  // Whether the detection, seen from x, falls within exclusion_radius of a landmark of its label.
  bool excluded(const ObjectDetection& detection, const SE3& x) const;
  // The leave-one-out check of `assigned` at pose x (ObjectSlamConfig::leave_one_out_check):
  // which detections' matches it refuses (their entries of `assigned` reset).
  std::vector<bool> refuseInconsistent(const SE3& x, const RelativePoseFactor& odometry,
                                       const std::vector<ObjectDetection>& detections,
                                       std::vector<std::optional<std::size_t>>& assigned) const;
  void record(const std::vector<ObjectDetection>& detections,
              const std::vector<std::optional<std::size_t>>& assigned,
              const std::vector<bool>& refused, const SE3& x);
  // The joint marginal covariance of the newest pose and the landmarks of the detections' labels
  // (ObjectSlamConfig::covariance_gate), or nullopt where the factorisation fails.
  struct MatchCovariance {
    SE3 pose;                            // the newest pose's estimate, predictions made from it
    std::vector<std::size_t> landmarks;  // block j + 1 of `joint` is landmarks[j]'s
    Eigen::MatrixXd joint;               // block 0: the newest pose
  };
  std::optional<MatchCovariance> matchCovariance(
      const std::vector<ObjectDetection>& detections) const;
  // r^T S^-1 r of `detection` from c.pose against landmark c.landmarks[j] (the covariance gate);
  // +inf where it is not finite. Optionally r and its Jacobians in the pose and the landmark.
  double chiSquare(const ObjectDetection& detection, const MatchCovariance& c, std::size_t j,
                   Vector6* residual = nullptr, Matrix6* d_pose = nullptr,
                   Matrix6* d_landmark = nullptr) const;
  // The ambiguity test of `assigned` at pose x (ObjectSlamConfig::ambiguity_ratio): which
  // detections' matches it refuses (their entries of `assigned` reset). With `covariance` the
  // distances are the covariance gate's r^T S^-1 r from covariance->pose and a rival must pass
  // that gate; without, the fixed gate's scores at x.
  std::vector<bool> refuseAmbiguous(const SE3& x, const std::vector<ObjectDetection>& detections,
                                    std::vector<std::optional<std::size_t>>& assigned,
                                    const MatchCovariance* covariance) const;
  // The covariance gate's matching of a pose's detections, jointly (joint compatibility branch
  // and bound, Neira and Tardos 2001): of the assignments of detections to distinct landmarks of
  // their labels (or to none), each pair within the gate, whose stacked residuals pass the joint
  // chi-square test (r^T S^-1 r with the correlations of the pose and the landmarks, at the tail
  // of covariance_gate: the bound of 6 m degrees of freedom by Wilson and Hilferty's
  // approximation), the one with the most pairs, then the lowest joint chi-square. A drifted pose
  // moves all its detections' predictions alike, so the right pairs agree with one another and a
  // wrong pair beside them does not. The search stops after kMaxJointNodes nodes with the best
  // assignment found.
  std::vector<std::optional<std::size_t>> matchJointly(
      const std::vector<ObjectDetection>& detections, const MatchCovariance& prior) const;
  // Each detection's match by the fixed gate at pose x, nearest first.
  std::vector<std::optional<std::size_t>> associate(
      const SE3& x, const std::vector<ObjectDetection>& detections) const;
  SE3 refinePose(const SE3& x0, const RelativePoseFactor& odometry,
                 const std::vector<ObjectDetection>& detections,
                 const std::vector<std::optional<std::size_t>>& assigned) const;
  void maybeUpdate();
  // Loop closure (ObjectSlamConfig::loop_closure): whether factors were added.
  bool closeLoops();

  int robot_;
  ObjectSlamConfig config_;
  int num_poses_ = 0;
  // Solved with robot-0 keys (the optimiser anchors robot 0's first pose); exported re-keyed.
  PoseGraph local_graph_;
  Values local_values_;
  std::vector<Landmark> landmarks_;
  std::vector<int> mapped_objects_;  // true objects with a landmark (sorted)
  AssociationStats stats_;
  std::vector<std::size_t> last_associations_;
  std::vector<int> factor_objects_;  // parallel to local_graph_.factors()
  std::size_t landmarks_at_last_loop_attempt_ = 0;
  std::size_t factors_at_last_optimize_ = 0;
  bool stale_ = false;  // team factors or estimate replaced since the last optimize()
  std::vector<RelativePoseFactor> team_factors_;        // keys of this robot
  std::vector<RelativePoseFactor> local_team_factors_;  // the same, robot-0 keys
  std::vector<double> factor_weights_;  // the first factors of local_graph_ (setFactorWeights)
  // local_graph_ with factor_weights_ applied, and the team factors.
  PoseGraph weightedGraph() const;
};

}  // namespace moslam
