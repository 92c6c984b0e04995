#include "moslam/slam/rendezvous.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/metrics/metrics.h"

namespace moslam {
namespace {

constexpr std::uint8_t kMagic = 0x4F;
constexpr std::uint8_t kVersion = 1;
constexpr std::uint8_t kKindObjectMap = 1;
constexpr std::uint8_t kKindSharedObjects = 2;
constexpr std::uint8_t kKindSharedObjectsAndRemovals = 3;
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// The first three bytes of every rendezvous message: magic, version, kind.
void ReadHeader(ByteReader& r, std::uint8_t kind) {
  if (r.u8("magic") != kMagic) r.fail("bad magic byte (not a moslam rendezvous message)");
  const std::uint8_t version = r.u8("version");
  if (version != kVersion) r.fail("unsupported version " + std::to_string(version));
  const std::uint8_t k = r.u8("kind");
  if (k != kind) r.fail("message kind " + std::to_string(k) + ", expected " + std::to_string(kind));
}

double FiniteF32(ByteReader& r, const char* field) {
  const float f = r.f32(field);
  if (!std::isfinite(f)) r.fail(std::string("non-finite ") + field);
  return static_cast<double>(f);
}

std::uint16_t RobotId(int robot, const char* what) {
  if (robot < 0 || robot > 65535) {
    throw InvalidInputError(std::string(what) + ": robot id " + std::to_string(robot) +
                            " does not fit the message (0..65535)");
  }
  return static_cast<std::uint16_t>(robot);
}

bool SharesPair(const SharedObject& s, int alpha, int beta) {
  return (s.alpha_object.robot == alpha && s.beta_object.robot == beta) ||
         (s.alpha_object.robot == beta && s.beta_object.robot == alpha);
}

// Landmark indices already shared between robots a and b (in either role), by owner.
void TakenLandmarks(const std::vector<SharedObject>& shared, int a, int b,
                    std::vector<std::uint32_t>* alpha_taken, std::vector<std::uint32_t>* beta_taken) {
  for (const auto& s : shared) {
    if (!SharesPair(s, a, b)) continue;
    for (const Key& k : {s.alpha_object, s.beta_object}) {
      (k.robot == a ? *alpha_taken : *beta_taken).push_back(static_cast<std::uint32_t>(k.index));
    }
  }
}

}  // namespace

std::vector<std::uint8_t> EncodeObjectMap(const ObjectMapMessage& message) {
  WireWriter w;
  w.u8(kMagic);
  w.u8(kVersion);
  w.u8(kKindObjectMap);
  w.u16(RobotId(message.sender, "EncodeObjectMap"));
  std::vector<std::string> labels;
  std::map<std::string, std::uint8_t> label_index;
  for (const auto& o : message.objects) {
    if (o.label.empty() || o.label.size() > 255) {
      throw InvalidInputError("EncodeObjectMap: label '" + o.label + "' must have 1..255 bytes");
    }
    if (label_index.count(o.label) == 0) {
      if (labels.size() == 255) throw InvalidInputError("EncodeObjectMap: more than 255 labels");
      label_index[o.label] = static_cast<std::uint8_t>(labels.size());
      labels.push_back(o.label);
    }
  }
  w.u8(static_cast<std::uint8_t>(labels.size()));
  for (const auto& l : labels) {
    w.u8(static_cast<std::uint8_t>(l.size()));
    w.bytes(l);
  }
  w.u32(static_cast<std::uint32_t>(message.objects.size()));
  for (const auto& o : message.objects) {
    const Vector3& t = o.pose.translation();
    const Eigen::Vector4d q = o.pose.rotation().quaternionWxyz();
    if (!t.allFinite() || !q.allFinite()) {
      throw InvalidInputError("EncodeObjectMap: landmark " + std::to_string(o.landmark) +
                              " has a non-finite pose");
    }
    w.u32(o.landmark);
    w.u8(label_index.at(o.label));
    for (double v : {t[0], t[1], t[2], q[1], q[2], q[3], q[0]}) w.f32(static_cast<float>(v));
  }
  return w.take();
}

ObjectMapMessage DecodeObjectMap(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "object map message");
  ReadHeader(r, kKindObjectMap);
  ObjectMapMessage m;
  m.sender = r.u16("sender");
  const std::uint8_t num_labels = r.u8("label count");
  std::vector<std::string> labels;
  for (int i = 0; i < num_labels; ++i) {
    const std::uint8_t n = r.u8("label length");
    if (n == 0) r.fail("empty label");
    labels.emplace_back(r.take(n, "label"));
  }
  const std::uint32_t count = r.count(33, "object");
  std::set<std::uint32_t> seen;
  for (std::uint32_t i = 0; i < count; ++i) {
    ObjectMapEntry e;
    e.landmark = r.u32("landmark index");
    if (!seen.insert(e.landmark).second) {
      r.fail("landmark " + std::to_string(e.landmark) + " appears twice");
    }
    const std::uint8_t li = r.u8("label index");
    if (li >= labels.size()) {
      r.fail("label index " + std::to_string(li) + " out of range (" +
             std::to_string(labels.size()) + " labels)");
    }
    e.label = labels[li];
    Vector3 t;
    for (int k = 0; k < 3; ++k) t[k] = FiniteF32(r, "translation");
    const double qx = FiniteF32(r, "quaternion"), qy = FiniteF32(r, "quaternion"),
                 qz = FiniteF32(r, "quaternion"), qw = FiniteF32(r, "quaternion");
    const double norm = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
    if (std::abs(norm - 1.0) > 1e-3) {
      r.fail("quaternion of landmark " + std::to_string(e.landmark) + " has norm " +
             std::to_string(norm));
    }
    e.pose = SE3(SO3::FromQuaternion(qw, qx, qy, qz), t);
    m.objects.push_back(std::move(e));
  }
  r.finish();
  return m;
}

std::vector<std::uint8_t> EncodeSharedObjects(const SharedObjectsMessage& message) {
  WireWriter w;
  w.u8(kMagic);
  w.u8(kVersion);
  w.u8(message.removed.empty() ? kKindSharedObjects : kKindSharedObjectsAndRemovals);
  w.u16(RobotId(message.sender, "EncodeSharedObjects"));
  w.u16(RobotId(message.receiver, "EncodeSharedObjects"));
  for (const auto* list : {&message.pairs, &message.removed}) {
    if (list == &message.removed && message.removed.empty()) break;  // kind 2: no removals
    w.u32(static_cast<std::uint32_t>(list->size()));
    for (const auto& [a, b] : *list) {
      w.u32(a);
      w.u32(b);
    }
  }
  return w.take();
}

SharedObjectsMessage DecodeSharedObjects(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "shared objects message");
  const bool removals = bytes.size() > 2 && bytes[2] == kKindSharedObjectsAndRemovals;
  ReadHeader(r, removals ? kKindSharedObjectsAndRemovals : kKindSharedObjects);
  SharedObjectsMessage m;
  m.sender = r.u16("sender");
  m.receiver = r.u16("receiver");
  for (auto* list : {&m.pairs, &m.removed}) {
    if (list == &m.removed && !removals) break;
    const bool added = list == &m.pairs;
    const std::uint32_t count = r.count(8, added ? "pair" : "removed pair");
    std::set<std::uint32_t> alpha_seen, beta_seen;
    std::set<std::pair<std::uint32_t, std::uint32_t>> pairs_seen;
    for (std::uint32_t i = 0; i < count; ++i) {
      const std::uint32_t a = r.u32("alpha landmark"), b = r.u32("beta landmark");
      if (added) {  // one rendezvous' matching is one-to-one
        if (!alpha_seen.insert(a).second) {
          r.fail("alpha landmark " + std::to_string(a) + " shared twice");
        }
        if (!beta_seen.insert(b).second) {
          r.fail("beta landmark " + std::to_string(b) + " shared twice");
        }
      } else if (!pairs_seen.insert({a, b}).second) {
        // Earlier pairs need not be one-to-one (wrong pairs injected beside right ones).
        r.fail("pair (" + std::to_string(a) + ", " + std::to_string(b) + ") removed twice");
      }
      list->emplace_back(a, b);
    }
  }
  r.finish();
  return m;
}

ObjectMapMessage MakeObjectMapMessage(const ObjectSlam& robot) {
  ObjectMapMessage m;
  m.sender = robot.robot();
  const auto& lms = robot.landmarks();
  for (std::size_t k = 0; k < lms.size(); ++k) {
    if (lms[k].key.index > 0xFFFFFFFFu) {
      throw InvalidInputError("MakeObjectMapMessage: landmark index does not fit 32 bits");
    }
    m.objects.push_back(
        {static_cast<std::uint32_t>(lms[k].key.index), lms[k].label, robot.landmarkPose(k)});
  }
  return m;
}

void RendezvousConfig::validate() const {
  gate.validate();
  auto bad = [](const std::string& msg) { throw InvalidInputError("RendezvousConfig: " + msg); };
  if (!(lambda_sigma_rotation_deg > 0.0) || !std::isfinite(lambda_sigma_rotation_deg)) {
    bad("lambda_sigma_rotation_deg must be positive and finite");
  }
  if (!(lambda_sigma_translation > 0.0) || !std::isfinite(lambda_sigma_translation)) {
    bad("lambda_sigma_translation must be positive and finite");
  }
  if (!(max_correction_m >= 0.0) || !std::isfinite(max_correction_m)) {
    bad("max_correction_m must be >= 0 and finite");
  }
  if (!(max_correction_deg >= 0.0) || !std::isfinite(max_correction_deg)) {
    bad("max_correction_deg must be >= 0 and finite");
  }
  if (min_inliers < 1) bad("min_inliers must be >= 1");
  constellation.validate();
  consistency.validate();
  overlap.validate();
}

void OverlapCheck::validate() const {
  camera.validate();
  auto bad = [](const std::string& msg) { throw InvalidInputError("OverlapCheck: " + msg); };
  if (!(radius > 0.0) || !std::isfinite(radius)) bad("radius must be positive and finite");
  if (min_seen < 1) bad("min_seen must be at least 1");
  if (!(min_confirmed_fraction >= 0.0 && min_confirmed_fraction <= 1.0)) {
    bad("min_confirmed_fraction must be in [0, 1]");
  }
}

OverlapEvidence AlignmentOverlap(const std::vector<ObjectMapEntry>& alpha_objects,
                                 const SE3& beta_T_alpha, const ObjectSlam& beta,
                                 const OverlapCheck& check) {
  check.validate();
  std::vector<SE3> pose_T_beta;  // beta's poses, inverted once
  pose_T_beta.reserve(static_cast<std::size_t>(beta.numPoses()));
  for (int t = 0; t < beta.numPoses(); ++t) pose_T_beta.push_back(beta.pose(t).inverse());
  OverlapEvidence out;
  for (const ObjectMapEntry& o : alpha_objects) {
    const Vector3 p = beta_T_alpha.transformFrom(o.pose.translation());
    const bool seen = std::any_of(pose_T_beta.begin(), pose_T_beta.end(), [&](const SE3& x_inv) {
      return check.camera.sees(x_inv.transformFrom(p));
    });
    if (!seen) continue;
    ++out.seen;
    const auto& landmarks = beta.landmarks();
    for (std::size_t k = 0; k < landmarks.size(); ++k) {
      if (landmarks[k].label == o.label &&
          (beta.landmarkPose(k).translation() - p).norm() <= check.radius) {
        ++out.confirmed;
        break;
      }
    }
  }
  return out;
}

Matrix6 RendezvousConfig::lambda() const {
  const double sr = lambda_sigma_rotation_deg * kDegToRad, st = lambda_sigma_translation;
  Vector6 d;
  d << Vector3::Constant(1.0 / (sr * sr)), Vector3::Constant(1.0 / (st * st));
  return d.asDiagonal();
}

RelativePoseFactor ObjectObjectFactor(const SharedObject& shared, const Matrix6& lambda) {
  return RelativePoseFactor(shared.beta_object, shared.alpha_object, SE3(), lambda);
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> MatchObjectMaps(
    const ObjectMapMessage& from_alpha, const SE3& beta_T_alpha,
    const std::vector<ObjectMapEntry>& beta_objects, const AssociationGate& gate,
    const std::vector<std::uint32_t>& alpha_taken, const std::vector<std::uint32_t>& beta_taken) {
  const std::set<std::uint32_t> at(alpha_taken.begin(), alpha_taken.end());
  const std::set<std::uint32_t> bt(beta_taken.begin(), beta_taken.end());
  std::vector<LandmarkCandidate> queries, candidates;
  for (const auto& o : from_alpha.objects) {
    queries.push_back({o.label, beta_T_alpha * o.pose, at.count(o.landmark) == 0});
  }
  for (const auto& o : beta_objects) {
    candidates.push_back({o.label, o.pose, bt.count(o.landmark) == 0});
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (const auto& p : MatchWithinGate(queries, candidates, gate)) {
    out.emplace_back(from_alpha.objects[p.query].landmark, beta_objects[p.candidate].landmark);
  }
  return out;
}

namespace {

std::vector<ConstellationObject> Constellation(const std::vector<ObjectMapEntry>& objects) {
  std::vector<ConstellationObject> out;
  for (const auto& o : objects) out.push_back({o.landmark, o.label, o.pose});
  return out;
}

// ConsistentSubset of `pairs` given by landmark, (alpha landmark, beta landmark): the indices
// into `pairs` of the largest pairwise-consistent subset (constellation.h, step 2).
std::vector<std::size_t> ConsistentPairs(
    const std::vector<ConstellationObject>& a, const std::vector<ConstellationObject>& b,
    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
    const ConstellationConfig& config) {
  std::map<std::uint32_t, std::size_t> a_index, b_index;
  for (std::size_t i = 0; i < a.size(); ++i) a_index.emplace(a[i].id, i);
  for (std::size_t j = 0; j < b.size(); ++j) b_index.emplace(b[j].id, j);
  std::vector<std::pair<std::size_t, std::size_t>> indexed;
  for (const auto& [ka, kb] : pairs) indexed.emplace_back(a_index.at(ka), b_index.at(kb));
  return ConsistentSubset(a, b, indexed, config);
}

using LandmarkPair = std::pair<std::uint32_t, std::uint32_t>;  // (alpha's, beta's)

// The two maps of a rendezvous, the landmarks their robots share already left out: what beta
// matches under a transform of alpha's objects.
struct MapPair {
  const ObjectMapMessage& alpha;
  const std::vector<ObjectMapEntry>& beta;
  const AssociationGate& gate;
  const std::vector<std::uint32_t>& alpha_taken;
  const std::vector<std::uint32_t>& beta_taken;

  std::vector<LandmarkPair> match(const SE3& b_T_a) const {
    return MatchObjectMaps(alpha, b_T_a, beta, gate, alpha_taken, beta_taken);
  }
  int count(const SE3& b_T_a) const { return static_cast<int>(match(b_T_a).size()); }
};

struct ScoredAlignment {
  SE3 b_T_a;
  int matches = 0;  // MapPair::count under b_T_a
};

// Single-pair proposals (RendezvousConfig::refine_alignment): for each pair of one label within
// the correction bound of the prior, the transform that makes the two coincide; the one under
// which the most objects match (ties: the pair nearest the prior). Zero matches when no pair is
// within the bound.
ScoredAlignment BestProposal(const MapPair& maps, const SE3& prior,
                             const RendezvousConfig& config) {
  const std::set<std::uint32_t> at(maps.alpha_taken.begin(), maps.alpha_taken.end());
  const std::set<std::uint32_t> bt(maps.beta_taken.begin(), maps.beta_taken.end());
  AssociationGate wide;
  wide.sigma = std::max(config.max_correction_m, 1e-9);
  wide.sigma_rotation_deg = std::max(config.max_correction_deg, 1e-9);
  wide.num_sigmas = 1.0;
  ScoredAlignment best;
  double best_score = 0.0;
  for (const auto& a : maps.alpha.objects) {
    if (at.count(a.landmark) != 0) continue;
    const SE3 predicted = prior * a.pose;
    for (const auto& b : maps.beta) {
      double score = 0.0;
      if (b.label != a.label || bt.count(b.landmark) != 0 ||
          !wide.accepts(predicted, b.pose, &score)) {
        continue;
      }
      const SE3 T = b.pose * a.pose.inverse();
      const int n = maps.count(T);
      if (n > best.matches || (n == best.matches && score < best_score)) {
        best = {T, n};
        best_score = score;
      }
    }
  }
  return best;
}

// `proposal` refined by the rigid fit of the positions it matches, when they fix a rotation and
// the fit matches as many objects.
ScoredAlignment RefinedByRigidFit(const MapPair& maps, const ScoredAlignment& proposal) {
  std::map<std::uint32_t, Vector3> pa, pb;
  for (const auto& o : maps.alpha.objects) pa[o.landmark] = o.pose.translation();
  for (const auto& o : maps.beta) pb[o.landmark] = o.pose.translation();
  std::vector<Vector3> src, dst;
  for (const auto& [ka, kb] : maps.match(proposal.b_T_a)) {
    src.push_back(pa.at(ka));
    dst.push_back(pb.at(kb));
  }
  try {
    const SE3 refined = AlignRigid(src, dst);
    const int n = maps.count(refined);
    if (n >= proposal.matches) return {refined, n};
  } catch (const UnderdeterminedError&) {
    // Collinear or too few matches: keep the single-pair proposal.
  }
  return proposal;
}

// The constellation's alignment (RendezvousConfig::refine_by_constellation) when more of the
// matches under it agree pairwise than under `current`; else `current`.
ScoredAlignment PreferConstellation(const MapPair& maps, const RendezvousConfig& config,
                                    const ScoredAlignment& current) {
  const std::vector<ConstellationObject> a = Constellation(maps.alpha.objects),
                                         b = Constellation(maps.beta);
  const ConstellationAlignment aligned = AlignConstellations(a, b, config.constellation);
  if (aligned.status != AlignmentStatus::kAligned) return current;
  const auto consistent = [&](const SE3& T) {
    return ConsistentPairs(a, b, maps.match(T), config.constellation).size();
  };
  if (consistent(aligned.b_T_a) <= consistent(current.b_T_a)) return current;
  return {aligned.b_T_a, maps.count(aligned.b_T_a)};
}

// The pairs robots a (alpha) and b (beta) share so far, in either role.
std::set<LandmarkPair> SharedBefore(const std::vector<SharedObject>& shared, int a, int b) {
  std::set<LandmarkPair> before;
  for (const auto& s : shared) {
    if (s.alpha_object.robot == a && s.beta_object.robot == b) {
      before.emplace(static_cast<std::uint32_t>(s.alpha_object.index),
                     static_cast<std::uint32_t>(s.beta_object.index));
    } else if (s.alpha_object.robot == b && s.beta_object.robot == a) {
      before.emplace(static_cast<std::uint32_t>(s.beta_object.index),
                     static_cast<std::uint32_t>(s.alpha_object.index));
    }
  }
  return before;
}

// Unknown initial poses: alpha's map aligned with beta's (`own`) from their objects alone, then
// refused as contradicted when, of alpha's objects the alignment puts in view of beta's poses (at
// least overlap.min_seen of them), fewer than overlap.min_confirmed_fraction have an object of
// their label within overlap.radius in beta's map (RendezvousConfig::overlap).
ConstellationAlignment AlignUnknown(const ObjectMapMessage& received,
                                    const std::vector<ObjectMapEntry>& own, const ObjectSlam& beta,
                                    const RendezvousConfig& config) {
  ConstellationAlignment aligned = AlignConstellations(Constellation(received.objects),
                                                       Constellation(own), config.constellation);
  if (aligned.status != AlignmentStatus::kAligned || !config.overlap.enabled) return aligned;
  const OverlapEvidence e = AlignmentOverlap(received.objects, aligned.b_T_a, beta, config.overlap);
  if (e.seen >= config.overlap.min_seen &&
      e.confirmed < config.overlap.min_confirmed_fraction * e.seen) {
    aligned.status = AlignmentStatus::kContradicted;
    aligned.reason = std::to_string(e.confirmed) + " of the " + std::to_string(e.seen) +
                     " objects of robot " + std::to_string(received.sender) +
                     " in view of this robot's poses have an object of their label within " +
                     std::to_string(config.overlap.radius) + " m";
    aligned.pairs.clear();
    aligned.b_T_a = SE3();
  }
  return aligned;
}

// Consistency across rendezvous: the pairs shared before and the new ones of `reply`, checked
// together; `reply` keeps the new ones in the largest consistent set and removes the old ones
// outside it.
void CheckAcrossRendezvous(const std::vector<ObjectMapEntry>& alpha_objects,
                           const std::vector<ObjectMapEntry>& own,
                           const std::set<LandmarkPair>& before, const ConstellationConfig& config,
                           SharedObjectsMessage& reply) {
  std::vector<LandmarkPair> all(before.begin(), before.end());
  all.insert(all.end(), reply.pairs.begin(), reply.pairs.end());
  const std::vector<std::size_t> kept =
      ConsistentPairs(Constellation(alpha_objects), Constellation(own), all, config);
  std::vector<bool> keep(all.size(), false);
  for (std::size_t k : kept) keep[k] = true;
  std::vector<LandmarkPair> added;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const bool old = i < before.size();
    if (old && !keep[i]) reply.removed.push_back(all[i]);
    if (!old && keep[i]) added.push_back(all[i]);
  }
  reply.pairs = std::move(added);
}

// Ground-truth association (RendezvousConfig::ground_truth_association, simulation only): each of
// alpha's objects paired with beta's landmark of the same world object, landmarks the two robots
// share already left out.
SharedObjectsMessage GroundTruthAnswer(const ObjectMapMessage& received, const ObjectSlam& alpha,
                                       const ObjectSlam& beta,
                                       const std::vector<SharedObject>& already_shared) {
  const int a = alpha.robot(), b = beta.robot();
  std::vector<std::uint32_t> alpha_taken, beta_taken;
  TakenLandmarks(already_shared, a, b, &alpha_taken, &beta_taken);
  SharedObjectsMessage reply;
  reply.sender = b;
  reply.receiver = a;
  const std::set<std::uint32_t> at(alpha_taken.begin(), alpha_taken.end());
  std::set<std::uint32_t> bt(beta_taken.begin(), beta_taken.end());
  for (const auto& o : received.objects) {
    const int truth = alpha.landmarks().at(o.landmark).true_object;
    if (truth < 0 || at.count(o.landmark) != 0) continue;
    for (const auto& lm : beta.landmarks()) {
      const auto l = static_cast<std::uint32_t>(lm.key.index);
      if (lm.true_object == truth && bt.insert(l).second) {
        reply.pairs.emplace_back(o.landmark, l);
        break;
      }
    }
  }
  return reply;
}

}  // namespace

SE3 AlignObjectMaps(const ObjectMapMessage& from_alpha, const SE3& prior,
                    const std::vector<ObjectMapEntry>& beta_objects, const RendezvousConfig& config,
                    const std::vector<std::uint32_t>& alpha_taken,
                    const std::vector<std::uint32_t>& beta_taken, int* inliers) {
  config.validate();
  const MapPair maps{from_alpha, beta_objects, config.gate, alpha_taken, beta_taken};
  ScoredAlignment best{prior, maps.count(prior)};
  if (config.refine_alignment) {
    const ScoredAlignment proposal = BestProposal(maps, prior, config);
    if (proposal.matches >= config.min_inliers && proposal.matches > best.matches) {
      best = RefinedByRigidFit(maps, proposal);
    }
  }
  if (config.refine_by_constellation) best = PreferConstellation(maps, config, best);
  if (inliers != nullptr) *inliers = best.matches;
  return best.b_T_a;
}

RendezvousOutcome RunRendezvous(const ObjectSlam& alpha, const ObjectSlam& beta,
                                const std::optional<SE3>& beta_T_alpha,
                                const std::vector<SharedObject>& already_shared,
                                const RendezvousConfig& config) {
  config.validate();
  const int a = alpha.robot(), b = beta.robot();
  if (a == b) throw InvalidInputError("RunRendezvous: robot " + std::to_string(a) + " meets itself");
  RendezvousOutcome out;
  // Alpha -> beta: its object map, through the wire.
  const ObjectMapMessage sent = MakeObjectMapMessage(alpha);
  const std::vector<std::uint8_t> wire1 = EncodeObjectMap(sent);
  out.bytes_alpha_to_beta = wire1.size();
  out.objects_sent = static_cast<int>(sent.objects.size());
  const ObjectMapMessage received = DecodeObjectMap(wire1);

  SharedObjectsMessage reply;
  if (config.ground_truth_association) {
    reply = GroundTruthAnswer(received, alpha, beta, already_shared);
  } else {
    ConstellationAlignment alignment;
    reply = AnswerObjectMap(received, beta, beta_T_alpha, already_shared, config, &alignment);
    if (!beta_T_alpha) out.alignment = alignment;
  }

  // Beta -> alpha: the shared-object list, through the wire; both add (and drop) the factors.
  const std::vector<std::uint8_t> wire2 = EncodeSharedObjects(reply);
  out.bytes_beta_to_alpha = wire2.size();
  const SharedObjectsMessage answer = DecodeSharedObjects(wire2);
  out.new_shared = SharedObjectsOf(answer);
  out.removed_shared = RemovedObjectsOf(answer);
  return out;
}

SharedObjectsMessage AnswerObjectMap(const ObjectMapMessage& received, const ObjectSlam& beta,
                                     const std::optional<SE3>& beta_T_alpha,
                                     const std::vector<SharedObject>& already_shared,
                                     const RendezvousConfig& config,
                                     ConstellationAlignment* alignment) {
  config.validate();
  const int a = received.sender, b = beta.robot();
  if (a == b) {
    throw InvalidInputError("AnswerObjectMap: robot " + std::to_string(a) + " meets itself");
  }
  std::vector<std::uint32_t> alpha_taken, beta_taken;
  TakenLandmarks(already_shared, a, b, &alpha_taken, &beta_taken);
  const std::set<LandmarkPair> before = SharedBefore(already_shared, a, b);
  SharedObjectsMessage reply;
  reply.sender = b;
  reply.receiver = a;
  const std::vector<ObjectMapEntry> own = MakeObjectMapMessage(beta).objects;
  if (beta_T_alpha) {
    const SE3 T =
        AlignObjectMaps(received, *beta_T_alpha, own, config, alpha_taken, beta_taken);
    reply.pairs = MatchObjectMaps(received, T, own, config.gate, alpha_taken, beta_taken);
    if (!config.check_consistency) return reply;
  } else {
    // Unknown initial poses: the whole maps aligned from their objects; the consistent set is
    // what this pair shares now.
    const ConstellationAlignment aligned = AlignUnknown(received, own, beta, config);
    if (alignment) *alignment = aligned;
    if (aligned.status != AlignmentStatus::kAligned) return reply;  // refused: nothing changes
    std::vector<std::uint32_t> a_used = alpha_taken, b_used = beta_taken;
    for (const auto& pair : aligned.pairs) {
      if (before.count(pair) == 0) reply.pairs.push_back(pair);
      a_used.push_back(pair.first);
      b_used.push_back(pair.second);
    }
    // The objects the set missed, matched under its transform as with a known prior.
    for (const auto& pair : MatchObjectMaps(received, aligned.b_T_a, own, config.gate, a_used, b_used)) {
      reply.pairs.push_back(pair);
    }
  }
  CheckAcrossRendezvous(received.objects, own, before, config.consistency, reply);
  return reply;
}

bool EraseShared(std::vector<SharedObject>& shared, const SharedObject& pair) {
  const auto it = std::find_if(shared.begin(), shared.end(), [&](const SharedObject& x) {
    return (x.beta_object == pair.beta_object && x.alpha_object == pair.alpha_object) ||
           (x.beta_object == pair.alpha_object && x.alpha_object == pair.beta_object);
  });
  if (it == shared.end()) return false;
  shared.erase(it);
  return true;
}

std::vector<SharedObject> RemovedObjectsOf(const SharedObjectsMessage& answer) {
  std::vector<SharedObject> out;
  for (const auto& [ka, kb] : answer.removed) {
    out.push_back({Key::Object(answer.sender, kb), Key::Object(answer.receiver, ka)});
  }
  return out;
}

std::vector<SharedObject> SharedObjectsOf(const SharedObjectsMessage& answer) {
  std::vector<SharedObject> out;
  for (const auto& [ka, kb] : answer.pairs) {
    out.push_back({Key::Object(answer.sender, kb), Key::Object(answer.receiver, ka)});
  }
  return out;
}

}  // namespace moslam
