#include "moslam/slam/object_slam.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/solver/marginals.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
// AssociationGateForNoise: sigma = kNoiseToGate * measurement sigma, with floors.
constexpr double kNoiseToGate = 3.4641016151377544;  // 2 sqrt(3)
constexpr double kLeverArm = 2.0;         // m: typical range times heading error
constexpr double kMinGateSigma = 0.1;     // m
constexpr double kMinGateSigmaDeg = 2.0;  // deg

// Throws InvalidInputError on a detection whose factor could not be built.
void ValidateDetections(const std::vector<ObjectDetection>& detections, int robot, int pose,
                        bool need_ids) {
  std::set<int> ids;
  for (std::size_t d = 0; d < detections.size(); ++d) {
    const std::string what = "robot " + std::to_string(robot) + " pose " + std::to_string(pose) +
                             " detection " + std::to_string(d);
    if (detections[d].label.empty()) throw InvalidInputError(what + ": empty label");
    if (need_ids && (detections[d].object_id < 0 || !ids.insert(detections[d].object_id).second)) {
      throw InvalidInputError(what + ": ground-truth association needs distinct object ids >= 0 "
                                     "in the detections of a pose");
    }
    try {
      RelativePoseFactor(Key::Pose(0, 0), Key::Object(0, 0), detections[d].measurement,
                         detections[d].information);
    } catch (const InvalidInputError& e) {
      throw InvalidInputError(what + ": " + e.what());
    }
  }
}

Key Rekey(Key k, int robot) {
  k.robot = robot;
  return k;
}

}  // namespace

void AssociationGate::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("AssociationGate: " + m); };
  if (!(sigma > 0.0) || !std::isfinite(sigma)) bad("sigma must be positive and finite");
  if (!std::isfinite(sigma_rotation_deg)) bad("sigma_rotation_deg must be finite");
  if (!(num_sigmas > 0.0) || !std::isfinite(num_sigmas)) {
    bad("num_sigmas must be positive and finite");
  }
}

namespace {

// The gate's two terms in sigmas: the position discrepancy, the angle (0 when not tested).
std::pair<double, double> GateTerms(const AssociationGate& gate, const SE3& predicted,
                                    const SE3& candidate) {
  const double d = (candidate.translation() - predicted.translation()).norm() / gate.sigma;
  if (gate.sigma_rotation_deg <= 0.0) return {d, 0.0};
  const double angle_deg =
      SO3::Log(predicted.rotation().inverse() * candidate.rotation()).norm() * kRadToDeg;
  return {d, angle_deg / gate.sigma_rotation_deg};
}

}  // namespace

double AssociationGate::score(const SE3& predicted, const SE3& candidate) const {
  const auto [d, a] = GateTerms(*this, predicted, candidate);
  return d * d + a * a;
}

bool AssociationGate::accepts(const SE3& predicted, const SE3& candidate, double* score) const {
  const auto [d, a] = GateTerms(*this, predicted, candidate);
  if (d > num_sigmas || a > num_sigmas) return false;
  if (score != nullptr) *score = d * d + a * a;
  return true;
}

AssociationGate AssociationGateForNoise(double sigma_rotation_deg, double sigma_translation,
                                        double num_sigmas) {
  if (!(sigma_translation >= 0.0) || !std::isfinite(sigma_translation)) {
    throw InvalidInputError("AssociationGateForNoise: sigma_translation must be >= 0 and finite");
  }
  if (!(sigma_rotation_deg >= 0.0) || !std::isfinite(sigma_rotation_deg)) {
    throw InvalidInputError("AssociationGateForNoise: sigma_rotation_deg must be >= 0 and finite");
  }
  AssociationGate g;
  const double lever = kLeverArm * sigma_rotation_deg / kRadToDeg;
  g.sigma = std::max(kNoiseToGate * std::max(sigma_translation, lever), kMinGateSigma);
  g.sigma_rotation_deg = std::max(kNoiseToGate * sigma_rotation_deg, kMinGateSigmaDeg);
  g.num_sigmas = num_sigmas;
  g.validate();
  return g;
}

namespace {

// The pairs accepted nearest first (stable in their order on ties), each query and each candidate
// at most once, in the order accepted.
std::vector<GatedPair> NearestFirst(std::vector<GatedPair> pairs, std::size_t queries,
                                    std::size_t candidates) {
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const GatedPair& a, const GatedPair& b) { return a.score < b.score; });
  std::vector<bool> q_used(queries, false), c_used(candidates, false);
  std::vector<GatedPair> out;
  for (const auto& p : pairs) {
    if (q_used[p.query] || c_used[p.candidate]) continue;
    q_used[p.query] = c_used[p.candidate] = true;
    out.push_back(p);
  }
  return out;
}

}  // namespace

std::optional<std::size_t> NearestWithinGate(const std::string& label, const SE3& predicted,
                                             const std::vector<LandmarkCandidate>& candidates,
                                             const AssociationGate& gate) {
  gate.validate();
  std::optional<std::size_t> best;
  double best_score = 0.0;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const auto& c = candidates[i];
    double score = 0.0;
    if (!c.available || c.label != label || !gate.accepts(predicted, c.pose, &score)) continue;
    if (!best || score < best_score) {
      best = i;
      best_score = score;
    }
  }
  return best;
}

std::vector<GatedPair> MatchWithinGate(const std::vector<LandmarkCandidate>& queries,
                                       const std::vector<LandmarkCandidate>& candidates,
                                       const AssociationGate& gate) {
  gate.validate();
  std::vector<GatedPair> pairs;
  for (std::size_t q = 0; q < queries.size(); ++q) {
    if (!queries[q].available) continue;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      if (!candidates[c].available || candidates[c].label != queries[q].label) continue;
      double score = 0.0;
      if (gate.accepts(queries[q].pose, candidates[c].pose, &score)) pairs.push_back({q, c, score});
    }
  }
  return NearestFirst(std::move(pairs), queries.size(), candidates.size());
}

AssociationStats& AssociationStats::operator+=(const AssociationStats& o) {
  static_assert(sizeof(AssociationStats) == 10 * sizeof(int),
                "AssociationStats has a new count: add it here");
  detections += o.detections;
  associated += o.associated;
  correct += o.correct;
  new_landmarks += o.new_landmarks;
  duplicate_landmarks += o.duplicate_landmarks;
  discarded += o.discarded;
  refused += o.refused;
  associable += o.associable;
  loop_closures += o.loop_closures;
  wrong_loop_closures += o.wrong_loop_closures;
  return *this;
}

void ObjectSlamConfig::validate() const {
  association.validate();
  if (update_every < 1) throw InvalidInputError("ObjectSlamConfig: update_every must be >= 1");
  if (localization_iterations < 0) {
    throw InvalidInputError("ObjectSlamConfig: localization_iterations must be >= 0");
  }
  if (iterations_per_update < 0) {
    throw InvalidInputError("ObjectSlamConfig: iterations_per_update must be >= 0");
  }
  if (!(exclusion_radius >= 0.0 && std::isfinite(exclusion_radius))) {
    throw InvalidInputError("ObjectSlamConfig: exclusion_radius must be finite and >= 0");
  }
  if (!(ambiguity_ratio >= 0.0 && ambiguity_ratio < 1.0)) {
    throw InvalidInputError("ObjectSlamConfig: ambiguity_ratio must be in [0, 1) (0: off)");
  }
  if (!(covariance_gate >= 0.0 && std::isfinite(covariance_gate))) {
    throw InvalidInputError(
        "ObjectSlamConfig: covariance_gate must be finite and >= 0 (a chi-square bound with 6 "
        "degrees of freedom, e.g. 22.46; 0: off)");
  }
  if (!(leave_one_out_rival_radii > 0.0 && std::isfinite(leave_one_out_rival_radii))) {
    throw InvalidInputError("ObjectSlamConfig: leave_one_out_rival_radii must be finite and > 0");
  }
  if (leave_one_out_check && localization_iterations == 0) {
    throw InvalidInputError(
        "ObjectSlamConfig: leave_one_out_check localises the pose on the other matches and needs "
        "localization_iterations >= 1");
  }
  if (loop_closure_window < 1) {
    throw InvalidInputError("ObjectSlamConfig: loop_closure_window must be >= 1");
  }
  if (!(loop_closure_sigma_rotation_deg > 0.0 && std::isfinite(loop_closure_sigma_rotation_deg))) {
    throw InvalidInputError("ObjectSlamConfig: loop_closure_sigma_rotation_deg must be finite and "
                            "> 0");
  }
  if (!(loop_closure_sigma_translation > 0.0 && std::isfinite(loop_closure_sigma_translation))) {
    throw InvalidInputError("ObjectSlamConfig: loop_closure_sigma_translation must be finite and "
                            "> 0");
  }
  if (loop_closure_one_label_min_support < 1) {
    throw InvalidInputError("ObjectSlamConfig: loop_closure_one_label_min_support must be >= 1");
  }
  if (loop_closure_iterations < 0) {
    throw InvalidInputError("ObjectSlamConfig: loop_closure_iterations must be >= 0");
  }
  try {
    loop_closure_alignment.validate();
  } catch (const InvalidInputError& e) {
    throw InvalidInputError(std::string("ObjectSlamConfig: loop_closure_alignment: ") + e.what());
  }
}

ObjectSlam::ObjectSlam(int robot, const ObjectSlamConfig& config)
    : robot_(robot), config_(config) {
  config_.validate();
  if (robot < 0 || robot > 65535) {
    throw InvalidInputError("ObjectSlam: robot id " + std::to_string(robot) +
                            " outside [0, 65535]");
  }
}

void ObjectSlam::addFirstPose(const std::vector<ObjectDetection>& detections) {
  if (num_poses_ != 0) throw InvalidInputError("ObjectSlam::addFirstPose called twice");
  ValidateDetections(detections, robot_, 0, config_.ground_truth_association);
  local_values_[Key::Pose(0, 0)] = SE3();
  num_poses_ = 1;
  addDetections(detections, nullptr);
  maybeUpdate();
}

void ObjectSlam::addPose(const OdometryReading& odometry,
                         const std::vector<ObjectDetection>& detections) {
  if (num_poses_ == 0) {
    throw InvalidInputError("ObjectSlam::addPose before addFirstPose (robot " +
                            std::to_string(robot_) + ")");
  }
  const auto i = static_cast<std::uint64_t>(num_poses_);
  const Key prev = Key::Pose(0, i - 1), cur = Key::Pose(0, i);
  const RelativePoseFactor odo(prev, cur, odometry.measurement, odometry.information);
  ValidateDetections(detections, robot_, num_poses_, config_.ground_truth_association);
  local_graph_.add(odo);
  factor_objects_.push_back(kNoObservation);
  local_values_[cur] = local_values_.at(prev) * odometry.measurement;
  ++num_poses_;
  addDetections(detections, &odo);
  maybeUpdate();
}

std::optional<ObjectSlam::MatchCovariance> ObjectSlam::matchCovariance(
    const std::vector<ObjectDetection>& detections) const {
  std::set<std::string> labels;
  for (const auto& d : detections) labels.insert(d.label);
  MatchCovariance out;
  out.pose = local_values_.at(Key::Pose(0, static_cast<std::uint64_t>(num_poses_ - 1)));
  std::vector<Key> keys{Key::Pose(0, static_cast<std::uint64_t>(num_poses_ - 1))};
  for (std::size_t k = 0; k < landmarks_.size(); ++k) {
    if (labels.count(landmarks_[k].label) == 0) continue;
    out.landmarks.push_back(k);
    keys.push_back(Key::Object(0, k));
  }
  if (out.landmarks.empty()) return out;
  try {
    out.joint = Marginals(weightedGraph(), local_values_).jointCovariance(keys);
  } catch (const UnderdeterminedError&) {
    return std::nullopt;
  } catch (const NumericalError&) {
    return std::nullopt;
  }
  return out;
}

double ObjectSlam::chiSquare(const ObjectDetection& detection, const MatchCovariance& c,
                             std::size_t j, Vector6* residual, Matrix6* d_pose,
                             Matrix6* d_landmark) const {
  const std::size_t k = c.landmarks[j];
  Matrix6 jx, jo;
  const Vector6 r =
      RelativePoseFactor(Key::Pose(0, static_cast<std::uint64_t>(num_poses_ - 1)),
                         Key::Object(0, k), detection.measurement, detection.information)
          .residual(c.pose, landmarkPose(k), &jx, &jo);
  if (residual != nullptr) *residual = r;
  if (d_pose != nullptr) *d_pose = jx;
  if (d_landmark != nullptr) *d_landmark = jo;
  const auto b = static_cast<Eigen::Index>(6 * (j + 1));
  const Matrix6 sxo = c.joint.block<6, 6>(0, b);
  const Matrix6 jsxo = jx * sxo * jo.transpose();
  const Matrix6 s = jx * c.joint.topLeftCorner<6, 6>() * jx.transpose() + jsxo +
                    jsxo.transpose() + jo * c.joint.block<6, 6>(b, b) * jo.transpose() +
                    detection.information.inverse();
  const double m2 = r.dot(s.ldlt().solve(r));
  return std::isfinite(m2) ? m2 : std::numeric_limits<double>::infinity();
}

std::vector<std::optional<std::size_t>> ObjectSlam::matchJointly(
    const std::vector<ObjectDetection>& detections, const MatchCovariance& prior) const {
  struct Candidate {
    std::size_t j;  // block j + 1 of prior.joint
    double m2;
    Vector6 r;
    Matrix6 jx, jo;
  };
  const std::size_t n = detections.size();
  std::vector<std::vector<Candidate>> candidates(n);
  for (std::size_t d = 0; d < n; ++d) {
    for (std::size_t j = 0; j < prior.landmarks.size(); ++j) {
      const std::size_t k = prior.landmarks[j];
      if (landmarks_[k].label != detections[d].label) continue;
      Candidate c{j, 0.0, Vector6::Zero(), Matrix6::Zero(), Matrix6::Zero()};
      c.m2 = chiSquare(detections[d], prior, j, &c.r, &c.jx, &c.jo);
      if (c.m2 <= config_.covariance_gate) candidates[d].push_back(c);
    }
    std::sort(candidates[d].begin(), candidates[d].end(),
              [](const Candidate& a, const Candidate& b) { return a.m2 < b.m2; });
  }
  // The chi-square bound of 6 m dof at the tail of covariance_gate's 6 (Wilson-Hilferty).
  const double z =
      (std::cbrt(config_.covariance_gate / 6.0) - 1.0 + 2.0 / 54.0) / std::sqrt(2.0 / 54.0);
  const auto bound = [z](std::size_t m) {
    const double nu = 6.0 * static_cast<double>(m);
    const double a = 2.0 / (9.0 * nu);
    return nu * std::pow(1.0 - a + z * std::sqrt(a), 3);
  };
  const auto block = [&](std::size_t a, std::size_t b) {
    return prior.joint.block<6, 6>(static_cast<Eigen::Index>(6 * a),
                                   static_cast<Eigen::Index>(6 * b));
  };
  std::vector<std::pair<std::size_t, const Candidate*>> hypothesis;  // (detection, candidate)
  const auto joint_m2 = [&]() {
    const auto m = static_cast<Eigen::Index>(6 * hypothesis.size());
    Eigen::MatrixXd s(m, m);
    Eigen::VectorXd r(m);
    for (std::size_t a = 0; a < hypothesis.size(); ++a) {
      const Candidate& ca = *hypothesis[a].second;
      r.segment<6>(static_cast<Eigen::Index>(6 * a)) = ca.r;
      for (std::size_t b = 0; b <= a; ++b) {
        const Candidate& cb = *hypothesis[b].second;
        Matrix6 sab = ca.jx * block(0, 0) * cb.jx.transpose() +
                      ca.jx * block(0, cb.j + 1) * cb.jo.transpose() +
                      ca.jo * block(ca.j + 1, 0) * cb.jx.transpose() +
                      ca.jo * block(ca.j + 1, cb.j + 1) * cb.jo.transpose();
        if (a == b) sab += detections[hypothesis[a].first].information.inverse();
        s.block<6, 6>(static_cast<Eigen::Index>(6 * a), static_cast<Eigen::Index>(6 * b)) = sab;
        s.block<6, 6>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(6 * a)) =
            sab.transpose();
      }
    }
    const double m2 = r.dot(s.ldlt().solve(r));
    return std::isfinite(m2) ? m2 : std::numeric_limits<double>::infinity();
  };
  std::vector<bool> taken(prior.landmarks.size(), false);
  std::vector<std::optional<std::size_t>> best(n);
  std::size_t best_pairs = 0;
  double best_m2 = std::numeric_limits<double>::infinity();
  long nodes = 0;
  const std::function<void(std::size_t, double)> search = [&](std::size_t d, double m2) {
    if (++nodes > kMaxJointNodes) return;
    if (d == n) {
      if (hypothesis.size() > best_pairs || (hypothesis.size() == best_pairs && m2 < best_m2)) {
        best_pairs = hypothesis.size();
        best_m2 = m2;
        best.assign(n, std::nullopt);
        for (const auto& [e, c] : hypothesis) best[e] = prior.landmarks[c->j];
      }
      return;
    }
    for (const Candidate& c : candidates[d]) {
      if (taken[c.j] || hypothesis.size() + (n - d) < best_pairs) continue;
      hypothesis.emplace_back(d, &c);
      const double joint = joint_m2();
      if (joint <= bound(hypothesis.size())) {
        taken[c.j] = true;
        search(d + 1, joint);
        taken[c.j] = false;
      }
      hypothesis.pop_back();
    }
    if (hypothesis.size() + (n - d - 1) >= best_pairs) search(d + 1, m2);
  };
  search(0, 0.0);
  return best;
}

std::vector<std::optional<std::size_t>> ObjectSlam::associate(
    const SE3& x, const std::vector<ObjectDetection>& detections) const {
  if (config_.ground_truth_association) {
    std::vector<std::optional<std::size_t>> assigned(detections.size());
    for (std::size_t d = 0; d < detections.size(); ++d) {
      for (std::size_t k = 0; k < landmarks_.size(); ++k) {
        if (landmarks_[k].true_object == detections[d].object_id) assigned[d] = k;
      }
    }
    return assigned;
  }
  std::vector<LandmarkCandidate> queries, candidates;
  queries.reserve(detections.size());
  for (const auto& d : detections) queries.push_back({d.label, x * d.measurement, true});
  candidates.reserve(landmarks_.size());
  for (std::size_t k = 0; k < landmarks_.size(); ++k) {
    candidates.push_back({landmarks_[k].label, landmarkPose(k), true});
  }
  std::vector<std::optional<std::size_t>> assigned(detections.size());
  for (const auto& m : MatchWithinGate(queries, candidates, config_.association)) {
    assigned[m.query] = m.candidate;
  }
  return assigned;
}

SE3 ObjectSlam::refinePose(const SE3& x0, const RelativePoseFactor& odometry,
                           const std::vector<ObjectDetection>& detections,
                           const std::vector<std::optional<std::size_t>>& assigned) const {
  // Gauss-Newton on x_i alone: its odometry factor (previous pose held) and the object-pose
  // factors of the associated detections (landmarks held).
  const SE3 prev = local_values_.at(odometry.a());
  std::vector<std::pair<RelativePoseFactor, SE3>> objects;
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (!assigned[d]) continue;
    objects.emplace_back(RelativePoseFactor(odometry.b(), Key::Object(0, *assigned[d]),
                                            detections[d].measurement, detections[d].information),
                         landmarkPose(*assigned[d]));
  }
  SE3 x = x0;
  for (int it = 0; it < config_.localization_iterations; ++it) {
    Matrix6 H = Matrix6::Zero();
    Vector6 g = Vector6::Zero();
    Matrix6 J;
    Vector6 r = odometry.residual(prev, x, nullptr, &J);
    H += J.transpose() * odometry.information() * J;
    g += J.transpose() * odometry.information() * r;
    for (const auto& [f, o] : objects) {
      r = f.residual(x, o, &J, nullptr);
      H += J.transpose() * f.information() * J;
      g += J.transpose() * f.information() * r;
    }
    const Vector6 delta = H.ldlt().solve(-g);
    if (!delta.allFinite()) break;
    x = x.retract(delta);
    if (delta.lpNorm<Eigen::Infinity>() < 1e-10) break;
  }
  return x;
}

void ObjectSlam::addDetections(const std::vector<ObjectDetection>& detections,
                               const RelativePoseFactor* odometry) {
  const auto i = static_cast<std::uint64_t>(num_poses_ - 1);
  const Key pose_key = Key::Pose(0, i);
  SE3 x = local_values_.at(pose_key);
  std::optional<MatchCovariance> covariance;
  if (config_.covariance_gate > 0.0 && !config_.ground_truth_association) {
    covariance = matchCovariance(detections);
  }
  const MatchCovariance* cov = covariance ? &*covariance : nullptr;
  // The covariance gate matches the pose's detections jointly, from the prediction; the fixed
  // gate matches them nearest first, then again from the pose localised on those matches.
  std::vector<std::optional<std::size_t>> assigned =
      cov != nullptr ? matchJointly(detections, *cov) : associate(x, detections);
  const bool any = std::any_of(assigned.begin(), assigned.end(),
                               [](const auto& a) { return a.has_value(); });
  if (odometry != nullptr && any && config_.localization_iterations > 0) {
    x = refinePose(x, *odometry, detections, assigned);
    local_values_[pose_key] = x;
    if (cov == nullptr) assigned = associate(x, detections);
  }
  // The pose stays localised on every match: localising it again without the refused ones (or
  // at the prediction, when none is left) mapped worse (chairs25, 6 robots, seeds 11-20: GT ATE
  // 0.71 -> 0.97 m).
  std::vector<bool> refused(detections.size(), false);
  if (odometry != nullptr && config_.leave_one_out_check && !config_.ground_truth_association) {
    refused = refuseInconsistent(x, *odometry, detections, assigned);
  }
  if (config_.ambiguity_ratio > 0.0 && !config_.ground_truth_association) {
    const std::vector<bool> ambiguous = refuseAmbiguous(x, detections, assigned, cov);
    for (std::size_t d = 0; d < detections.size(); ++d) refused[d] = refused[d] || ambiguous[d];
  }
  record(detections, assigned, refused, x);
}

std::vector<bool> ObjectSlam::refuseAmbiguous(const SE3& x,
                                              const std::vector<ObjectDetection>& detections,
                                              std::vector<std::optional<std::size_t>>& assigned,
                                              const MatchCovariance* covariance) const {
  std::vector<bool> refused(detections.size(), false);
  std::vector<bool> taken(landmarks_.size(), false);
  for (const auto& a : assigned) {
    if (a) taken[*a] = true;
  }
  const AssociationGate& gate = config_.association;
  const double ratio2 = config_.ambiguity_ratio * config_.ambiguity_ratio;
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (!assigned[d]) continue;
    if (covariance != nullptr) {  // the covariance gate's distance, as the match was made
      const MatchCovariance& c = *covariance;
      const auto at = std::find(c.landmarks.begin(), c.landmarks.end(), *assigned[d]);
      const double score = chiSquare(detections[d], c, at - c.landmarks.begin());
      for (std::size_t j = 0; j < c.landmarks.size() && !refused[d]; ++j) {
        const std::size_t k = c.landmarks[j];
        if (taken[k] || landmarks_[k].label != detections[d].label) continue;
        const double rival = chiSquare(detections[d], c, j);
        refused[d] = rival <= config_.covariance_gate && score > ratio2 * rival;
      }
      continue;
    }
    const SE3 predicted = x * detections[d].measurement;
    const double score = gate.score(predicted, landmarkPose(*assigned[d]));
    for (std::size_t k = 0; k < landmarks_.size(); ++k) {
      if (taken[k] || landmarks_[k].label != detections[d].label) continue;
      double rival = 0.0;
      if (gate.accepts(predicted, landmarkPose(k), &rival) && score > ratio2 * rival) {
        refused[d] = true;
        break;
      }
    }
  }
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (refused[d]) assigned[d].reset();
  }
  return refused;
}

std::vector<bool> ObjectSlam::refuseInconsistent(
    const SE3& x, const RelativePoseFactor& odometry,
    const std::vector<ObjectDetection>& detections,
    std::vector<std::optional<std::size_t>>& assigned) const {
  std::vector<bool> refused(detections.size(), false);
  const auto matches = std::count_if(assigned.begin(), assigned.end(),
                                     [](const auto& a) { return a.has_value(); });
  if (matches < 2) return refused;
  const AssociationGate& gate = config_.association;
  const double limit = gate.num_sigmas * gate.num_sigmas;
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (!assigned[d]) continue;
    std::vector<std::optional<std::size_t>> others = assigned;
    others[d].reset();
    const SE3 localised = refinePose(x, odometry, detections, others);
    const SE3 predicted = localised * detections[d].measurement;
    refused[d] = gate.score(predicted, landmarkPose(*assigned[d])) > limit &&
                 nearLandmark(detections[d].label, predicted.translation(),
                              config_.leave_one_out_rival_radii * gate.radius(), *assigned[d]);
  }
  for (std::size_t d = 0; d < detections.size(); ++d) {
    if (refused[d]) assigned[d].reset();
  }
  return refused;
}

void ObjectSlam::record(const std::vector<ObjectDetection>& detections,
                        const std::vector<std::optional<std::size_t>>& assigned,
                        const std::vector<bool>& refused, const SE3& x) {
  const auto i = static_cast<std::uint64_t>(num_poses_ - 1);
  const Key pose_key = Key::Pose(0, i);
  const std::vector<int> mapped_before = mapped_objects_;
  auto was_mapped = [&](int object) {
    return object >= 0 && std::binary_search(mapped_before.begin(), mapped_before.end(), object);
  };
  last_associations_.assign(detections.size(), 0);
  for (std::size_t d = 0; d < detections.size(); ++d) {
    const auto& det = detections[d];
    ++stats_.detections;
    if (was_mapped(det.object_id)) ++stats_.associable;
    std::size_t k;
    if (assigned[d]) {
      k = *assigned[d];
      ++stats_.associated;
      if (det.object_id >= 0 && landmarks_[k].true_object == det.object_id) ++stats_.correct;
    } else if (refused[d]) {
      ++stats_.refused;
      last_associations_[d] = kDiscarded;
      continue;
    } else if (excluded(det, x)) {
      ++stats_.discarded;
      last_associations_[d] = kDiscarded;
      continue;
    } else {
      k = landmarks_.size();
      Landmark lm;
      lm.key = Key::Object(robot_, k);
      lm.label = det.label;
      lm.true_object = det.object_id;
      lm.first_pose = static_cast<int>(i);
      landmarks_.push_back(lm);
      local_values_[Key::Object(0, k)] = x * det.measurement;
      ++stats_.new_landmarks;
      if (was_mapped(det.object_id)) ++stats_.duplicate_landmarks;
      if (det.object_id >= 0) {
        const auto it = std::lower_bound(mapped_objects_.begin(), mapped_objects_.end(),
                                         det.object_id);
        if (it == mapped_objects_.end() || *it != det.object_id) {
          mapped_objects_.insert(it, det.object_id);
        }
      }
    }
    ++landmarks_[k].observations;
    last_associations_[d] = k;
    local_graph_.add(
        RelativePoseFactor(pose_key, Key::Object(0, k), det.measurement, det.information));
    factor_objects_.push_back(det.object_id);
  }
}

bool ObjectSlam::nearLandmark(const std::string& label, const Vector3& position, double radius,
                              std::size_t except) const {
  for (std::size_t k = 0; k < landmarks_.size(); ++k) {
    if (k != except && landmarks_[k].label == label &&
        (landmarkPose(k).translation() - position).norm() <= radius) {
      return true;
    }
  }
  return false;
}

bool ObjectSlam::excluded(const ObjectDetection& detection, const SE3& x) const {
  if (config_.exclusion_radius <= 0.0 || config_.ground_truth_association) return false;
  return nearLandmark(detection.label, (x * detection.measurement).translation(),
                      config_.exclusion_radius);
}

void ObjectSlam::maybeUpdate() {
  if ((num_poses_ - 1) % config_.update_every != 0) return;
  optimize(config_.iterations_per_update);
  if (closeLoops()) {
    optimize(std::max(config_.iterations_per_update, config_.loop_closure_iterations));
  }
}

bool ObjectSlam::closeLoops() {
  if (!config_.loop_closure || landmarks_.size() == landmarks_at_last_loop_attempt_) return false;
  landmarks_at_last_loop_attempt_ = landmarks_.size();
  // Recent: created within the last loop_closure_window poses and not closed yet; older: before.
  const int start = num_poses_ - config_.loop_closure_window;
  std::vector<ConstellationObject> recent, older;
  for (std::size_t k = 0; k < landmarks_.size(); ++k) {
    const Landmark& l = landmarks_[k];
    ConstellationObject o{static_cast<std::uint32_t>(k), l.label, landmarkPose(k)};
    if (l.first_pose < start) {
      older.push_back(std::move(o));
    } else if (l.closed_with < 0) {
      recent.push_back(std::move(o));
    }
  }
  // The pairs an alignment needs: min_support, or loop_closure_one_label_min_support when they
  // hold one label. Its pairs hold recent landmarks only: with one label among those, the
  // alignment itself is asked for that many.
  std::set<std::string> recent_labels;
  for (const ConstellationObject& o : recent) recent_labels.insert(o.label);
  const auto needed = [&](std::size_t labels) {
    return static_cast<std::size_t>(labels > 1 ? config_.loop_closure_alignment.min_support
                                               : config_.loop_closure_one_label_min_support);
  };
  ConstellationConfig alignment_config = config_.loop_closure_alignment;
  alignment_config.min_support = static_cast<int>(needed(recent_labels.size()));
  const auto min_support = static_cast<std::size_t>(alignment_config.min_support);
  if (recent.size() < min_support || older.size() < min_support) return false;
  const ConstellationAlignment alignment = AlignConstellations(recent, older, alignment_config);
  if (alignment.status != AlignmentStatus::kAligned) return false;
  // Each pair, the drift corrected, must pass the robot's association gate: the match it would
  // have made without the drift. The others are dropped, and too few left refuse the alignment.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (const auto& [r, o] : alignment.pairs) {
    if (config_.association.accepts(alignment.b_T_a * landmarkPose(r), landmarkPose(o))) {
      pairs.emplace_back(r, o);
    }
  }
  std::set<std::string> labels;
  for (const auto& [r, o] : pairs) labels.insert(landmarks_[r].label);
  if (pairs.size() < std::max(min_support, needed(labels.size()))) return false;
  const double sr = config_.loop_closure_sigma_rotation_deg / kRadToDeg;
  const double st = config_.loop_closure_sigma_translation;
  Vector6 diagonal;
  diagonal << Vector3::Constant(1.0 / (sr * sr)), Vector3::Constant(1.0 / (st * st));
  const Matrix6 information = diagonal.asDiagonal();
  for (const auto& [r, o] : pairs) {
    local_graph_.add(
        RelativePoseFactor(Key::Object(0, o), Key::Object(0, r), SE3(), information));
    factor_objects_.push_back(kNoObservation);
    landmarks_[r].closed_with = static_cast<int>(o);
    ++stats_.loop_closures;
    const int tr = landmarks_[r].true_object, to = landmarks_[o].true_object;
    if (tr >= 0 && to >= 0 && tr != to) ++stats_.wrong_loop_closures;
  }
  return true;
}

PoseGraph ObjectSlam::weightedGraph() const {
  PoseGraph g;
  if (factor_weights_.empty()) {
    g = local_graph_;
  } else {
    const auto& factors = local_graph_.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const RelativePoseFactor& f = factors[i];
      const double w = i < factor_weights_.size() ? factor_weights_[i] : 1.0;
      g.add(w == 1.0 ? f : RelativePoseFactor(f.a(), f.b(), f.measured(), w * f.information()));
    }
  }
  for (const auto& f : local_team_factors_) g.add(f);
  return g;
}

double ObjectSlam::refresh(int max_iterations) {
  if (local_graph_.factors().size() == factors_at_last_optimize_ && !stale_) {
    return weightedGraph().cost(local_values_);
  }
  return optimize(max_iterations);
}

double ObjectSlam::optimize(int max_iterations) {
  factors_at_last_optimize_ = local_graph_.factors().size();
  stale_ = false;
  if (local_graph_.empty()) return 0.0;
  const PoseGraph g = weightedGraph();
  if (max_iterations <= 0) return g.cost(local_values_);
  OptimizerOptions options;
  options.max_iterations = max_iterations;
  options.relative_cost_tolerance = 1e-6;
  NonlinearOptimizer opt(g, local_values_, options);
  const OptimizerResult& r = opt.optimize();
  local_values_ = r.values;
  return r.final_cost;
}

void ObjectSlam::setTeamFactors(const std::vector<RelativePoseFactor>& factors) {
  std::vector<RelativePoseFactor> local;
  local.reserve(factors.size());
  for (const auto& f : factors) {
    const bool pose_first = f.a() == Key::Pose(robot_, 0) && f.b().isObject();
    const bool pose_second = f.b() == Key::Pose(robot_, 0) && f.a().isObject();
    const Key object = pose_first ? f.b() : f.a();
    if (!(pose_first || pose_second) || object.robot != robot_ ||
        object.index >= landmarks_.size()) {
      throw InvalidInputError("ObjectSlam::setTeamFactors: robot " + std::to_string(robot_) +
                              " got a team factor between " + ToString(f.a()) + " and " +
                              ToString(f.b()) +
                              "; a team factor joins the robot's first pose and one of its "
                              "landmarks");
    }
    local.emplace_back(Rekey(f.a(), 0), Rekey(f.b(), 0), f.measured(), f.information());
  }
  team_factors_ = factors;
  local_team_factors_ = std::move(local);
  stale_ = true;
}

void ObjectSlam::setFactorWeights(std::vector<double> weights) {
  if (weights.size() > local_graph_.factors().size()) {
    throw InvalidInputError("ObjectSlam::setFactorWeights: robot " + std::to_string(robot_) +
                            " got " + std::to_string(weights.size()) + " weights for " +
                            std::to_string(local_graph_.factors().size()) + " factors");
  }
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!(weights[i] > 0.0 && weights[i] <= 1.0)) {
      throw InvalidInputError("ObjectSlam::setFactorWeights: robot " + std::to_string(robot_) +
                              ": the weight of factor " + std::to_string(i) + " is " +
                              std::to_string(weights[i]) + ", not in (0, 1]");
    }
  }
  factor_weights_ = std::move(weights);
  stale_ = true;
}

void ObjectSlam::setEstimate(const Values& estimate) {
  const auto fail = [&](const std::string& why) {
    throw InvalidInputError("ObjectSlam::setEstimate: robot " + std::to_string(robot_) + ": " +
                            why);
  };
  if (estimate.size() != local_values_.size()) {
    fail(std::to_string(estimate.size()) + " values for " +
         std::to_string(local_values_.size()) + " variables");
  }
  Values local;
  for (const auto& [k, x] : estimate) {
    if (k.robot != robot_ || local_values_.count(Rekey(k, 0)) == 0) {
      fail("no variable " + ToString(k));
    }
    if (!x.matrix().allFinite()) fail("the value of " + ToString(k) + " is not finite");
    local.emplace_hint(local.end(), Rekey(k, 0), x);
  }
  const Vector6 first = SE3::Log(local.at(Key::Pose(0, 0)));
  if (!(first.norm() <= 1e-9)) {
    fail("the first pose is not the identity (|Log| = " + std::to_string(first.norm()) +
         "): give the estimate in the robot's own frame");
  }
  local_values_ = std::move(local);
  local_values_[Key::Pose(0, 0)] = SE3();
  stale_ = true;
}

PoseGraph ObjectSlam::graph() const {
  PoseGraph g;
  for (const auto& f : local_graph_.factors()) {
    g.add(RelativePoseFactor(Rekey(f.a(), robot_), Rekey(f.b(), robot_), f.measured(),
                             f.information()));
  }
  return g;
}

Values ObjectSlam::estimate() const {
  Values v;
  for (const auto& [k, x] : local_values_) v.emplace_hint(v.end(), Rekey(k, robot_), x);
  return v;
}

SE3 ObjectSlam::pose(int i) const {
  if (i < 0 || i >= num_poses_) {
    throw InvalidInputError("ObjectSlam::pose: no pose " + std::to_string(i));
  }
  return local_values_.at(Key::Pose(0, static_cast<std::uint64_t>(i)));
}

SE3 ObjectSlam::landmarkPose(std::size_t k) const {
  if (k >= landmarks_.size()) {
    throw InvalidInputError("ObjectSlam::landmarkPose: no landmark " + std::to_string(k));
  }
  return local_values_.at(Key::Object(0, k));
}

}  // namespace moslam
