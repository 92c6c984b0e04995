// Rendezvous between two robots (paper Section 2, "Robot Communication").
//
// Two ways to relate the robots' frames:
//   known initial poses (the paper's idealisation, the default): beta moves alpha's objects into
//     its frame with the initial poses, as below;
//   unknown initial poses (RendezvousConfig's prior absent: `moslam simulate --initial-poses
//     unknown`): beta aligns alpha's object map with its own from the objects alone
//     (constellation.h: label-consistent candidates, pairwise consistency of relative poses, a
//     maximum clique, refused when too small or ambiguous), over all the objects of both maps,
//     then checks that alpha's other objects, moved by the transform, are beta's objects where
//     beta looked (OverlapCheck); the consistent set is the shared objects of the pair.
// Consistency across rendezvous (RendezvousConfig::check_consistency, on with unknown initial
// poses): the same two robots meet many times; every pair they shared before is checked again
// with the new ones against the current maps, and only the largest pairwise consistent set stays
// (ConsistentSubset): the answer lists the pairs removed, and both robots drop their factors.
//
// Robot alpha sends the labels and poses of all its object landmarks, in its own frame (an
// ObjectMapMessage). Robot beta transforms them into its frame with the known initial poses,
//   beta_T_alpha = (world_T_beta0)^-1 * world_T_alpha0,
// (used for this association only, never in the optimisation), and matches them with its own
// landmarks: same label, within the gate ("2 sigma", AssociationGate in slam/object_slam.h),
// nearest first, each landmark at most once (MatchWithinGate), landmarks already shared between
// these two robots excluded. By default (RendezvousConfig::refine_alignment, an extension) the
// transform is first refined by aligning the two object maps, since both maps drift from their
// robots' first poses: on chairs25 with 6 robots at 5 deg / 0.2 m this raised the recall of the
// shared objects from 0.67 to 0.91 at a precision of 0.99, and on generated worlds with 64
// robots it is what connects the team (recall 0.20 -> 0.71). With
// RendezvousConfig::refine_by_constellation (on with rendered perception) beta also aligns the
// two maps by their constellation and keeps the transform whose matches agree best. Beta answers
// with the list of new shared objects (a SharedObjectsMessage), and both robots add one
// object-object factor per shared pair:
//   RelativePoseFactor(a = o_{beta,l}, b = o_{alpha,k}, z = identity, information = Lambda),
//   r = Log(o_{beta,l}^-1 o_{alpha,k}).
// Both messages cross as bytes (encoded, then decoded by the receiver) and are counted.
//
// Wire format (little-endian; every message starts with magic 0x4F, version 1, and a kind byte):
//   ObjectMap (kind 1):
//     u8 magic, u8 version, u8 kind, u16 sender robot,
//     u8 L (labels), L x { u8 length n >= 1, n bytes of label },
//     u32 N (objects), N x { u32 landmark index, u8 label index < L,
//                            f32 x y z, f32 qx qy qz qw }          (33 bytes per object)
//   SharedObjects (kind 2; kind 3 when it removes pairs):
//     u8 magic, u8 version, u8 kind, u16 sender (beta), u16 receiver (alpha),
//     u32 N, N x { u32 alpha landmark index, u32 beta landmark index }   (new pairs)
//     kind 3 only: u32 M, M x { u32 alpha landmark index, u32 beta landmark index } (removed)
// Poses travel as float32 (they serve association only). Decoding rejects with
// InvalidInputError: truncated input, trailing bytes, a wrong magic/version/kind, an empty
// label, a label index out of range, a repeated landmark index, non-finite numbers, a
// quaternion whose norm is not 1 within 1e-3, a list of new pairs that uses a landmark twice
// (one rendezvous' matching is one-to-one), and a list of removed pairs that holds a pair twice
// (the pairs shared before need not be one-to-one: `simulate --outliers` injects wrong pairs
// beside right ones on the same landmark, and both may be removed at once).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <optional>

#include "moslam/graph/factors.h"
#include "moslam/sim/sensing.h"
#include "moslam/slam/constellation.h"
#include "moslam/slam/object_slam.h"

namespace moslam {

struct ObjectMapEntry {
  std::uint32_t landmark = 0;  // index k of o_{sender,k}
  std::string label;
  SE3 pose;                    // in the sender's frame
};

struct ObjectMapMessage {
  int sender = 0;
  std::vector<ObjectMapEntry> objects;
};

struct SharedObjectsMessage {
  int sender = 0;    // beta
  int receiver = 0;  // alpha
  // (alpha landmark index, beta landmark index): new shared objects, and those shared before
  // that are inconsistent with the others (RendezvousConfig::check_consistency).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> removed;
};

// Throw InvalidInputError when the message cannot be encoded (robot id > 65535, more than 255
// labels, a label longer than 255 bytes or empty, a non-finite pose).
std::vector<std::uint8_t> EncodeObjectMap(const ObjectMapMessage& message);
std::vector<std::uint8_t> EncodeSharedObjects(const SharedObjectsMessage& message);
// Throw InvalidInputError naming what is wrong (the rules above).
ObjectMapMessage DecodeObjectMap(const std::vector<std::uint8_t>& bytes);
SharedObjectsMessage DecodeSharedObjects(const std::vector<std::uint8_t>& bytes);

// Alpha's message: all its landmarks with their current estimates.
ObjectMapMessage MakeObjectMapMessage(const ObjectSlam& robot);

// The overlap check of an alignment with unknown initial poses (an extension). A chance set of a
// few objects that agree pairwise fixes a transform under which the rest of alpha's map lands
// anywhere; under the right transform, alpha's objects that fall where beta looked are mostly
// beta's objects too. Beta moves every object of alpha's map by the alignment's transform; one
// inside its camera's view from one of its own poses (CameraModel::sees, at beta's estimate of
// the pose) is SEEN, and a seen object is CONFIRMED by a landmark of beta of its label within
// `radius` of it. At least min_seen seen and fewer than min_confirmed_fraction of them confirmed
// refuse the alignment (AlignmentStatus::kContradicted): no pairs. Failure modes: a map whose
// parts away from the shared objects drifted beyond `radius`, or a robot that missed the objects
// in its view (occlusion, detector), is refused too; a chance transform that puts alpha's objects
// where beta never looked passes. Chosen on the selection seeds (README: generated with 64
// robots, 6069 alignments in 10 runs: the 3 wrong ones had 1-2 of 9-22 seen objects confirmed;
// 3 right ones fall below 0.2).
struct OverlapCheck {
  bool enabled = true;
  CameraModel camera;                  // the robot's camera (the simulation's)
  double radius = 1.5;                 // m
  int min_seen = 8;
  double min_confirmed_fraction = 0.2;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct OverlapEvidence {
  int seen = 0;       // alpha's objects in view of one of beta's poses, moved by the transform
  int confirmed = 0;  // of those, with a landmark of beta of their label within the radius
};

// The evidence of OverlapCheck for alpha's objects moved by beta_T_alpha into the frame of
// `beta` (its poses and landmarks, at its current estimate).
OverlapEvidence AlignmentOverlap(const std::vector<ObjectMapEntry>& alpha_objects,
                                 const SE3& beta_T_alpha, const ObjectSlam& beta,
                                 const OverlapCheck& check);

struct RendezvousConfig {
  AssociationGate gate;  // for matching the two maps
  // Map alignment (an extension; false reproduces the paper's procedure exactly): before the
  // final matching, beta refines beta_T_alpha. Every label-consistent pair (o_{alpha,k},
  // o_{beta,l}) that lies within max_correction_m and max_correction_deg of each other under the
  // known-initial-pose transform proposes beta_T_alpha' = o_{beta,l} o_{alpha,k}^-1; the proposal
  // with the most matches under the gate wins (ties: the smaller correction), is refined by the
  // rigid fit of its matched positions, and replaces the prior when it has at least
  // min_inliers matches. This absorbs the drift of both maps relative to their first poses.
  bool refine_alignment = true;
  double max_correction_m = 4.0;
  double max_correction_deg = 45.0;
  int min_inliers = 3;
  // Refinement by the constellation (an extension, off here; `simulate --perception rendered`
  // turns it on): beta also aligns the two maps as with unknown initial poses
  // (AlignConstellations over all their objects, shared ones included, with `constellation`),
  // and when it aligns them, scores both transforms by the largest pairwise-consistent subset
  // (constellation.h, step 2, `constellation`'s tolerances) of the matches each makes under the
  // gate; the alignment's replaces the one above when it scores higher. A single pair's
  // proposal carries one object's orientation error over the map and wins on a count of matches,
  // which a grid read one row off in part can reach (chairs25, rendered, seed 2: 14 matches, 4
  // of them wrong, of which 11 agree, against the alignment's 13 right, 12 agreeing); the
  // alignment weighs every object's orientation and the drift between them, and refuses a layout
  // it cannot read. It needs no prior (as with unknown initial poses), so max_correction_m /
  // max_correction_deg do not bound it. Chosen on the selection seeds (README).
  bool refine_by_constellation = false;
  // Simulation only, for ablations: beta pairs the landmarks whose true objects are equal
  // (Landmark::true_object), each at most once, instead of matching; the messages still cross.
  bool ground_truth_association = false;
  // Unknown initial poses: the alignment of the two object maps (constellation.h), then its
  // overlap check.
  ConstellationConfig constellation;
  OverlapCheck overlap;
  // Check every pair shared before with the new ones, drop the inconsistent (above); forced on
  // with unknown initial poses.
  bool check_consistency = false;
  // Its tolerances. Looser than the alignment's: pairs found at different rendezvous were
  // mapped far apart in time, and each robot's map drifts in between (the alignment compares
  // objects of one moment). Measured on chairs25 6 robots x 10 runs, unknown initial poses:
  // with the alignment's tolerances (0.2 m, 5 deg, 0.05 m/m) the check removed right pairs and
  // the ground-truth ATE rose from 0.59 m (no check) to 0.74 m; with these 0.62 m.
  ConstellationConfig consistency{0.5, 15.0, 0.2};
  // Lambda = diag(1/s_R^2 I3, 1/s_t^2 I3), the confidence in a shared-object association.
  double lambda_sigma_rotation_deg = 5.0;
  double lambda_sigma_translation = 0.2;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  Matrix6 lambda() const;
};

// One shared object: the factor's a = beta's landmark, b = alpha's landmark.
struct SharedObject {
  Key beta_object;
  Key alpha_object;
};

// Erases from `shared` the pair that joins the landmarks of `pair`, whichever robot was alpha
// when it was found (a pair removed at a rendezvous may have been found at one with the roles the
// other way); false when there is none.
bool EraseShared(std::vector<SharedObject>& shared, const SharedObject& pair);

RelativePoseFactor ObjectObjectFactor(const SharedObject& shared, const Matrix6& lambda);

// The transform under which beta matches alpha's objects: `prior` (the known-initial-pose
// transform), or its refinement (RendezvousConfig::refine_alignment, refine_by_constellation).
// `inliers` (optional): the number of matches under the returned transform.
SE3 AlignObjectMaps(const ObjectMapMessage& from_alpha, const SE3& prior,
                    const std::vector<ObjectMapEntry>& beta_objects, const RendezvousConfig& config,
                    const std::vector<std::uint32_t>& alpha_taken = {},
                    const std::vector<std::uint32_t>& beta_taken = {}, int* inliers = nullptr);

// Beta's matching step: alpha's objects moved into beta's frame by beta_T_alpha, matched with
// `beta_objects` (beta's own map, e.g. MakeObjectMapMessage(beta).objects). Landmark indices in
// `alpha_taken` / `beta_taken` are excluded. Returns (alpha landmark, beta landmark) pairs,
// nearest first.
std::vector<std::pair<std::uint32_t, std::uint32_t>> MatchObjectMaps(
    const ObjectMapMessage& from_alpha, const SE3& beta_T_alpha,
    const std::vector<ObjectMapEntry>& beta_objects, const AssociationGate& gate,
    const std::vector<std::uint32_t>& alpha_taken = {},
    const std::vector<std::uint32_t>& beta_taken = {});

// Beta's side of a rendezvous, without ground-truth association (RunRendezvous calls it; a robot
// process calls it on the object map received over the network). `received` is alpha's object
// map as decoded (float32 poses). With `beta_T_alpha` (known initial poses:
// (world_T_beta0)^-1 world_T_alpha0): beta matches under AlignObjectMaps, landmarks already
// shared between the two robots excluded. Without it (unknown initial poses): beta aligns the
// two maps with AlignConstellations over all their objects; `alignment` (optional) receives its
// outcome. Then, with check_consistency (forced without beta_T_alpha), the consistency check
// across rendezvous. Returns the answer (new pairs, pairs removed). Throws InvalidInputError
// when alpha and beta are the same robot.
SharedObjectsMessage AnswerObjectMap(const ObjectMapMessage& received, const ObjectSlam& beta,
                                     const std::optional<SE3>& beta_T_alpha,
                                     const std::vector<SharedObject>& already_shared,
                                     const RendezvousConfig& config,
                                     ConstellationAlignment* alignment = nullptr);

// The transform under which beta matches alpha's objects when the initial poses are known.
inline SE3 BetaTAlpha(const SE3& world_T_alpha0, const SE3& world_T_beta0) {
  return world_T_beta0.inverse() * world_T_alpha0;
}

// The shared objects an answer adds: {Key::Object(beta, l), Key::Object(alpha, k)} per pair.
std::vector<SharedObject> SharedObjectsOf(const SharedObjectsMessage& answer);

struct RendezvousOutcome {
  std::vector<SharedObject> new_shared;
  std::vector<SharedObject> removed_shared;  // pairs shared before, found inconsistent
  std::optional<ConstellationAlignment> alignment;  // unknown initial poses
  int objects_sent = 0;
  std::size_t bytes_alpha_to_beta = 0;
  std::size_t bytes_beta_to_alpha = 0;
};

// One rendezvous, both messages through their byte encoding; beta answers with AnswerObjectMap
// (beta_T_alpha: from the known initial poses, or absent). `already_shared` lists every pair
// shared so far (any robots); those between alpha and beta exclude their landmarks.
// Throws InvalidInputError when alpha and beta are the same robot.
RendezvousOutcome RunRendezvous(const ObjectSlam& alpha, const ObjectSlam& beta,
                                const std::optional<SE3>& beta_T_alpha,
                                const std::vector<SharedObject>& already_shared,
                                const RendezvousConfig& config);

// The shared objects an answer removes: {Key::Object(beta, l), Key::Object(alpha, k)} per pair.
std::vector<SharedObject> RemovedObjectsOf(const SharedObjectsMessage& answer);

}  // namespace moslam
