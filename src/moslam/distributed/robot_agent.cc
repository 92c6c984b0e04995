#include "moslam/distributed/robot_agent.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/two_stage_terms.h"
#include "moslam/geometry/so3.h"

namespace moslam {

void AgentOptions::validate() const {
  if (!(gamma > 0.0 && gamma < 2.0)) {
    throw InvalidInputError("DGS: gamma must be in (0, 2) (over-relaxation), got " +
                            std::to_string(gamma));
  }
  if (!(refine_gamma > 0.0 && refine_gamma < 2.0)) {
    throw InvalidInputError("DGS: refine_gamma must be in (0, 2) (over-relaxation), got " +
                            std::to_string(refine_gamma));
  }
}

namespace {

constexpr std::size_t kMaxWindow = 64;  // errorBound(): the longest window of change ratios

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

RobotAgent::RobotAgent(int robot, const PoseGraph& subgraph, const Values& initial,
                       const Key& anchor, const AgentOptions& options)
    : robot_(robot), options_(options), anchor_(anchor) {
  options_.validate();
  std::set<Key> own;
  std::vector<std::pair<Key, Key>> coupled;
  for (const RelativePoseFactor& f : subgraph.factors()) {
    const bool own_a = f.a().robot == robot_;
    const bool own_b = f.b().robot == robot_;
    if (!own_a && !own_b) {
      throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": factor " +
                              ToString(f.a()) + "-" + ToString(f.b()) +
                              " touches none of its variables");
    }
    const std::size_t index = factors_.size();
    factors_.push_back(f);
    if (own_a) own.insert(f.a());
    if (own_b) own.insert(f.b());
    if (own_a && own_b) {
      inner_.push_back(index);
      coupled.emplace_back(f.a(), f.b());
    } else {
      const Key mine = own_a ? f.a() : f.b();
      const Key theirs = own_a ? f.b() : f.a();
      separators_.push_back({index, mine, theirs, theirs.robot});
      neighbour_keys_.insert(theirs);
      auto& shared = shared_with_[theirs.robot];
      shared.push_back(mine);
    }
  }
  for (const PriorFactor& p : subgraph.priors()) {
    if (p.key().robot != robot_) {
      throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": prior on " +
                              ToString(p.key()) + " is another robot's");
    }
    priors_.push_back(p);
    own.insert(p.key());
  }
  if (own.empty()) {
    throw UnderdeterminedError("DGS robot " + std::to_string(robot_) +
                               ": its subgraph touches none of its variables");
  }
  for (auto& [r, keys] : shared_with_) {
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  }
  neighbour_list_.assign(neighbour_keys_.begin(), neighbour_keys_.end());
  for (std::size_t i = 0; i < neighbour_list_.size(); ++i) {
    neighbour_slot_[neighbour_list_[i]] = static_cast<int>(i);
  }
  for (Separator& sep : separators_) sep.slot = neighbour_slot_.at(sep.foreign);
  own_.assign(own.begin(), own.end());
  owns_anchor_ = own.count(anchor_) > 0;
  for (const Key& k : own_) {
    const auto it = initial.find(k);
    initial_[k] = it != initial.end() ? it->second : SE3();
    if (k == anchor_) continue;
    unknown_index_[k] = static_cast<int>(unknowns_.size());
    unknowns_.push_back(k);
  }
  if (owns_anchor_) anchor_pose_ = initial_.at(anchor_);

  // Components of the unknowns through inner edges (the anchor is fixed, so it does not join
  // components: it ties each one it touches).
  const int n = static_cast<int>(unknowns_.size());
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (std::size_t i : inner_) {
    const auto ia = unknown_index_.find(factors_[i].a());
    const auto ib = unknown_index_.find(factors_[i].b());
    if (ia == unknown_index_.end() || ib == unknown_index_.end()) continue;
    parent[Find(parent, ia->second)] = Find(parent, ib->second);
  }
  std::map<int, int> root_to_component;
  component_of_.resize(n);
  for (int i = 0; i < n; ++i) {
    const int root = Find(parent, i);
    const auto [it, inserted] =
        root_to_component.emplace(root, static_cast<int>(root_to_component.size()));
    component_of_[i] = it->second;
  }
  component_fixed_.assign(root_to_component.size(), false);
  component_separators_.assign(root_to_component.size(), {});
  for (std::size_t i : inner_) {
    const Key a = factors_[i].a(), b = factors_[i].b();
    if (a == anchor_ && b != anchor_) component_fixed_[component_of_[unknown_index_.at(b)]] = true;
    if (b == anchor_ && a != anchor_) component_fixed_[component_of_[unknown_index_.at(a)]] = true;
  }
  for (const PriorFactor& p : priors_) {
    const auto it = unknown_index_.find(p.key());
    if (it != unknown_index_.end()) component_fixed_[component_of_[it->second]] = true;
  }
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    const auto it = unknown_index_.find(separators_[s].own);
    if (it != unknown_index_.end()) component_separators_[component_of_[it->second]].push_back(s);
  }

  rotation_problem_ = std::make_unique<BlockLeastSquares>(unknowns_, 3, 3, coupled);
  pose_problem_ = std::make_unique<BlockLeastSquares>(unknowns_, 6, 1, coupled);
}

RobotAgent::~RobotAgent() = default;

std::set<int> RobotAgent::neighbourRobots() const {
  std::set<int> robots;
  for (const Key& k : neighbour_keys_) robots.insert(k.robot);
  return robots;
}

std::map<int, int> RobotAgent::neighbourLinks() const {
  std::map<int, int> links;
  for (const Key& k : neighbour_keys_) ++links[k.robot];
  return links;
}

DgsStage RobotAgent::currentStage() const {
  switch (state_) {
    case AgentState::kRotation:
      return DgsStage::kRotation;
    case AgentState::kPose:
      return DgsStage::kPose;
    case AgentState::kRefine:
      return DgsStage::kRefine;
    default:
      break;
  }
  throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": no stage is running (state " +
                          ToString(state_) + ")");
}

RobotAgent::StageInbox& RobotAgent::inbox(DgsStage stage) {
  StageInbox& box = inboxes_[stage];
  if (box.values.size() != neighbour_list_.size()) {
    box.values.assign(neighbour_list_.size(), Eigen::VectorXd::Zero(StageDimension(stage)));
    box.has.assign(neighbour_list_.size(), 0);
  }
  return box;
}

void RobotAgent::startRotation() {
  requireState(AgentState::kIdle, "startRotation()");
  x_.clear();
  for (const Key& k : unknowns_) x_.push_back(RowMajor(initial_.at(k).rotation().matrix()));
  state_ = AgentState::kRotation;
  prepareStage(DgsStage::kRotation);
  iteration_ = 0;
  resetProgress();
}

void RobotAgent::startPose() {
  requireState(AgentState::kRotation, "startPose()");
  relaxed_ = x_;
  R_hat_.clear();
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    R_hat_[unknowns_[i]] = ProjectToRotation(x_[i]);
  }
  if (owns_anchor_) R_hat_[anchor_] = anchor_pose_.rotation().matrix();
  // Neighbours: the projection of the last rotation estimate received (the same numbers their
  // owner projected, as the owner's final estimate was delivered after its last solve).
  const StageInbox& rot = inbox(DgsStage::kRotation);
  for (std::size_t i = 0; i < neighbour_list_.size(); ++i) {
    const Eigen::VectorXd* v = rot.get(static_cast<int>(i));
    if (v) R_hat_[neighbour_list_[i]] = ProjectToRotation(*v);
  }
  x_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  state_ = AgentState::kPose;
  prepareStage(DgsStage::kPose);
  iteration_ = 0;
  resetProgress();
}

void RobotAgent::finish() {
  requireState(AgentState::kPose, "finish()");
  state_ = AgentState::kDone;
}

ReceiveStatus RobotAgent::receive(const Message& m) {
  if (m.sender == robot_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": message from itself");
  }
  const int dim = StageDimension(m.stage);
  if (m.values.size() != m.keys.size() * static_cast<std::size_t>(dim)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": message from robot " +
                            std::to_string(m.sender) + " has " + std::to_string(m.values.size()) +
                            " values for " + std::to_string(m.keys.size()) + " keys");
  }
  for (const Key& k : m.keys) {
    if (k.robot != m.sender) {
      throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": message from robot " +
                              std::to_string(m.sender) + " carries " + ToString(k) +
                              ", another robot's variable");
    }
  }
  // A message of a stage this agent has left is stale.
  const bool left = (state_ == AgentState::kDone) ||
                    (state_ == AgentState::kPose && m.stage == DgsStage::kRotation) ||
                    (state_ == AgentState::kRefine && m.stage != DgsStage::kRefine);
  StageInbox& box = inbox(m.stage);
  const auto last = box.last_iteration.find(m.sender);
  const std::int64_t last_iteration = last == box.last_iteration.end() ? -1 : last->second;
  if (!left && static_cast<std::int64_t>(m.iteration) == last_iteration) {
    ++duplicates_;
    return ReceiveStatus::kDuplicate;
  }
  if (left || static_cast<std::int64_t>(m.iteration) < last_iteration) {
    ++stale_;
    return ReceiveStatus::kStale;
  }
  box.last_iteration[m.sender] = m.iteration;
  if (m.initialised) box.initialised_robots.insert(m.sender);
  for (std::size_t i = 0; i < m.keys.size(); ++i) {
    const auto slot = neighbour_slot_.find(m.keys[i]);
    if (slot == neighbour_slot_.end()) continue;  // a variable this robot does not need
    const auto j = static_cast<std::size_t>(slot->second);
    box.values[j] = Eigen::Map<const Eigen::VectorXd>(m.entry(i), dim);
    box.has[j] = 1;
  }
  return ReceiveStatus::kAccepted;
}

bool RobotAgent::usable(const Separator& s, DgsStage stage) const {
  if (stage == DgsStage::kRefine) return pose_known_[static_cast<std::size_t>(s.slot)] != 0;
  const auto it = inboxes_.find(stage);
  if (it == inboxes_.end() || it->second.get(s.slot) == nullptr) return false;
  if (options_.flagged_initialisation && it->second.initialised_robots.count(s.foreign_robot) == 0) {
    return false;
  }
  if (stage == DgsStage::kPose && R_hat_.count(s.foreign) == 0) return false;
  return true;
}

Eigen::MatrixXd RobotAgent::neighbourValue(int slot, DgsStage stage) const {
  const auto box = inboxes_.find(stage);
  const Eigen::VectorXd* v = box == inboxes_.end() ? nullptr : box->second.get(slot);
  if (stage == DgsStage::kRefine) {
    // The neighbour's value in this step (increment, or z of conjugate gradients); 0 until it
    // arrives.
    return v ? *v : Eigen::VectorXd(Eigen::VectorXd::Zero(6));
  }
  if (stage == DgsStage::kRotation) return RotationUnknown(FromRowMajor(*v));
  return *v;
}

void RobotAgent::prepareStage(DgsStage stage) {
  if (stage == DgsStage::kRefine) {
    linearizeRefine();
    return;
  }
  const bool rotation = stage == DgsStage::kRotation;
  const bool weighted = options_.weight_by_information;
  if (owns_anchor_) {
    if (rotation) {
      anchor_value_ = RotationUnknown(anchor_pose_.rotation().matrix());
    } else {
      anchor_value_ = Eigen::VectorXd::Zero(6);
      anchor_value_.bottomRows(3) = anchor_pose_.translation();
    }
  }
  terms_.assign(factors_.size(), LinearTerm());
  auto build = [&](std::size_t i) {
    const RelativePoseFactor& f = factors_[i];
    terms_[i] = rotation ? RotationTerm(f, weighted)
                         : PoseTerm(f, R_hat_.at(f.a()), R_hat_.at(f.b()), weighted);
  };
  for (std::size_t i : inner_) build(i);
  coupling_.assign(separators_.size(), Eigen::MatrixXd());
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    const Separator& sep = separators_[s];
    // Stage 2 needs the neighbour's rotation; without one the separator stays unusable.
    if (!rotation && R_hat_.count(sep.foreign) == 0) continue;
    build(sep.factor);
    coupling_[s] = couplingBlock(sep);
  }
  prior_terms_.clear();
  for (const PriorFactor& p : priors_) {
    prior_terms_.push_back(rotation ? RotationPriorTerm(p, weighted)
                                    : PosePriorTerm(p, R_hat_.at(p.key()), weighted));
  }
  cached_use_.clear();
  factorized_ = false;
}

Eigen::MatrixXd RobotAgent::couplingBlock(const Separator& sep) const {
  const LinearTerm& t = terms_[sep.factor];
  const bool own_is_a = factors_[sep.factor].a() == sep.own;
  const Eigen::MatrixXd& A_own = own_is_a ? t.A_a : t.A_b;
  const Eigen::MatrixXd& A_foreign = own_is_a ? t.A_b : t.A_a;
  return A_own.transpose() * t.W * A_foreign;
}

bool RobotAgent::solvable(DgsStage stage, std::vector<bool>& use) const {
  use.assign(separators_.size(), false);
  for (std::size_t s = 0; s < separators_.size(); ++s) use[s] = usable(separators_[s], stage);
  for (std::size_t c = 0; c < component_fixed_.size(); ++c) {
    if (component_fixed_[c]) continue;
    bool reached = false;
    for (std::size_t s : component_separators_[c]) reached = reached || use[s];
    if (!reached) return false;  // some variables are not anchored yet: wait
  }
  return true;
}

void RobotAgent::assemble(DgsStage stage, const std::vector<bool>& use) {
  if (factorized_ && use == cached_use_) return;
  const bool rotation = stage == DgsStage::kRotation;
  BlockLeastSquares& problem = rotation ? *rotation_problem_ : *pose_problem_;
  const Eigen::MatrixXd* anchor = owns_anchor_ ? &anchor_value_ : nullptr;
  auto fixedValue = [&](const Key& k) -> const Eigen::MatrixXd* {
    return k == anchor_ ? anchor : nullptr;
  };
  // Normal matrix and the constant part of the right-hand side (neighbours at zero).
  problem.setZero();
  for (std::size_t i : inner_) {
    const RelativePoseFactor& f = factors_[i];
    if (f.a() == anchor_ && f.b() == anchor_) continue;
    problem.add(terms_[i], fixedValue(f.a()), fixedValue(f.b()));
  }
  const int bs = rotation ? 3 : 6;
  const Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(bs, rotation ? 3 : 1);
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    if (!use[s] || unknown_index_.count(separators_[s].own) == 0) continue;
    const RelativePoseFactor& f = factors_[separators_[s].factor];
    const bool foreign_is_a = f.a() == separators_[s].foreign;
    problem.add(terms_[separators_[s].factor], foreign_is_a ? &zero : nullptr,
                foreign_is_a ? nullptr : &zero);
  }
  for (std::size_t p = 0; p < priors_.size(); ++p) {
    if (priors_[p].key() == anchor_) continue;
    problem.add(prior_terms_[p], nullptr, nullptr);
  }
  if (stage == DgsStage::kRefine && lambda_ > 0.0) {
    // Levenberg-Marquardt damping of the robot's own diagonal blocks: + lambda diag(H_rr).
    LinearTerm damping;
    damping.unary = true;
    damping.C = Eigen::VectorXd::Zero(6);
    damping.W = Eigen::MatrixXd::Identity(6, 6);
    for (std::size_t i = 0; i < unknowns_.size(); ++i) {
      damping.a = unknowns_[i];
      damping.A_a = (lambda_ * hessian_diagonal_[i]).cwiseSqrt().asDiagonal();
      problem.add(damping, nullptr, nullptr);
    }
  }
  problem.factorize();
  G0_ = problem.rhs();
  cached_use_ = use;
  factorized_ = true;
  separator_row_.assign(separators_.size(), -1);
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    const auto it = unknown_index_.find(separators_[s].own);
    if (use[s] && it != unknown_index_.end()) separator_row_[s] = problem.row(it->first);
  }
}

Eigen::MatrixXd RobotAgent::localRhs(DgsStage stage) const {
  // Conjugate gradients: the sweeps apply the preconditioner to the residual.
  Eigen::MatrixXd G = cg_ ? Eigen::MatrixXd(cg_res_) : G0_;
  const auto box = inboxes_.find(stage);
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    if (separator_row_[s] < 0) continue;
    if (stage == DgsStage::kRotation) {
      const Eigen::MatrixXd foreign = neighbourValue(separators_[s].slot, stage);
      G.middleRows(separator_row_[s], 3).noalias() -= coupling_[s] * foreign;
      continue;
    }
    // Stages 2 and refinement: 6 numbers; an increment that has not arrived is 0.
    const Eigen::VectorXd* foreign =
        box == inboxes_.end() ? nullptr : box->second.get(separators_[s].slot);
    if (!foreign) continue;
    G.col(0).segment<6>(separator_row_[s]).noalias() -=
        Matrix6(coupling_[s]) * foreign->head<6>();
  }
  return G;
}

Eigen::MatrixXd RobotAgent::CoarseBasis(DgsStage stage, const Eigen::VectorXd& x,
                                        const Matrix3* R_hat, const Eigen::Vector3d& lever) {
  if (stage == DgsStage::kRotation) return Eigen::Map<const Eigen::Matrix3d>(x.data());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(6, 6);
  P.topLeftCorner<3, 3>() = R_hat->transpose();
  P.bottomLeftCorner<3, 3>() = -SO3::Hat(lever);  // w x d = -d^ w
  P.bottomRightCorner<3, 3>().setIdentity();
  return P;
}

Eigen::MatrixXd RobotAgent::coarseBasisOf(const Key& key, const Eigen::VectorXd& x,
                                          const Eigen::Vector3d& frozen) const {
  if (currentStage() == DgsStage::kRotation) {
    return CoarseBasis(DgsStage::kRotation, x, nullptr, Eigen::Vector3d::Zero());
  }
  return CoarseBasis(DgsStage::kPose, x, &R_hat_.at(key), frozen - coarse_centre_);
}

void RobotAgent::freezeCoarseBasis() {
  if (coarse_frozen_ || currentStage() != DgsStage::kPose) return;
  coarse_ref_.clear();
  coarse_centre_.setZero();
  for (const Eigen::VectorXd& x : x_) {
    coarse_ref_.push_back(x.tail<3>());
    coarse_centre_ += x.tail<3>();
  }
  if (!x_.empty()) coarse_centre_ /= static_cast<double>(x_.size());
  const StageInbox& box = inbox(DgsStage::kPose);
  coarse_ref_copy_.assign(neighbour_list_.size(), Eigen::Vector3d::Zero());
  for (std::size_t j = 0; j < neighbour_list_.size(); ++j) {
    if (box.has[j]) coarse_ref_copy_[j] = box.values[j].tail<3>();
  }
  coarse_frozen_ = true;
}

bool RobotAgent::coarseReady(const std::set<int>& absent) const {
  if ((state_ != AgentState::kRotation && state_ != AgentState::kPose) || !initialised_ ||
      !factorized_ || cg_ || cached_use_.size() != separators_.size()) {
    return false;
  }
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    if (!cached_use_[s] && absent.count(separators_[s].foreign_robot) == 0) return false;
  }
  return true;
}

CoarseShare RobotAgent::coarseShare() {
  if ((state_ != AgentState::kRotation && state_ != AgentState::kPose) || !factorized_ || cg_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": coarseShare() before a solve of stage 1 or 2 (state " +
                            ToString(state_) + ")");
  }
  const DgsStage stage = currentStage();
  const bool rotation = stage == DgsStage::kRotation;
  const BlockLeastSquares& problem = rotation ? *rotation_problem_ : *pose_problem_;
  const int bs = rotation ? 3 : 6, k = rotation ? 3 : 6, ncols = rotation ? 3 : 1;
  const Eigen::Index n = static_cast<Eigen::Index>(unknowns_.size()) * bs;
  freezeCoarseBasis();
  CoarseShare share;
  share.center = rotation ? Eigen::Vector3d::Zero() : coarse_centre_;
  // P (n x k) and x (n x ncols), stacked in the problem's order.
  Eigen::MatrixXd P(n, k), X(n, ncols);
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();  // stage 1 has no lever arms
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    const Eigen::Index row = problem.row(unknowns_[i]);
    P.middleRows(row, bs) = coarseBasisOf(unknowns_[i], x_[i], rotation ? none : coarse_ref_[i]);
    X.middleRows(row, bs) = Eigen::Map<const Eigen::MatrixXd>(x_[i].data(), bs, ncols);
  }
  Eigen::MatrixXd HP(n, k);
  for (int c = 0; c < k; ++c) HP.col(c) = problem.multiply(P.col(c));
  share.diagonal = P.transpose() * HP;
  Eigen::MatrixXd residual = localRhs(stage);
  for (int c = 0; c < ncols; ++c) residual.col(c) -= problem.multiply(X.col(c));
  share.residual = P.transpose() * residual;
  const auto box = inboxes_.find(stage);
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    if (separator_row_[s] < 0) continue;
    const Separator& sep = separators_[s];
    if (sep.foreign == anchor_) continue;  // fixed: not in its owner's coarse space
    const Eigen::VectorXd* foreign = box->second.get(sep.slot);
    if (!foreign) continue;  // stage 2: no increment yet, P_j unknown (and the coupling unused)
    const Eigen::Vector3d& frozen =
        rotation ? none : coarse_ref_copy_[static_cast<std::size_t>(sep.slot)];
    const Eigen::MatrixXd block = P.middleRows(separator_row_[s], bs).transpose() *
                                  coupling_[s] * coarseBasisOf(sep.foreign, *foreign, frozen);
    auto [it, inserted] = share.coupling.try_emplace(sep.foreign_robot, block);
    if (!inserted) it->second += block;
  }
  return share;
}

void RobotAgent::applyCoarse(const std::map<int, Eigen::MatrixXd>& y) {
  if (state_ != AgentState::kRotation && state_ != AgentState::kPose) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": applyCoarse() in state " +
                            ToString(state_));
  }
  const DgsStage stage = currentStage();
  const bool rotation = stage == DgsStage::kRotation;
  const int bs = rotation ? 3 : 6, ncols = rotation ? 3 : 1;
  if (!rotation && !coarse_frozen_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": applyCoarse() in stage 2 before coarseShare()");
  }
  auto apply = [&](const Key& key, Eigen::VectorXd& x, const Eigen::MatrixXd& yr,
                   const Eigen::Vector3d& frozen) {
    const Eigen::MatrixXd dx = coarseBasisOf(key, x, frozen) * yr;
    x += Eigen::Map<const Eigen::VectorXd>(dx.data(), bs * ncols);
  };
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();  // stage 1 has no lever arms
  const auto own = y.find(robot_);
  if (own != y.end()) {
    if (before_coarse_.empty()) before_coarse_ = x_;
    for (std::size_t i = 0; i < unknowns_.size(); ++i) {
      apply(unknowns_[i], x_[i], own->second, rotation ? none : coarse_ref_[i]);
    }
  }
  StageInbox& box = inbox(stage);
  for (std::size_t j = 0; j < neighbour_list_.size(); ++j) {
    const Key& key = neighbour_list_[j];
    const auto it = y.find(key.robot);
    if (it == y.end() || !box.has[j] || key == anchor_) continue;  // the anchor never moves
    if (!rotation && R_hat_.count(key) == 0) continue;
    apply(key, box.values[j], it->second, rotation ? none : coarse_ref_copy_[j]);
  }
}

bool RobotAgent::iterate() {
  const DgsStage stage = currentStage();
  if (stage == DgsStage::kRefine && !linearized_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": iterate() in the refinement before beginStep()");
  }
  std::vector<bool> use;
  if (!solvable(stage, use)) return false;
  assemble(stage, use);
  const bool rotation = stage == DgsStage::kRotation;
  BlockLeastSquares& problem = rotation ? *rotation_problem_ : *pose_problem_;

  const std::vector<Eigen::MatrixXd> solution = problem.backSolve(localRhs(stage));

  const double gamma = stage == DgsStage::kRefine ? options_.refine_gamma : options_.gamma;
  double change2 = 0.0;
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    // Stage 1: X = R^T, whose column-major flattening is r (row by row).
    const Eigen::VectorXd x_new =
        Eigen::Map<const Eigen::VectorXd>(solution[i].data(), solution[i].size());
    // Two-level: the change of the iteration includes the coarse correction since the last solve.
    const Eigen::VectorXd& x_old = before_coarse_.empty() ? x_[i] : before_coarse_[i];
    change2 += (x_new - x_old).squaredNorm();
    x_[i] = (1.0 - gamma) * x_[i] + gamma * x_new;
  }
  last_change_ = std::sqrt(change2);
  before_coarse_.clear();
  // A solve that changes nothing (no new neighbour value since the last one: Jacobi on two
  // robots alternates) is not a step of the contraction: it is left out of the ratios.
  if (last_change_ == 0.0) {
    ++zero_changes_;
  } else {
    zero_changes_ = 0;
    if (recent_changes_.size() == kMaxWindow + 2) recent_changes_.erase(recent_changes_.begin());
    recent_changes_.push_back(last_change_);
  }
  ++iteration_;
  initialised_ = true;
  return true;
}

std::vector<OutgoingMessage> RobotAgent::outgoing() const {
  std::vector<OutgoingMessage> out;
  if (state_ != AgentState::kRotation && state_ != AgentState::kPose &&
      state_ != AgentState::kRefine) {
    return out;
  }
  const DgsStage stage = currentStage();
  const int dim = StageDimension(stage);
  for (const auto& [to, keys] : shared_with_) {
    OutgoingMessage o;
    o.to = to;
    Message& m = o.message;
    m.stage = stage;
    m.iteration = static_cast<std::uint32_t>(iteration_);
    m.sender = robot_;
    m.initialised = initialised_;
    m.keys = keys;
    m.values.reserve(keys.size() * static_cast<std::size_t>(dim));
    for (const Key& k : keys) {
      Eigen::VectorXd v;
      const auto it = unknown_index_.find(k);
      if (it != unknown_index_.end()) {
        v = x_[it->second];
      } else if (stage == DgsStage::kRotation) {  // the anchor
        v = RowMajor(anchor_pose_.rotation().matrix());
      } else if (stage == DgsStage::kRefine) {  // the anchor: never moves
        v = Eigen::VectorXd::Zero(6);
      } else {
        v = Eigen::VectorXd::Zero(6);
        v.tail<3>() = anchor_pose_.translation();
      }
      m.values.insert(m.values.end(), v.data(), v.data() + v.size());
    }
    out.push_back(std::move(o));
  }
  return out;
}

Values RobotAgent::estimate() const {
  if (refined_) return pose_;
  Values values;
  for (const Key& k : own_) {
    const auto it = unknown_index_.find(k);
    if (it == unknown_index_.end() || state_ == AgentState::kIdle) {
      values[k] = initial_.at(k);  // the anchor, or nothing estimated yet
      continue;
    }
    const Eigen::VectorXd& x = x_[it->second];
    if (state_ == AgentState::kRotation) {
      values[k] = SE3(SO3(ProjectToRotation(x)), Vector3::Zero());
    } else {
      const SO3 R = SO3(R_hat_.at(k)) * SO3::Exp(x.head<3>());
      values[k] = SE3(R, x.tail<3>());
    }
  }
  return values;
}

void RobotAgent::requireRefine(const char* what) const {
  requireState(AgentState::kRefine, what, " (only during the refinement)");
}

void RobotAgent::requireState(AgentState expected, const char* what, const char* hint) const {
  if (state_ != expected) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": " + what + " in state " +
                            ToString(state_) + hint);
  }
}

double RobotAgent::errorBound(int window) const {
  if (window < 1 || window > static_cast<int>(kMaxWindow)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": error-bound window must be in [1, " + std::to_string(kMaxWindow) +
                            "], got " + std::to_string(window));
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Stationary: the last window + 2 solves changed nothing.
  if (zero_changes_ >= window + 2) return 0.0;
  const std::size_t n = recent_changes_.size();
  if (n < static_cast<std::size_t>(window) + 2) return kInf;
  // Two-solve ratios: Jacobi sweeps alternate between modes of eigenvalues +mu and -mu, so the
  // change oscillates from solve to solve while c_k / c_{k-2} = mu^2 (Gauss-Seidel is monotone).
  double rho = 0.0;
  for (std::size_t k = n - static_cast<std::size_t>(window); k < n; ++k) {
    rho = std::max(rho, std::sqrt(recent_changes_[k] / recent_changes_[k - 2]));
  }
  if (!(rho < 1.0)) return kInf;
  const double gamma = state_ == AgentState::kRefine ? options_.refine_gamma : options_.gamma;
  return gamma * recent_changes_.back() * rho / (1.0 - rho);
}

void RobotAgent::resetProgress() {
  initialised_ = false;
  last_change_ = std::numeric_limits<double>::infinity();
  recent_changes_.clear();
  zero_changes_ = 0;
  before_coarse_.clear();
  coarse_frozen_ = false;
}

void RobotAgent::startRefine() {
  if (state_ != AgentState::kDone || refined_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) + ": startRefine() in state " +
                            ToString(state_) +
                            (refined_ ? " (the refinement runs once)" : "") +
                            "; it follows the pose stage");
  }
  pose_ = estimate();
  // The neighbours' two-stage estimates, exactly as their owners form them: R_hat (the projected
  // stage-1 rotation received) and the last stage-2 increment (dtheta, t) received.
  neighbour_pose_.assign(neighbour_list_.size(), SE3());
  pose_known_.assign(neighbour_list_.size(), 0);
  const auto box = inboxes_.find(DgsStage::kPose);
  for (std::size_t i = 0; i < neighbour_list_.size(); ++i) {
    const auto R = R_hat_.find(neighbour_list_[i]);
    if (R == R_hat_.end() || box == inboxes_.end()) continue;
    const Eigen::VectorXd* x = box->second.get(static_cast<int>(i));
    if (!x) continue;
    neighbour_pose_[i] = SE3(SO3(R->second) * SO3::Exp(x->head<3>()), x->tail<3>());
    pose_known_[i] = 1;
  }
  refined_ = true;
  linearized_ = false;
  lambda_ = 0.0;
  state_ = AgentState::kRefine;
  x_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  iteration_ = 0;
  resetProgress();
}

const SE3* RobotAgent::knownPose(const Key& key) const {
  const auto own = pose_.find(key);
  if (own != pose_.end()) return &own->second;
  const auto it = neighbour_slot_.find(key);
  if (it == neighbour_slot_.end()) return nullptr;
  const auto i = static_cast<std::size_t>(it->second);
  return pose_known_[i] ? &neighbour_pose_[i] : nullptr;
}

void RobotAgent::linearizeRefine() {
  anchor_value_ = Eigen::VectorXd::Zero(6);  // the anchor's increment
  terms_.assign(factors_.size(), LinearTerm());
  hessian_diagonal_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  auto accumulateDiagonal = [&](const Key& k, const Eigen::MatrixXd& A, const Eigen::MatrixXd& W) {
    const auto it = unknown_index_.find(k);
    if (it == unknown_index_.end()) return;
    hessian_diagonal_[static_cast<std::size_t>(it->second)] +=
        (A.transpose() * W * A).diagonal();
  };
  auto build = [&](std::size_t i) {
    const RelativePoseFactor& f = factors_[i];
    Matrix6 Ha, Hb;
    const Vector6 r = f.residual(*knownPose(f.a()), *knownPose(f.b()), &Ha, &Hb);
    LinearTerm& t = terms_[i];
    t.a = f.a();
    t.b = f.b();
    t.A_a = Ha;
    t.A_b = Hb;
    t.C = r;
    t.W = f.information();
    accumulateDiagonal(f.a(), t.A_a, t.W);
    if (f.b() != f.a()) accumulateDiagonal(f.b(), t.A_b, t.W);
  };
  for (std::size_t i : inner_) build(i);
  coupling_.assign(separators_.size(), Eigen::MatrixXd());
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    const Separator& sep = separators_[s];
    if (!pose_known_[static_cast<std::size_t>(sep.slot)]) continue;  // never received: left out
    build(sep.factor);
    coupling_[s] = couplingBlock(sep);
  }
  prior_terms_.clear();
  for (const PriorFactor& p : priors_) {
    Matrix6 H;
    const Vector6 r = p.residual(pose_.at(p.key()), &H);
    LinearTerm t;
    t.a = p.key();
    t.unary = true;
    t.A_a = H;
    t.C = r;
    t.W = p.information();
    accumulateDiagonal(p.key(), t.A_a, t.W);
    prior_terms_.push_back(std::move(t));
  }
  cached_use_.clear();
  factorized_ = false;
  linearized_ = true;
}

void RobotAgent::beginStep(double lambda) {
  requireRefine("beginStep()");
  if (!(lambda >= 0.0) || !std::isfinite(lambda)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": damping lambda must be finite and >= 0, got " +
                            std::to_string(lambda));
  }
  if (!linearized_) prepareStage(DgsStage::kRefine);
  if (lambda != lambda_) factorized_ = false;
  lambda_ = lambda;
  cg_ = false;
  can_solve_ = true;
  x_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  inbox(DgsStage::kRefine).forget();  // the neighbours' increments of an earlier step
  resetProgress();
}

Vector6 RobotAgent::ownIncrement(std::size_t i) const {
  if (cg_) return cg_delta_.segment<6>(static_cast<Eigen::Index>(6 * i));
  return x_[i];
}

Vector6 RobotAgent::neighbourIncrement(int slot) const {
  if (cg_) return neighbour_delta_[static_cast<std::size_t>(slot)];
  return neighbourValue(slot, DgsStage::kRefine);
}

Eigen::VectorXd RobotAgent::stackedSweepValue() const {
  Eigen::VectorXd z(static_cast<Eigen::Index>(6 * unknowns_.size()));
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    z.segment<6>(static_cast<Eigen::Index>(6 * i)) = x_[i];
  }
  return z;
}

void RobotAgent::acceptStep() {
  requireRefine("acceptStep()");
  for (std::size_t i = 0; i < unknowns_.size(); ++i) {
    SE3& x = pose_.at(unknowns_[i]);
    x = x * SE3::Exp(ownIncrement(i));
  }
  for (std::size_t i = 0; i < neighbour_pose_.size(); ++i) {
    if (!pose_known_[i]) continue;
    neighbour_pose_[i] = neighbour_pose_[i] * SE3::Exp(neighbourIncrement(static_cast<int>(i)));
  }
  x_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  inbox(DgsStage::kRefine).forget();
  cg_ = false;
  linearized_ = false;
}

void RobotAgent::startPreconditioner() {
  requireRefine("startPreconditioner()");
  if (!linearized_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": startPreconditioner() before beginStep()");
  }
  const Eigen::Index n = static_cast<Eigen::Index>(6 * unknowns_.size());
  if (!cg_) {
    std::vector<bool> use;
    can_solve_ = solvable(DgsStage::kRefine, use);
    if (can_solve_) assemble(DgsStage::kRefine, use);
    cg_ = true;
    cg_delta_ = Eigen::VectorXd::Zero(n);
    cg_res_ = can_solve_ ? Eigen::VectorXd(G0_.col(0)) : Eigen::VectorXd(Eigen::VectorXd::Zero(n));
    cg_p_ = Eigen::VectorXd::Zero(n);
    cg_q_ = Eigen::VectorXd::Zero(n);
    neighbour_p_.assign(neighbour_list_.size(), Vector6::Zero());
    neighbour_delta_.assign(neighbour_list_.size(), Vector6::Zero());
  }
  x_.assign(unknowns_.size(), Eigen::VectorXd::Zero(6));
  inbox(DgsStage::kRefine).forget();
  resetProgress();
}

double RobotAgent::residualDot() const {
  requireRefine("residualDot()");
  if (!cg_) return 0.0;
  return cg_res_.dot(stackedSweepValue());
}

void RobotAgent::firstDirection() { nextDirection(0.0); }

void RobotAgent::nextDirection(double beta) {
  requireRefine("nextDirection()");
  if (!cg_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot_) +
                            ": a search direction before startPreconditioner()");
  }
  cg_p_ = stackedSweepValue() + beta * cg_p_;
  const StageInbox& box = inbox(DgsStage::kRefine);
  for (std::size_t i = 0; i < neighbour_p_.size(); ++i) {
    const Eigen::VectorXd* z = box.get(static_cast<int>(i));
    neighbour_p_[i] = beta * neighbour_p_[i];
    if (z) neighbour_p_[i] += z->head<6>();
  }
}

double RobotAgent::curvature() {
  requireRefine("curvature()");
  if (!cg_ || !can_solve_) {
    if (cg_) cg_q_.setZero();
    return 0.0;
  }
  cg_q_ = pose_problem_->multiply(cg_p_);
  for (std::size_t s = 0; s < separators_.size(); ++s) {
    if (separator_row_[s] < 0) continue;
    cg_q_.segment<6>(separator_row_[s]).noalias() +=
        Matrix6(coupling_[s]) * neighbour_p_[static_cast<std::size_t>(separators_[s].slot)];
  }
  return cg_p_.dot(cg_q_);
}

void RobotAgent::advance(double alpha) {
  requireRefine("advance()");
  if (!cg_) return;
  cg_delta_ += alpha * cg_p_;
  cg_res_ -= alpha * cg_q_;
  for (std::size_t i = 0; i < neighbour_p_.size(); ++i) neighbour_delta_[i] += alpha * neighbour_p_[i];
}

void RobotAgent::finishRefine() {
  requireRefine("finishRefine()");
  state_ = AgentState::kDone;
}

double RobotAgent::costShare(bool candidate) const {
  requireRefine("costShare()");
  auto value = [&](const Key& k) {
    const SE3& x = *knownPose(k);
    if (!candidate) return x;
    const auto own = unknown_index_.find(k);
    if (own != unknown_index_.end()) {
      return SE3(x * SE3::Exp(ownIncrement(static_cast<std::size_t>(own->second))));
    }
    const auto slot = neighbour_slot_.find(k);
    if (slot != neighbour_slot_.end()) return SE3(x * SE3::Exp(neighbourIncrement(slot->second)));
    return x;  // the anchor
  };
  double cost = 0.0;
  for (std::size_t i : inner_) {
    const RelativePoseFactor& f = factors_[i];
    cost += f.cost(value(f.a()), value(f.b()));
  }
  for (const Separator& s : separators_) {
    if (!pose_known_[static_cast<std::size_t>(s.slot)]) continue;
    if (s.foreign_robot < robot_ && unresponsive_.count(s.foreign_robot) == 0) continue;
    const RelativePoseFactor& f = factors_[s.factor];
    cost += f.cost(value(f.a()), value(f.b()));
  }
  for (const PriorFactor& p : priors_) cost += p.cost(value(p.key()));
  return cost;
}

double RobotAgent::incrementNorm() const {
  if (state_ != AgentState::kRefine) return 0.0;
  if (cg_) return cg_delta_.norm();
  double n2 = 0.0;
  for (const Eigen::VectorXd& x : x_) n2 += x.squaredNorm();
  return std::sqrt(n2);
}

void RobotAgent::setUnresponsive(int robot) { unresponsive_.insert(robot); }

std::map<Key, Eigen::VectorXd> RobotAgent::relaxedRotations() const {
  std::map<Key, Eigen::VectorXd> out;
  const std::vector<Eigen::VectorXd>& r = state_ == AgentState::kRotation ? x_ : relaxed_;
  for (std::size_t i = 0; i < unknowns_.size() && i < r.size(); ++i) out[unknowns_[i]] = r[i];
  if (owns_anchor_) out[anchor_] = RowMajor(anchor_pose_.rotation().matrix());
  return out;
}

}  // namespace moslam
