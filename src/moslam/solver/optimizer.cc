#include "moslam/solver/optimizer.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include "moslam/common/errors.h"
#include "moslam/solver/block_sparse_system.h"

namespace moslam {
namespace {

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

void OptimizerOptions::validate() const {
  auto bad = [](const std::string& what) {
    throw InvalidInputError("OptimizerOptions: " + what);
  };
  if (max_iterations < 0) bad("max_iterations must be >= 0");
  if (!(relative_cost_tolerance >= 0.0)) bad("relative_cost_tolerance must be >= 0");
  if (!(absolute_cost_tolerance >= 0.0)) bad("absolute_cost_tolerance must be >= 0");
  if (!(step_tolerance >= 0.0)) bad("step_tolerance must be >= 0");
  if (!(lm_initial_lambda > 0.0) || !std::isfinite(lm_initial_lambda)) {
    bad("lm_initial_lambda must be positive and finite");
  }
  if (!(lm_max_lambda > lm_initial_lambda)) bad("lm_max_lambda must exceed lm_initial_lambda");
}

std::string ToString(TerminationStatus status) {
  switch (status) {
    case TerminationStatus::kNotStarted: return "not_started";
    case TerminationStatus::kConverged: return "converged";
    case TerminationStatus::kMaxIterations: return "max_iterations";
    case TerminationStatus::kCostIncreased: return "cost_increased";
    case TerminationStatus::kNoDecreasingStep: return "no_decreasing_step";
  }
  return "unknown";
}

struct NonlinearOptimizer::Impl {
  explicit Impl(const PoseGraph& g) : graph(g) {}
  const PoseGraph& graph;  // the caller's (NonlinearOptimizer's contract)
  OptimizerOptions options;
  Key anchor;
  std::vector<Key> keys;         // every variable, in key order
  std::vector<SE3> x;            // current estimate, parallel to keys
  std::vector<int> block;        // block index in the linear system, -1 for the anchor
  struct FactorIndex {
    int a, b;  // positions in keys/x
    BlockSparseSystem::Slot aa, bb, ab;
  };
  std::vector<FactorIndex> factor_index;
  std::vector<std::pair<int, BlockSparseSystem::Slot>> prior_index;
  std::unique_ptr<BlockSparseSystem> system;

  double cost = 0.0;
  double lambda = 0.0, nu = 2.0;
  bool finished = false;
  mutable bool values_dirty = true;
  mutable Values values_cache;
  OptimizerResult result;

  double Cost(const std::vector<SE3>& est) const {
    double total = 0.0;
    const auto& factors = graph.factors();
    for (size_t i = 0; i < factors.size(); ++i) {
      total += factors[i].cost(est[factor_index[i].a], est[factor_index[i].b]);
    }
    for (size_t i = 0; i < graph.priors().size(); ++i) {
      total += graph.priors()[i].cost(est[prior_index[i].first]);
    }
    return total;
  }

  // Builds J^T Omega J into the system and -J^T Omega r into its right-hand side.
  void Linearize() {
    const auto t0 = Clock::now();
    BlockSparseSystem& sys = *system;
    sys.setZero();
    Eigen::VectorXd& rhs = sys.rhs();
    Matrix6 Ha, Hb;
    const auto& factors = graph.factors();
    for (size_t i = 0; i < factors.size(); ++i) {
      const RelativePoseFactor& f = factors[i];
      const FactorIndex& fi = factor_index[i];
      const Vector6 r = f.residual(x[fi.a], x[fi.b], &Ha, &Hb);
      const Matrix6& U = f.sqrtInformation();
      const Vector6 wr = U * r;
      const Matrix6 Ja = U * Ha, Jb = U * Hb;
      const int ba = block[fi.a], bb = block[fi.b];
      // Blocks evaluated into fixed-size matrices: add() then reads them in place.
      if (ba >= 0) {
        const Matrix6 Haa = Ja.transpose() * Ja;
        sys.add(fi.aa, Haa);
        rhs.segment<6>(6 * ba) -= Ja.transpose() * wr;
      }
      if (bb >= 0) {
        const Matrix6 Hbb = Jb.transpose() * Jb;
        sys.add(fi.bb, Hbb);
        rhs.segment<6>(6 * bb) -= Jb.transpose() * wr;
      }
      if (ba >= 0 && bb >= 0) {
        const Matrix6 Hab = Ja.transpose() * Jb;
        sys.add(fi.ab, Hab);
      }
    }
    for (size_t i = 0; i < graph.priors().size(); ++i) {
      const PriorFactor& p = graph.priors()[i];
      const int v = prior_index[i].first;
      if (block[v] < 0) continue;
      Matrix6 H;
      const Vector6 r = p.residual(x[v], &H);
      const Matrix6 J = p.sqrtInformation() * H;
      const Matrix6 JTJ = J.transpose() * J;
      sys.add(prior_index[i].second, JTJ);
      rhs.segment<6>(6 * block[v]) -= J.transpose() * (p.sqrtInformation() * r);
    }
    result.linearize_seconds += SecondsSince(t0);
  }

  Eigen::VectorXd Solve(const Eigen::VectorXd& damping) {
    const auto t0 = Clock::now();
    Eigen::VectorXd delta = system->solve(damping);
    result.solve_seconds += SecondsSince(t0);
    return delta;
  }

  std::vector<SE3> Retract(const Eigen::VectorXd& delta) const {
    std::vector<SE3> out = x;
    for (size_t v = 0; v < x.size(); ++v) {
      if (block[v] >= 0) out[v] = x[v].retract(delta.segment<6>(6 * block[v]));
    }
    return out;
  }

  void Finish(TerminationStatus status) {
    finished = true;
    result.termination = status;
  }

  bool Converged(double old_cost, double new_cost, double step_norm) const {
    return (old_cost - new_cost) <= options.relative_cost_tolerance * old_cost ||
           new_cost <= options.absolute_cost_tolerance || step_norm <= options.step_tolerance;
  }

  IterationSummary IterateGaussNewton(IterationSummary s) {
    Linearize();
    const Eigen::VectorXd delta = Solve(Eigen::VectorXd());
    s.linear_solves = 1;
    s.step_norm = delta.size() ? delta.cwiseAbs().maxCoeff() : 0.0;
    std::vector<SE3> candidate = Retract(delta);
    const double new_cost = Cost(candidate);
    if (!std::isfinite(new_cost)) {
      throw NumericalError("Gauss-Newton step produced a non-finite cost (initial estimate far "
                           "from the solution? try --method lm or --init chordal)");
    }
    s.cost_change = cost - new_cost;
    if (new_cost <= cost) {
      x = std::move(candidate);
      values_dirty = true;
      const double old = cost;
      cost = new_cost;
      if (Converged(old, new_cost, s.step_norm)) Finish(TerminationStatus::kConverged);
    } else if (new_cost - cost <= options.relative_cost_tolerance * cost) {
      Finish(TerminationStatus::kConverged);  // at the optimum up to round-off: keep the lower
    } else {
      Finish(TerminationStatus::kCostIncreased);
    }
    s.cost = cost;
    return s;
  }

  IterationSummary IterateLevenbergMarquardt(IterationSummary s) {
    Linearize();
    const Eigen::VectorXd rhs = system->rhs();  // -gradient
    const Eigen::VectorXd diag = system->diagonal().cwiseMax(1e-9).cwiseMin(1e32);
    while (true) {
      const Eigen::VectorXd delta = Solve(lambda * diag);
      ++s.linear_solves;
      // Decrease predicted by the undamped quadratic model: -(g.d + 1/2 d.H.d).
      const double predicted = rhs.dot(delta) - 0.5 * delta.dot(system->multiply(delta));
      const std::vector<SE3> candidate = Retract(delta);
      const double new_cost = Cost(candidate);
      s.step_norm = delta.size() ? delta.cwiseAbs().maxCoeff() : 0.0;
      if (std::isfinite(new_cost) && new_cost < cost) {
        const double rho = (cost - new_cost) / std::max(predicted, 1e-300);
        s.cost_change = cost - new_cost;
        s.lambda = lambda;
        const double old = cost;
        x = candidate;
        values_dirty = true;
        cost = new_cost;
        lambda *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
        nu = 2.0;
        if (Converged(old, new_cost, s.step_norm)) Finish(TerminationStatus::kConverged);
        break;
      }
      if (predicted <= options.relative_cost_tolerance * cost ||
          s.step_norm <= options.step_tolerance) {
        Finish(TerminationStatus::kConverged);  // no decrease left to find
        break;
      }
      lambda *= nu;
      nu *= 2.0;
      if (lambda > options.lm_max_lambda) {
        Finish(TerminationStatus::kNoDecreasingStep);
        break;
      }
    }
    s.cost = cost;
    return s;
  }
};

NonlinearOptimizer::NonlinearOptimizer(const PoseGraph& graph, const Values& initial,
                                       const OptimizerOptions& options)
    : impl_(std::make_unique<Impl>(graph)) {
  const auto t0 = Clock::now();
  options.validate();
  Impl& im = *impl_;
  im.options = options;
  im.anchor = GaugeAnchor(graph);
  RequireAnchored(graph, im.anchor);

  std::unordered_map<Key, int> position;
  int num_free = 0;
  for (const Key& k : graph.keys()) {
    const auto it = initial.find(k);
    if (it == initial.end()) {
      throw InvalidInputError("no initial estimate for variable " + ToString(k) +
                              " (the file has no vertex for it: initialise with the chordal "
                              "relaxation or odometry)");
    }
    if (!it->second.rotation().matrix().allFinite() || !it->second.translation().allFinite()) {
      throw InvalidInputError("initial estimate of " + ToString(k) + " is not finite");
    }
    position[k] = static_cast<int>(im.keys.size());
    im.keys.push_back(k);
    im.x.push_back(it->second);
    im.block.push_back(k == im.anchor ? -1 : num_free++);
  }

  std::vector<std::pair<int, int>> pairs;
  for (const auto& f : graph.factors()) {
    const int ba = im.block[position.at(f.a())], bb = im.block[position.at(f.b())];
    if (ba >= 0 && bb >= 0) pairs.emplace_back(ba, bb);
  }
  im.system = std::make_unique<BlockSparseSystem>(num_free, 6, pairs);
  for (const auto& f : graph.factors()) {
    Impl::FactorIndex fi{position.at(f.a()), position.at(f.b()), {}, {}, {}};
    const int ba = im.block[fi.a], bb = im.block[fi.b];
    if (ba >= 0) fi.aa = im.system->slot(ba, ba);
    if (bb >= 0) fi.bb = im.system->slot(bb, bb);
    if (ba >= 0 && bb >= 0) fi.ab = im.system->slot(ba, bb);
    im.factor_index.push_back(fi);
  }
  for (const auto& p : graph.priors()) {
    const int v = position.at(p.key());
    im.prior_index.emplace_back(
        v, im.block[v] >= 0 ? im.system->slot(im.block[v], im.block[v]) : BlockSparseSystem::Slot{});
  }

  im.cost = im.Cost(im.x);
  if (!std::isfinite(im.cost)) throw NumericalError("initial cost is not finite");
  im.lambda = options.lm_initial_lambda;
  im.result.initial_cost = im.cost;
  im.result.final_cost = im.cost;
  if (options.max_iterations == 0 || num_free == 0 || im.cost <= options.absolute_cost_tolerance) {
    im.Finish(options.max_iterations == 0 ? TerminationStatus::kMaxIterations
                                          : TerminationStatus::kConverged);
  }
  im.result.seconds = SecondsSince(t0);
}

NonlinearOptimizer::~NonlinearOptimizer() = default;

IterationSummary NonlinearOptimizer::iterate() {
  Impl& im = *impl_;
  IterationSummary s;
  if (im.finished) {
    s.iteration = im.result.iterations;
    s.cost = im.cost;
    return s;
  }
  const auto t0 = Clock::now();
  s.iteration = im.result.iterations + 1;
  s = im.options.method == Method::kGaussNewton ? im.IterateGaussNewton(s)
                                                : im.IterateLevenbergMarquardt(s);
  s.seconds = SecondsSince(t0);
  im.result.iterations = s.iteration;
  im.result.history.push_back(s);
  im.result.final_cost = im.cost;
  im.result.seconds += s.seconds;
  if (!im.finished && im.result.iterations >= im.options.max_iterations) {
    im.Finish(TerminationStatus::kMaxIterations);
  }
  if (im.options.verbose) {
    fmt::print(stderr, "iter {:3d}  cost {:.10e}  change {:.3e}  step {:.3e}  lambda {:.1e}  {:.3f}s\n",
               s.iteration, s.cost, s.cost_change, s.step_norm, s.lambda, s.seconds);
  }
  return s;
}

OptimizerResult NonlinearOptimizer::optimize() {
  while (!done()) iterate();
  OptimizerResult out = impl_->result;
  out.values = values();
  return out;
}

bool NonlinearOptimizer::done() const { return impl_->finished; }
double NonlinearOptimizer::cost() const { return impl_->cost; }
TerminationStatus NonlinearOptimizer::termination() const { return impl_->result.termination; }
const OptimizerResult& NonlinearOptimizer::result() const { return impl_->result; }

const Values& NonlinearOptimizer::values() const {
  const Impl& im = *impl_;
  if (im.values_dirty) {
    im.values_cache.clear();
    for (size_t i = 0; i < im.keys.size(); ++i) im.values_cache.emplace_hint(im.values_cache.end(), im.keys[i], im.x[i]);
    im.values_dirty = false;
  }
  return im.values_cache;
}

OptimizerResult Optimize(const PoseGraph& graph, const Values& initial,
                         const OptimizerOptions& options) {
  return NonlinearOptimizer(graph, initial, options).optimize();
}

}  // namespace moslam
