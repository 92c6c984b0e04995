// The Ceres side of the solver benchmarks: a moslam pose graph as a Ceres problem (the cost of
// ceres_se3_cost.h, written independently of moslam's), and Ceres' solve of it.
#pragma once

#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/product_manifold.h>
#include <ceres/solver.h>

#include <array>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include "ceres_se3_cost.h"
#include "moslam/graph/pose_graph.h"

namespace moslam_bench {

// The Ceres problem of a pose graph at an estimate: one 7-double block per variable
// (ceres_se3_cost.h), the anchor held constant.
class CeresPoseGraph {
 public:
  CeresPoseGraph(const moslam::PoseGraph& graph, const moslam::Values& values,
                 const moslam::Key& anchor) {
    for (const auto& [key, pose] : values) {
      const Eigen::Vector4d q = pose.rotation().quaternionWxyz();
      const moslam::Vector3& t = pose.translation();
      blocks_[key] = {q[1], q[2], q[3], q[0], t[0], t[1], t[2]};
    }
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(problem_options);
    for (const auto& f : graph.factors()) {
      problem_->AddResidualBlock(
          RelativePoseCost::Create(QuatWxyz(f.measured()), Trans(f.measured()),
                                                 f.sqrtInformation()),
          nullptr, block(f.a()), block(f.b()));
    }
    for (const auto& p : graph.priors()) {
      problem_->AddResidualBlock(PriorCost::Create(
                                     QuatWxyz(p.prior()), Trans(p.prior()), p.sqrtInformation()),
                                 nullptr, block(p.key()));
    }
    for (auto& [key, b] : blocks_) {
      if (problem_->HasParameterBlock(b.data())) problem_->SetManifold(b.data(), &manifold_);
    }
    problem_->SetParameterBlockConstant(block(anchor));
  }

  ceres::Problem& problem() { return *problem_; }

  moslam::Values values() const {
    moslam::Values out;
    for (const auto& [key, b] : blocks_) {
      out[key] = moslam::SE3(moslam::SO3::FromQuaternion(b[3], b[0], b[1], b[2]),
                             moslam::Vector3(b[4], b[5], b[6]));
    }
    return out;
  }

 private:
  double* block(const moslam::Key& key) {
    const auto it = blocks_.find(key);
    if (it == blocks_.end()) {
      throw std::runtime_error("variable " + moslam::ToString(key) + " has no initial estimate");
    }
    return it->second.data();
  }
  static Quat<double> QuatWxyz(const moslam::SE3& z) {
    const Eigen::Vector4d q = z.rotation().quaternionWxyz();
    return {q[0], q[1], q[2], q[3]};
  }
  static Vec3<double> Trans(const moslam::SE3& z) {
    return {z.translation()[0], z.translation()[1], z.translation()[2]};
  }

  std::map<moslam::Key, std::array<double, kPoseSize>> blocks_;  // stable addresses
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> manifold_;
  std::unique_ptr<ceres::Problem> problem_;  // declared last: destroyed before what it points to
};

struct CeresRun {
  ceres::Solver::Summary summary;
  moslam::Values values;
};

// Ceres' Levenberg-Marquardt (SPARSE_NORMAL_CHOLESKY on SuiteSparse) from `initial`: stops when
// the cost changes by less than function_tolerance relative (moslam's relative_cost_tolerance),
// the gradient and step tolerances tight enough never to stop it first.
inline CeresRun SolveWithCeres(const moslam::PoseGraph& graph, const moslam::Values& initial,
                               const moslam::Key& anchor, int num_threads,
                               double function_tolerance) {
  CeresPoseGraph cpg(graph, initial, anchor);
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  options.num_threads = num_threads;
  options.function_tolerance = function_tolerance;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  options.max_num_iterations = 500;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;

  CeresRun run;
  ceres::Solve(options, &cpg.problem(), &run.summary);
  run.values = cpg.values();
  return run;
}

}  // namespace moslam_bench
