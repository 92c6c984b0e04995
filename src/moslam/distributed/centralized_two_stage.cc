#include "moslam/distributed/centralized_two_stage.h"

#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/distributed/two_stage_terms.h"

namespace moslam {

namespace {

struct Layout {
  std::vector<Key> unknowns;
  std::vector<std::pair<Key, Key>> coupled;
};

Layout MakeLayout(const PoseGraph& graph, const Key& anchor) {
  Layout layout;
  for (const Key& k : graph.keys()) {
    if (k != anchor) layout.unknowns.push_back(k);
  }
  for (const RelativePoseFactor& f : graph.factors()) layout.coupled.emplace_back(f.a(), f.b());
  return layout;
}

void CheckConnected(const PoseGraph& graph, const Key& anchor) {
  const std::vector<Key> unreachable = UnreachableFrom(graph, anchor);
  if (!unreachable.empty()) {
    throw UnderdeterminedError("two-stage solve: " + std::to_string(unreachable.size()) +
                               " variables (first " + ToString(unreachable.front()) +
                               ") are not connected to the anchor " + ToString(anchor));
  }
}

}  // namespace

Values CentralizedPoseStep(const PoseGraph& graph, const std::map<Key, Matrix3>& rotations,
                           const Key& anchor, const SE3& anchor_pose,
                           const TwoStageOptions& options) {
  const Layout layout = MakeLayout(graph, anchor);
  const bool weighted = options.weight_by_information;
  auto R = [&](const Key& k) -> const Matrix3& {
    const auto it = rotations.find(k);
    if (it == rotations.end()) {
      throw InvalidInputError("pose step: no rotation for " + ToString(k));
    }
    return it->second;
  };
  BlockLeastSquares problem(layout.unknowns, 6, 1, layout.coupled);
  Eigen::MatrixXd anchor_value = Eigen::VectorXd::Zero(6);
  anchor_value.bottomRows(3) = anchor_pose.translation();
  const Eigen::MatrixXd* fixed = &anchor_value;
  for (const RelativePoseFactor& f : graph.factors()) {
    if (f.a() == anchor && f.b() == anchor) continue;
    problem.add(PoseTerm(f, f.a() == anchor ? anchor_pose.rotation().matrix() : R(f.a()),
                         f.b() == anchor ? anchor_pose.rotation().matrix() : R(f.b()), weighted),
                fixed, fixed);
  }
  for (const PriorFactor& p : graph.priors()) {
    if (p.key() == anchor) continue;
    problem.add(PosePriorTerm(p, R(p.key()), weighted), nullptr, nullptr);
  }
  const std::vector<Eigen::MatrixXd> delta = problem.solve();
  Values values;
  values[anchor] = anchor_pose;
  for (std::size_t i = 0; i < layout.unknowns.size(); ++i) {
    const Key& k = layout.unknowns[i];
    const Eigen::VectorXd d = delta[i];
    values[k] = SE3(SO3(R(k)) * SO3::Exp(d.head<3>()), d.tail<3>());
  }
  return values;
}

TwoStageResult CentralizedTwoStage(const PoseGraph& graph, const Values& initial,
                                   const TwoStageOptions& options) {
  const Key anchor = GaugeAnchor(graph);
  CheckConnected(graph, anchor);
  const auto anchor_it = initial.find(anchor);
  const SE3 anchor_pose = anchor_it != initial.end() ? anchor_it->second : SE3();
  const Layout layout = MakeLayout(graph, anchor);
  const bool weighted = options.weight_by_information;

  BlockLeastSquares rotation(layout.unknowns, 3, 3, layout.coupled);
  const Eigen::MatrixXd anchor_value = RotationUnknown(anchor_pose.rotation().matrix());
  for (const RelativePoseFactor& f : graph.factors()) {
    if (f.a() == anchor && f.b() == anchor) continue;
    rotation.add(RotationTerm(f, weighted), &anchor_value, &anchor_value);
  }
  for (const PriorFactor& p : graph.priors()) {
    if (p.key() == anchor) continue;
    rotation.add(RotationPriorTerm(p, weighted), nullptr, nullptr);
  }
  const std::vector<Eigen::MatrixXd> X = rotation.solve();

  TwoStageResult result;
  for (std::size_t i = 0; i < layout.unknowns.size(); ++i) {
    const Eigen::VectorXd r = Eigen::Map<const Eigen::VectorXd>(X[i].data(), 9);
    result.relaxed_rotations[layout.unknowns[i]] = r;
    result.rotations[layout.unknowns[i]] = ProjectToRotation(r);
  }
  result.relaxed_rotations[anchor] = RowMajor(anchor_pose.rotation().matrix());
  result.rotations[anchor] = anchor_pose.rotation().matrix();
  result.values = CentralizedPoseStep(graph, result.rotations, anchor, anchor_pose, options);
  return result;
}

}  // namespace moslam
