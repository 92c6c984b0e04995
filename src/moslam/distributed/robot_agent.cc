#include "moslam/distributed/robot_agent.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
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

const AgentOptions& Validated(const AgentOptions& options) {
  options.validate();
  return options;
}

}  // namespace

RobotAgent::RobotAgent(int robot, const PoseGraph& subgraph, const Values& initial,
                       const Key& anchor, const AgentOptions& options)
    : options_(Validated(options)),
      graph_(robot, subgraph, initial, anchor),
      inbox_(graph_),
      rotation_(graph_, 3, 3),
      pose_(graph_, 6, 1),
      coarse_(graph_),
      refinement_(graph_) {}

RobotAgent::~RobotAgent() = default;

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
  throw InvalidInputError("DGS robot " + std::to_string(robot()) + ": no stage is running (state " +
                          ToString(state_) + ")");
}

void RobotAgent::startRotation() {
  requireState(AgentState::kIdle, "startRotation()");
  x_.clear();
  for (const Key& k : graph_.unknowns()) x_.push_back(RowMajor(graph_.initial(k).rotation().matrix()));
  solved_.assign(x_.size(), false);
  state_ = AgentState::kRotation;
  prepareStage(DgsStage::kRotation);
  iteration_ = 0;
  resetProgress();
}

void RobotAgent::startPose() {
  requireState(AgentState::kRotation, "startPose()");
  relaxed_ = x_;
  R_hat_.clear();
  const auto& unknowns = graph_.unknowns();
  for (std::size_t i = 0; i < unknowns.size(); ++i) R_hat_[unknowns[i]] = ProjectToRotation(x_[i]);
  if (graph_.ownsAnchor()) R_hat_[graph_.anchor()] = graph_.initial(graph_.anchor()).rotation().matrix();
  // Neighbours: the projection of the last rotation estimate received (the same numbers their
  // owner projected, as the owner's final estimate was delivered after its last solve).
  const auto& neighbours = graph_.neighbours();
  for (std::size_t i = 0; i < neighbours.size(); ++i) {
    const Eigen::VectorXd* v = inbox_.get(DgsStage::kRotation, static_cast<int>(i));
    if (v) R_hat_[neighbours[i]] = ProjectToRotation(*v);
  }
  x_.assign(unknowns.size(), Eigen::VectorXd::Zero(6));
  solved_.assign(x_.size(), false);
  state_ = AgentState::kPose;
  prepareStage(DgsStage::kPose);
  iteration_ = 0;
  resetProgress();
}

void RobotAgent::finish() {
  requireState(AgentState::kPose, "finish()");
  if (cg_active_) {
    // Conjugate gradients solved the stage: x = the starting values + delta, and the
    // neighbours' values likewise from their copies, for the refinement's start.
    for (std::size_t i = 0; i < x_.size(); ++i) x_[i] = own_start_[i] + cg_.increment(i);
    for (std::size_t j = 0; j < pose_start_.size(); ++j) {
      inbox_.set(DgsStage::kPose, static_cast<int>(j),
                 pose_start_[j] + Eigen::VectorXd(cg_.neighbourIncrement(static_cast<int>(j))));
    }
    cg_active_ = false;
  }
  state_ = AgentState::kDone;
}

ReceiveStatus RobotAgent::receive(const Message& m) {
  // A message of a stage this agent has left is stale.
  const bool left = (state_ == AgentState::kDone) ||
                    (state_ == AgentState::kPose && m.stage == DgsStage::kRotation) ||
                    (state_ == AgentState::kRefine && m.stage != DgsStage::kRefine);
  return inbox_.receive(m, left);
}

bool RobotAgent::usable(const Separator& s, DgsStage stage) const {
  if (stage == DgsStage::kRefine) return refinement_.knows(s.slot);
  // Conjugate gradients in the pose stage: every separator whose term is built (the neighbour's
  // rotation is known) takes part from the start; the values are the CG vectors.
  if (stage == DgsStage::kPose && cg_active_) return pose_.built(s.factor);
  if (inbox_.get(stage, s.slot) == nullptr) return false;
  if (options_.flagged_initialisation && !inbox_.initialisedSlot(stage, s.slot)) return false;
  if (stage == DgsStage::kPose && R_hat_.count(s.foreign) == 0) return false;
  return true;
}

void RobotAgent::prepareStage(DgsStage stage) {
  const bool rotation = stage == DgsStage::kRotation;
  const bool weighted = options_.weight_by_information;
  Eigen::MatrixXd anchor_value;
  if (graph_.ownsAnchor()) {
    const SE3& anchor = graph_.initial(graph_.anchor());
    if (rotation) {
      anchor_value = RotationUnknown(anchor.rotation().matrix());
    } else {
      anchor_value = Eigen::VectorXd::Zero(6);
      anchor_value.bottomRows(3) = anchor.translation();
    }
  }
  const auto& factors = graph_.factors();
  std::vector<LinearTerm> terms(factors.size());
  std::vector<bool> built(factors.size(), false);
  auto build = [&](std::size_t i) {
    const RelativePoseFactor& f = factors[i];
    terms[i] = rotation ? RotationTerm(f, weighted)
                        : PoseTerm(f, R_hat_.at(f.a()), R_hat_.at(f.b()), weighted);
    built[i] = true;
  };
  for (std::size_t i : graph_.inner()) build(i);
  for (const Separator& sep : graph_.separators()) {
    // Stage 2 needs the neighbour's rotation; without one the separator stays unusable.
    if (!rotation && R_hat_.count(sep.foreign) == 0) continue;
    build(sep.factor);
  }
  std::vector<LinearTerm> prior_terms;
  for (const PriorFactor& p : graph_.priors()) {
    prior_terms.push_back(rotation ? RotationPriorTerm(p, weighted)
                                   : PosePriorTerm(p, R_hat_.at(p.key()), weighted));
  }
  system(stage).setTerms(std::move(terms), std::move(built), std::move(prior_terms),
                         std::move(anchor_value));
}

bool RobotAgent::solvable(DgsStage stage, std::vector<bool>& use, std::vector<bool>* held) const {
  const auto& separators = graph_.separators();
  use.assign(separators.size(), false);
  for (std::size_t s = 0; s < separators.size(); ++s) use[s] = usable(separators[s], stage);
  if (held) held->clear();
  const std::vector<bool> anchored = graph_.anchoredUnknowns(use);
  if (std::all_of(anchored.begin(), anchored.end(), [](bool a) { return a; })) return true;
  if (!held) return false;  // some variables are not anchored yet: wait
  if (std::none_of(anchored.begin(), anchored.end(), [](bool a) { return a; })) return false;
  held->resize(anchored.size());
  for (std::size_t i = 0; i < anchored.size(); ++i) (*held)[i] = !anchored[i];
  return true;
}

Eigen::MatrixXd RobotAgent::localRhs(DgsStage stage) const {
  // Conjugate gradients: the sweeps apply the preconditioner to the residual.
  return subtractCouplings(stage, cg_active_ ? Eigen::MatrixXd(cg_.residual())
                                             : system(stage).constantRhs());
}

Eigen::MatrixXd RobotAgent::subtractCouplings(DgsStage stage, Eigen::MatrixXd G) const {
  const LocalSystem& sys = system(stage);
  const auto& separators = graph_.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    const Eigen::Index row = sys.separatorRow(s);
    if (row < 0) continue;
    const Eigen::VectorXd* foreign = inbox_.get(stage, separators[s].slot);
    if (stage == DgsStage::kRotation) {
      G.middleRows(row, 3).noalias() -= sys.coupling(s) * RotationUnknown(FromRowMajor(*foreign));
      continue;
    }
    // Stages 2 and refinement: 6 numbers; an increment that has not arrived is 0.
    if (!foreign) continue;
    G.col(0).segment<6>(row).noalias() -= Matrix6(sys.coupling(s)) * foreign->head<6>();
  }
  return G;
}

bool RobotAgent::coarseReady(const std::set<int>& absent) const {
  if (state_ != AgentState::kRotation && state_ != AgentState::kPose) return false;
  const LocalSystem& sys = system(currentStage());
  if (!progress_.initialised() || !sys.factorized() || cg_active_ ||
      sys.use().size() != graph_.separators().size()) {
    return false;
  }
  const auto& separators = graph_.separators();
  for (std::size_t s = 0; s < separators.size(); ++s) {
    if (!sys.use()[s] && absent.count(separators[s].foreign_robot) == 0) return false;
  }
  return true;
}

CoarseShare RobotAgent::coarseShare() {
  if ((state_ != AgentState::kRotation && state_ != AgentState::kPose) ||
      !system(currentStage()).factorized() || cg_active_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": coarseShare() before a solve of stage 1 or 2 (state " +
                            ToString(state_) + ")");
  }
  const DgsStage stage = currentStage();
  return coarse_.share(stage, x_, localRhs(stage), system(stage), inbox_, R_hat_);
}

void RobotAgent::applyCoarse(const std::map<int, Eigen::MatrixXd>& y) {
  if (state_ != AgentState::kRotation && state_ != AgentState::kPose) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) + ": applyCoarse() in state " +
                            ToString(state_));
  }
  const DgsStage stage = currentStage();
  if (stage == DgsStage::kPose && !coarse_.frozen()) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": applyCoarse() in stage 2 before coarseShare()");
  }
  if (y.count(robot()) && before_coarse_.empty()) before_coarse_ = x_;
  coarse_.apply(stage, y, x_, inbox_, R_hat_);
}

bool RobotAgent::iterate() {
  const DgsStage stage = currentStage();
  if (stage == DgsStage::kRefine && !linearized_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": iterate() in the refinement before beginStep()");
  }
  std::vector<bool> use, held;
  const bool by_groups = solvesByGroups(stage);
  if (!solvable(stage, use, by_groups ? &held : nullptr)) return false;
  LocalSystem& sys = system(stage);
  sys.assemble(use, held);
  const std::vector<Eigen::MatrixXd> solution = sys.solve(localRhs(stage));

  const double gamma = stage == DgsStage::kRefine ? options_.refine_gamma : options_.gamma;
  double change2 = 0.0;
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (!held.empty() && held[i]) continue;  // not tied down yet: keeps its value, unsent
    if (by_groups) solved_[i] = true;
    // Stage 1: X = R^T, whose column-major flattening is r (row by row).
    const Eigen::VectorXd x_new =
        Eigen::Map<const Eigen::VectorXd>(solution[i].data(), solution[i].size());
    // Two-level: the change of the iteration includes the coarse correction since the last solve.
    const Eigen::VectorXd& x_old = before_coarse_.empty() ? x_[i] : before_coarse_[i];
    change2 += (x_new - x_old).squaredNorm();
    x_[i] = (1.0 - gamma) * x_[i] + gamma * x_new;
  }
  before_coarse_.clear();
  // Some groups still wait: not converged, whatever the solved ones did.
  progress_.record(held.empty() ? std::sqrt(change2) : std::numeric_limits<double>::infinity());
  ++iteration_;
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
  // After its first solve of stage 1 or 2, the variables it has solved (flagged initialisation).
  const bool only_solved = solvesByGroups(stage) && progress_.initialised();
  for (const auto& [to, shared] : graph_.sharedWith()) {
    OutgoingMessage o;
    o.to = to;
    Message& m = o.message;
    m.stage = stage;
    m.iteration = static_cast<std::uint32_t>(iteration_);
    m.sender = robot();
    m.initialised = progress_.initialised();
    for (const Key& k : shared) {
      const int i = graph_.unknownIndex(k);
      if (!only_solved || i < 0 || solved_[static_cast<std::size_t>(i)]) m.keys.push_back(k);
    }
    m.values.reserve(m.keys.size() * static_cast<std::size_t>(dim));
    for (const Key& k : m.keys) {
      Eigen::VectorXd v;
      const int i = graph_.unknownIndex(k);
      if (i >= 0) {
        v = x_[static_cast<std::size_t>(i)];
      } else if (stage == DgsStage::kRotation) {  // the anchor
        v = RowMajor(graph_.initial(k).rotation().matrix());
      } else if (stage == DgsStage::kRefine || cg_active_) {  // the anchor: never moves
        v = Eigen::VectorXd::Zero(6);
      } else {
        v = Eigen::VectorXd::Zero(6);
        v.tail<3>() = graph_.initial(k).translation();
      }
      m.values.insert(m.values.end(), v.data(), v.data() + v.size());
    }
    out.push_back(std::move(o));
  }
  return out;
}

Values RobotAgent::neighbourEstimates() const {
  Values out;
  if (!refinement_.started()) return out;
  for (const Key& k : graph_.neighbourKeys()) {
    if (const SE3* x = refinement_.knownPose(k)) out.emplace(k, *x);
  }
  return out;
}

Values RobotAgent::estimate() const {
  if (refinement_.started()) return refinement_.estimate();
  Values values;
  for (const Key& k : graph_.own()) {
    const int i = graph_.unknownIndex(k);
    if (i < 0 || state_ == AgentState::kIdle) {
      values[k] = graph_.initial(k);  // the anchor, or nothing estimated yet
      continue;
    }
    const Eigen::VectorXd x = state_ == AgentState::kPose && cg_active_
                                  ? Eigen::VectorXd(cg_.increment(static_cast<std::size_t>(i)))
                                  : x_[static_cast<std::size_t>(i)];
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
    throw InvalidInputError("DGS robot " + std::to_string(robot()) + ": " + what + " in state " +
                            ToString(state_) + hint);
  }
}

double RobotAgent::errorBound(int window) const {
  if (window < 1 || window > SweepProgress::kMaxWindow) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": error-bound window must be in [1, " +
                            std::to_string(SweepProgress::kMaxWindow) + "], got " +
                            std::to_string(window));
  }
  const double gamma = state_ == AgentState::kRefine ? options_.refine_gamma : options_.gamma;
  return progress_.errorBound(window, gamma);
}

void RobotAgent::resetProgress() {
  progress_.reset();
  before_coarse_.clear();
  coarse_.reset();
}

void RobotAgent::startRefine() {
  if (state_ != AgentState::kDone || refinement_.started()) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) + ": startRefine() in state " +
                            ToString(state_) +
                            (refinement_.started() ? " (the refinement runs once)" : "") +
                            "; it follows the pose stage");
  }
  // The neighbours' two-stage estimates, exactly as their owners form them: R_hat (the projected
  // stage-1 rotation received) and the last stage-2 increment (dtheta, t) received.
  const auto& neighbours = graph_.neighbours();
  std::vector<SE3> poses(neighbours.size());
  std::vector<const SE3*> known(neighbours.size(), nullptr);
  for (std::size_t i = 0; i < neighbours.size(); ++i) {
    const auto R = R_hat_.find(neighbours[i]);
    const Eigen::VectorXd* x = inbox_.get(DgsStage::kPose, static_cast<int>(i));
    if (R == R_hat_.end() || !x) continue;
    poses[i] = SE3(SO3(R->second) * SO3::Exp(x->head<3>()), x->tail<3>());
    known[i] = &poses[i];
  }
  refinement_.start(estimate(), known);
  linearized_ = false;
  lambda_ = 0.0;
  state_ = AgentState::kRefine;
  x_.assign(graph_.unknowns().size(), Eigen::VectorXd::Zero(6));
  iteration_ = 0;
  resetProgress();
}

void RobotAgent::beginStep(double lambda) {
  requireRefine("beginStep()");
  if (!(lambda >= 0.0) || !std::isfinite(lambda)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": damping lambda must be finite and >= 0, got " +
                            std::to_string(lambda));
  }
  if (!linearized_) {
    refinement_.linearize(pose_);
    linearized_ = true;
  }
  lambda_ = lambda;
  step_scale_ = 1.0;
  pose_.setDamping(lambda, refinement_.hessianDiagonal());
  cg_active_ = false;
  refine_coarse_built_ = false;
  can_solve_ = true;
  x_.assign(graph_.unknowns().size(), Eigen::VectorXd::Zero(6));
  inbox_.forget(DgsStage::kRefine);  // the neighbours' increments of an earlier step
  resetProgress();
}

Vector6 RobotAgent::ownIncrement(std::size_t i) const {
  if (cg_active_) return cg_.increment(i);
  return x_[i];
}

Vector6 RobotAgent::neighbourIncrement(int slot) const {
  if (cg_active_) return cg_.neighbourIncrement(slot);
  const Eigen::VectorXd* v = inbox_.get(DgsStage::kRefine, slot);
  return v ? Vector6(v->head<6>()) : Vector6::Zero();
}

Eigen::VectorXd RobotAgent::stackedSweepValue() const {
  Eigen::VectorXd z(static_cast<Eigen::Index>(6 * x_.size()));
  for (std::size_t i = 0; i < x_.size(); ++i) z.segment<6>(static_cast<Eigen::Index>(6 * i)) = x_[i];
  return z;
}

void RobotAgent::scaleStep(double factor) {
  requireRefine("scaleStep()");
  if (!(factor > 0.0 && factor <= 1.0)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": a step is scaled by a factor in (0, 1], got " +
                            std::to_string(factor));
  }
  step_scale_ *= factor;
}

void RobotAgent::acceptStep() {
  requireRefine("acceptStep()");
  refinement_.accept([this](std::size_t i) { return Vector6(step_scale_ * ownIncrement(i)); },
                     [this](int slot) { return Vector6(step_scale_ * neighbourIncrement(slot)); });
  x_.assign(graph_.unknowns().size(), Eigen::VectorXd::Zero(6));
  inbox_.forget(DgsStage::kRefine);
  cg_active_ = false;
  linearized_ = false;
}

DgsStage RobotAgent::cgStage(const char* what) const {
  if (state_ == AgentState::kPose) return DgsStage::kPose;
  requireRefine(what);
  if (!linearized_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) + ": " + what +
                            " before beginStep()");
  }
  return DgsStage::kRefine;
}

void RobotAgent::startPreconditioner() {
  const DgsStage stage = cgStage("startPreconditioner()");
  if (!cg_active_) {
    // Pose stage: conjugate gradients start from the stage's current values, the own unknowns'
    // and the neighbours' last received: zero increments and the anchor's translation after
    // the stage's first exchange, or the flagged sweeps' values (dgs_driver.h). The residual
    // holds them, the increments start at 0 from them.
    std::vector<Eigen::VectorXd> start(graph_.neighbours().size());
    own_start_.assign(x_.size(), Eigen::VectorXd::Zero(6));
    if (stage == DgsStage::kPose) {
      own_start_ = x_;
      for (std::size_t j = 0; j < start.size(); ++j) {
        const Eigen::VectorXd* v = inbox_.get(DgsStage::kPose, static_cast<int>(j));
        start[j] = v ? *v : Eigen::VectorXd(Eigen::VectorXd::Zero(6));
      }
    }
    cg_active_ = true;
    std::vector<bool> use;
    can_solve_ = solvable(stage, use);
    const Eigen::Index n = static_cast<Eigen::Index>(6 * graph_.unknowns().size());
    Eigen::VectorXd residual = Eigen::VectorXd::Zero(n);
    if (can_solve_) {
      pose_.assemble(use);
      residual = pose_.constantRhs().col(0);
      if (stage == DgsStage::kPose) {
        const auto& separators = graph_.separators();
        for (std::size_t s = 0; s < separators.size(); ++s) {
          const Eigen::Index row = pose_.separatorRow(s);
          if (row < 0) continue;
          residual.segment<6>(row).noalias() -=
              Matrix6(pose_.coupling(s)) * start[static_cast<std::size_t>(separators[s].slot)];
        }
        residual.noalias() -= pose_.multiply(stackedSweepValue());
      }
    }
    cg_.start(residual, graph_.neighbours().size());
    pose_start_ = std::move(start);
  }
  x_.assign(graph_.unknowns().size(), Eigen::VectorXd::Zero(6));
  inbox_.forget(stage);
  resetProgress();
}

double RobotAgent::residualDot() const {
  cgStage("residualDot()");
  if (!cg_active_) return 0.0;
  return cg_.residual().dot(stackedSweepValue());
}

void RobotAgent::firstDirection() { nextDirection(0.0); }

void RobotAgent::nextDirection(double beta) {
  cgStage("nextDirection()");
  if (!cg_active_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": a search direction before startPreconditioner()");
  }
  const DgsStage stage = currentStage();
  std::vector<const Eigen::VectorXd*> neighbour_z(graph_.neighbours().size());
  for (std::size_t i = 0; i < neighbour_z.size(); ++i) {
    neighbour_z[i] = inbox_.get(stage, static_cast<int>(i));
  }
  cg_.nextDirection(beta, stackedSweepValue(), neighbour_z);
}

double RobotAgent::curvature() {
  cgStage("curvature()");
  if (!cg_active_ || !can_solve_) {
    if (cg_active_) cg_.clearCurvature();
    return 0.0;
  }
  return cg_.curvature(graph_, pose_);
}

void RobotAgent::advance(double alpha) {
  cgStage("advance()");
  if (!cg_active_) return;
  cg_.advance(alpha);
}

bool RobotAgent::refineCoarseReady() const {
  return (state_ == AgentState::kRefine || state_ == AgentState::kPose) && cg_active_ &&
         can_solve_;
}

CoarseShare RobotAgent::refineCoarseMatrix() {
  if (!refineCoarseReady()) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": refineCoarseMatrix() outside a conjugate-gradient step it can "
                            "solve in (state " + ToString(state_) + ")");
  }
  if (state_ == AgentState::kPose) {
    refine_coarse_.buildPoseStage(graph_, R_hat_);
  } else {
    refine_coarse_.build(graph_, refinement_);
  }
  refine_coarse_built_ = true;
  return refine_coarse_.matrix(graph_, pose_);
}

Eigen::VectorXd RobotAgent::refineCoarseResidual() const {
  if (!refineCoarseReady() || !refine_coarse_built_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": refineCoarseResidual() before refineCoarseMatrix() of the step");
  }
  const Eigen::VectorXd r =
      localRhs(currentStage()).col(0) - pose_.multiply(stackedSweepValue());
  return refine_coarse_.project(graph_, pose_, r);
}

void RobotAgent::applyRefineCoarse(const std::map<int, Eigen::MatrixXd>& y) {
  if (!refineCoarseReady() || !refine_coarse_built_) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": applyRefineCoarse() before refineCoarseMatrix() of the step");
  }
  refine_coarse_.apply(graph_, currentStage(), y, x_, inbox_);
}

CoarseMessage RobotAgent::refinePieceMatrix(std::uint64_t piece_poses, std::uint32_t iteration) {
  if (!refineCoarseReady() || state_ != AgentState::kRefine || piece_poses == 0) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": refinePieceMatrix() outside a refinement step it can solve in, or "
                            "with no pieces (state " +
                            ToString(state_) + ")");
  }
  refine_coarse_.build(graph_, refinement_, piece_poses);
  refine_coarse_built_ = true;
  return refine_coarse_.pieceMatrix(graph_, pose_, iteration);
}

CoarseMessage RobotAgent::refinePieceResidual(std::uint32_t iteration) const {
  if (!refineCoarseReady() || !refine_coarse_built_ || !refine_coarse_.byPieces()) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": refinePieceResidual() before refinePieceMatrix() of the step");
  }
  const Eigen::VectorXd r = localRhs(currentStage()).col(0) - pose_.multiply(stackedSweepValue());
  return refine_coarse_.pieceResidual(graph_, pose_, r, iteration);
}

void RobotAgent::applyRefinePieces(const CoarseMessage& solution) {
  if (!refineCoarseReady() || !refine_coarse_built_ || !refine_coarse_.byPieces()) {
    throw InvalidInputError("DGS robot " + std::to_string(robot()) +
                            ": applyRefinePieces() before refinePieceMatrix() of the step");
  }
  refine_coarse_.applyPieces(graph_, currentStage(), solution, x_, inbox_);
}

void RobotAgent::finishRefine() {
  requireRefine("finishRefine()");
  state_ = AgentState::kDone;
}

double RobotAgent::costShare(bool candidate) const {
  requireRefine("costShare()");
  if (!candidate) return refinement_.costShare({}, {});
  return refinement_.costShare(
      [this](std::size_t i) { return Vector6(step_scale_ * ownIncrement(i)); },
      [this](int slot) { return Vector6(step_scale_ * neighbourIncrement(slot)); });
}

double RobotAgent::incrementNorm() const {
  if (state_ != AgentState::kRefine) return 0.0;
  if (cg_active_) return cg_.increment().norm();
  double n2 = 0.0;
  for (const Eigen::VectorXd& x : x_) n2 += x.squaredNorm();
  return std::sqrt(n2);
}

std::map<Key, Eigen::VectorXd> RobotAgent::relaxedRotations() const {
  std::map<Key, Eigen::VectorXd> out;
  const std::vector<Eigen::VectorXd>& r = state_ == AgentState::kRotation ? x_ : relaxed_;
  const auto& unknowns = graph_.unknowns();
  for (std::size_t i = 0; i < unknowns.size() && i < r.size(); ++i) out[unknowns[i]] = r[i];
  if (graph_.ownsAnchor()) {
    out[graph_.anchor()] = RowMajor(graph_.initial(graph_.anchor()).rotation().matrix());
  }
  return out;
}

}  // namespace moslam
