#include "moslam/robust/gnc.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "moslam/common/errors.h"

namespace moslam {

void GncOptions::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("GncOptions: " + m); };
  if (!(threshold >= 0.0) || !std::isfinite(threshold)) bad("threshold must be >= 0 and finite");
  if (!(mu_step > 1.0) || !std::isfinite(mu_step)) bad("mu_step must be > 1 and finite");
  if (max_iterations < 1) bad("max_iterations must be >= 1");
  if (!(weight_tolerance > 0.0 && weight_tolerance < 0.5)) {
    bad("weight_tolerance must be in (0, 0.5)");
  }
  if (!(min_weight >= 0.0 && min_weight < 1.0)) bad("min_weight must be in [0, 1)");
}

double TlsWeight(double r2, double mu, double c2) {
  if (r2 <= mu / (mu + 1.0) * c2) return 1.0;
  if (r2 >= (mu + 1.0) / mu * c2) return 0.0;
  return std::sqrt(c2 * mu * (mu + 1.0) / r2) - mu;
}

std::string ToString(GncStatus status) {
  switch (status) {
    case GncStatus::kAllInliers:
      return "all inliers";
    case GncStatus::kConverged:
      return "converged";
    case GncStatus::kMaxIterations:
      return "max iterations";
  }
  return "unknown";
}

GncSchedule::GncSchedule(const GncOptions& options) : options_(options) {
  options_.validate();
  c2_ = options_.threshold2();
}

bool GncSchedule::start(double max_r2) {
  iterations_ = 0;
  if (!(max_r2 > c2_)) {
    status_ = GncStatus::kAllInliers;
    mu_ = 0.0;
    return false;
  }
  mu_ = c2_ / (2.0 * max_r2 - c2_);
  return true;
}

bool GncSchedule::next(bool decided) {
  ++iterations_;
  if (decided) {
    status_ = GncStatus::kConverged;
    return true;
  }
  if (iterations_ >= options_.max_iterations) {
    status_ = GncStatus::kMaxIterations;
    return true;
  }
  mu_ *= options_.mu_step;
  return false;
}

std::vector<double> SquaredResiduals(const PoseGraph& graph, const Values& values) {
  std::vector<double> out;
  out.reserve(graph.factors().size());
  for (const RelativePoseFactor& f : graph.factors()) {
    out.push_back(2.0 * f.cost(values.at(f.a()), values.at(f.b())));
  }
  return out;
}

PoseGraph WeightedGraph(const PoseGraph& graph, const std::vector<double>& weights,
                        double min_weight) {
  if (weights.size() != graph.factors().size()) {
    throw InvalidInputError("WeightedGraph: " + std::to_string(weights.size()) +
                            " weights for " + std::to_string(graph.factors().size()) +
                            " factors");
  }
  std::vector<RelativePoseFactor> factors;
  factors.reserve(weights.size());
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    const double w = std::max(weights[i], min_weight);
    factors.emplace_back(f.a(), f.b(), f.measured(), (w * f.information()).eval());
  }
  PoseGraph out(std::move(factors));
  for (const PriorFactor& p : graph.priors()) out.add(p);
  return out;
}

PoseGraph SubGraph(const PoseGraph& graph, const std::vector<bool>& keep,
                   std::vector<std::size_t>* index) {
  std::vector<RelativePoseFactor> factors;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    if (!keep[i]) continue;
    factors.push_back(graph.factors()[i]);
    if (index) index->push_back(i);
  }
  PoseGraph out(std::move(factors));
  for (const PriorFactor& p : graph.priors()) out.add(p);
  return out;
}

std::vector<bool> Inliers(const std::vector<double>& weights) {
  std::vector<bool> out;
  out.reserve(weights.size());
  for (double w : weights) out.push_back(w >= 0.5);
  return out;
}

bool AllWeightsOne(const std::vector<double>& weights) {
  return std::all_of(weights.begin(), weights.end(), [](double w) { return w == 1.0; });
}

int CountOutliers(const std::vector<bool>& robust, const std::vector<double>& weights) {
  int n = 0;
  for (std::size_t i = 0; i < weights.size(); ++i) n += (robust[i] && weights[i] < 0.5) ? 1 : 0;
  return n;
}

std::vector<bool> SeparatorFactors(const PoseGraph& graph) {
  std::vector<bool> out;
  out.reserve(graph.factors().size());
  for (const RelativePoseFactor& f : graph.factors()) out.push_back(f.a().robot != f.b().robot);
  return out;
}

std::vector<bool> LoopClosureFactors(const PoseGraph& graph) {
  std::vector<bool> out;
  out.reserve(graph.factors().size());
  for (const RelativePoseFactor& f : graph.factors()) {
    const Key a = f.a(), b = f.b();
    const bool consecutive =
        a.isPose() && b.isPose() && (a.index + 1 == b.index || b.index + 1 == a.index);
    out.push_back(!consecutive);
  }
  return out;
}

std::vector<bool> DefaultRobustFactors(const PoseGraph& graph) {
  if (graph.numRobots() > 1) return SeparatorFactors(graph);
  return LoopClosureFactors(graph);
}

std::vector<bool> ObjectFactors(const PoseGraph& graph) {
  std::vector<bool> out;
  out.reserve(graph.factors().size());
  for (const RelativePoseFactor& f : graph.factors()) {
    out.push_back(f.a().isObject() || f.b().isObject());
  }
  return out;
}

GncResult SolveGnc(const PoseGraph& graph, const Values& initial, const std::vector<bool>& robust,
                   const GncOptions& options, const OptimizerOptions& solver) {
  const auto t0 = std::chrono::steady_clock::now();
  options.validate();
  solver.validate();
  const std::size_t n = graph.factors().size();
  if (robust.size() != n) {
    throw InvalidInputError("SolveGnc: the robust mask has " + std::to_string(robust.size()) +
                            " entries for " + std::to_string(n) + " factors");
  }
  GncResult out;
  out.weights.assign(n, 1.0);
  out.values = Optimize(graph, initial, solver).values;
  out.least_squares_cost = graph.cost(out.values);
  GncSchedule schedule(options);
  auto robustMax = [&](const std::vector<double>& r2) {
    double m = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (robust[i]) m = std::max(m, r2[i]);
    }
    return m;
  };
  std::vector<double> r2 = SquaredResiduals(graph, out.values);
  if (schedule.start(robustMax(r2))) {
    for (;;) {
      bool decided = true;
      for (std::size_t i = 0; i < n; ++i) {
        if (!robust[i]) continue;
        out.weights[i] = schedule.weight(r2[i]);
        decided = decided && schedule.decided(out.weights[i]);
      }
      const PoseGraph weighted = WeightedGraph(graph, out.weights, options.min_weight);
      out.values = Optimize(weighted, out.values, solver).values;
      r2 = SquaredResiduals(graph, out.values);
      if (schedule.next(decided)) break;
    }
  }
  // The inliers alone, at full weight: the rounds kept min_weight of every rejected factor. A
  // variable only rejected factors touch is not in them: it keeps the rounds' estimate.
  if (!AllWeightsOne(out.weights)) {
    try {
      for (const auto& [k, x] :
           Optimize(SubGraph(graph, Inliers(out.weights)), out.values, solver).values) {
        out.values[k] = x;
      }
    } catch (const UnderdeterminedError&) {
      // The inliers leave part of the graph unanchored: keep the rounds' estimate.
    }
  }
  out.status = schedule.status();
  out.iterations = schedule.iterations();
  out.final_mu = schedule.mu();
  out.outliers = CountOutliers(robust, out.weights);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace moslam
