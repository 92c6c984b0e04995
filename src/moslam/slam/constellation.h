// Aligning two robots' object maps with no initial guess (the rendezvous with unknown initial
// poses): which objects of map a are which objects of map b, and the transform b_T_a between
// the two frames, from the objects' labels and poses alone (PCM / CLIPPER style).
//
// 1. Candidates: every pair (i in a, j in b) with the same label.
// 2. Consistency: two candidates (i, j) and (k, l) (i != k, j != l) agree when the relative pose
//    of the two objects is the same in both maps: A = a_i^-1 a_k against B = b_j^-1 b_l, the
//    rotation angle of A^-1 B within tau_R and the translations within tau_t(d), d the distance
//    of the two objects:
//      tau_R    = num_sigmas * 2 sigma_R
//      tau_t(d) = num_sigmas * sqrt(4 sigma_t^2 + 2 (d sigma_R)^2) + drift_per_m * d
//    (per axis the four object errors add up to 2 sigma; the orientation of the first object in
//    each map acts over d; the two maps drift apart between objects mapped far apart; num_sigmas
//    bounds the norm of a 3-D error in units of its per-axis sigma: 3.4 is its 99 % quantile). Each candidate alone fixes a transform
//    T = b_j a_i^-1; two consistent candidates fix nearly the same one: the orientations of the
//    objects are what tells a symmetric layout's positions apart (a grid of chairs).
// 3. The largest set of pairwise consistent candidates, each object at most once: a maximum
//    clique (robust/max_clique.h).
// 4. Support: the objects a set stands for. Two of its candidates whose objects of a, or of b,
//    have one label and lie within same_object_radius of each other may be one world object
//    mapped twice (a landmark the robot's association gate did not join to the first: a
//    duplicate); the support is the most candidates no two of which may be one object (a
//    maximum clique again, on at most the set's size); otherwise a robot's duplicates, each
//    paired with the other robot's duplicates of another object, inflate a chance set (two
//    wrong alignments of about 600 per run on generated with 64 robots, 3 distinct objects
//    each, counted 4).
//    Refusal: fewer than min_support objects (kTooFew), or a rival set of at least
//    support - ambiguity_margin objects that reads the best set's objects otherwise: each of its
//    candidates gives an object of the best set another partner that the best set's transform
//    does not put there (a grid read one cell off; not a duplicate landmark of the same object)
//    (kAmbiguous): the layout does not tell the two readings apart.
// 5. The transform: the chordal mean of the set's rotations b_j R_i^T, then the mean translation.
//
// ConsistentSubset() is step 3 on given pairs: the largest subset of already associated pairs
// that agree pairwise (consistency of the shared objects across rendezvous, as PCM checks
// inter-robot loop closures).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "moslam/geometry/se3.h"

namespace moslam {

struct ConstellationConfig {
  double sigma_translation = 0.2;   // m: an object's position error in one map (per axis)
  double sigma_rotation_deg = 5.0;  // its orientation error
  double drift_per_m = 0.05;        // relative error of the two maps per metre between objects
  double num_sigmas = 3.4;
  // Objects in the accepted set. 3 accepted one wrong alignment in 475 on generated with 16
  // robots (README); 4 none, and as many of the rendezvous with 4 or more shared objects.
  int min_support = 4;
  // m: two objects of one label closer than this in one map may be one object (step 4). The
  // robots' association gate at the paper's noise, 2 x 0.69 m (object_slam.h): a robot joins a
  // detection to a landmark within it, so two of its landmarks that close are not told apart.
  double same_object_radius = 1.3856406460551018;
  int ambiguity_margin = 1;         // a rival of support - margin objects or more: ambiguous
  long long max_search_nodes = 2000000;  // bound of the clique search (MaximumClique)
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct ConstellationObject {
  std::uint32_t id = 0;  // the landmark index
  std::string label;
  SE3 pose;              // in its map's frame
};

// kContradicted: aligned here, then refused by the rendezvous' overlap check (rendezvous.h,
// OverlapCheck): the other map's objects fall where this robot looked and mapped none.
enum class AlignmentStatus { kAligned, kTooFew, kAmbiguous, kContradicted };
std::string ToString(AlignmentStatus status);

struct ConstellationAlignment {
  AlignmentStatus status = AlignmentStatus::kTooFew;
  SE3 b_T_a;                                               // when aligned
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // (a id, b id): the consistent set
  int support = 0;     // distinct objects in the best consistent set (step 4)
  int rival = 0;       // distinct objects in the best rival set (another reading of them)
  int candidates = 0;  // label-consistent pairs considered
  bool exact = true;   // the clique searches finished (not cut at max_search_nodes)
  std::string reason;  // why it was refused
};

ConstellationAlignment AlignConstellations(const std::vector<ConstellationObject>& a,
                                           const std::vector<ConstellationObject>& b,
                                           const ConstellationConfig& config);

// The largest subset of `pairs` (indices into a and b, each object at most once) whose relative
// poses agree pairwise as in step 2; returns the indices into `pairs` kept, increasing.
std::vector<std::size_t> ConsistentSubset(
    const std::vector<ConstellationObject>& a, const std::vector<ConstellationObject>& b,
    const std::vector<std::pair<std::size_t, std::size_t>>& pairs,
    const ConstellationConfig& config);

}  // namespace moslam
