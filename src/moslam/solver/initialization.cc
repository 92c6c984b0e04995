#include "moslam/solver/initialization.h"

#include <deque>
#include <set>
#include <unordered_map>

#include "moslam/common/errors.h"
#include "moslam/solver/block_sparse_system.h"

namespace moslam {
namespace {

// Variables other than the anchor, numbered 0..n-1 in key order; the anchor maps to -1.
struct Indexing {
  Key anchor;
  std::vector<Key> keys;
  std::unordered_map<Key, int> index;

  Indexing(const PoseGraph& graph, Key anchor_key) : anchor(anchor_key) {
    for (const Key& k : graph.keys()) {
      if (k == anchor) continue;
      index[k] = static_cast<int>(keys.size());
      keys.push_back(k);
    }
    index[anchor] = -1;
  }
  int operator()(Key k) const { return index.at(k); }
  int size() const { return static_cast<int>(keys.size()); }
};

std::vector<std::pair<int, int>> FreePairs(const PoseGraph& graph, const Indexing& idx) {
  std::vector<std::pair<int, int>> pairs;
  for (const auto& f : graph.factors()) {
    const int a = idx(f.a()), b = idx(f.b());
    if (a >= 0 && b >= 0) pairs.emplace_back(a, b);
  }
  return pairs;
}

double RotationWeight(const Matrix6& information, const ChordalOptions& options) {
  return options.weight_by_information ? information.topLeftCorner<3, 3>().trace() / 3.0 : 1.0;
}

Matrix3 TranslationWeight(const Matrix6& information, const ChordalOptions& options) {
  return options.weight_by_information ? Matrix3(information.bottomRightCorner<3, 3>())
                                       : Matrix3::Identity();
}

}  // namespace

namespace {

// The two linear least-squares problems of the chordal initialisation share their unknowns
// (3 numbers per variable, the anchor eliminated) and their sparsity pattern: one system, one
// symbolic analysis, factorized once per problem.
struct ChordalProblem {
  Key anchor;
  Indexing idx;
  BlockSparseSystem sys;

  explicit ChordalProblem(const PoseGraph& graph)
      : anchor(GaugeAnchor(graph)),
        idx(Anchored(graph, anchor), anchor),
        sys(idx.size(), 3, FreePairs(graph, idx)) {}

  static const PoseGraph& Anchored(const PoseGraph& graph, Key anchor) {
    RequireAnchored(graph, anchor);
    return graph;
  }

  // Stage 1 (see ChordalRotations).
  std::map<Key, SO3> rotations(const PoseGraph& graph, const SO3& anchor_rotation,
                               const ChordalOptions& options) {
    const int n = idx.size();
    // Unknown per variable: P = R^T, whose column k is row k of R. Each edge gives, for every k,
    // || P_b e_k - R_ab^T P_a e_k ||^2, so the three rows share one system with three right sides.
    sys.setZero();
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(3 * n, 3);
    const Matrix3 I = Matrix3::Identity();
    const Matrix3 P_anchor = anchor_rotation.matrix().transpose();
    for (const auto& f : graph.factors()) {
      const int a = idx(f.a()), b = idx(f.b());
      const double w = RotationWeight(f.information(), options);
      const Matrix3& Rab = f.measured().rotation().matrix();
      if (a >= 0) sys.addDiagonal(a, w * I);
      if (b >= 0) sys.addDiagonal(b, w * I);
      if (a >= 0 && b >= 0) {
        sys.add(sys.slot(a, b), -w * Rab);
      } else if (a < 0) {
        B.block<3, 3>(3 * b, 0) += w * Rab.transpose() * P_anchor;
      } else {
        B.block<3, 3>(3 * a, 0) += w * Rab * P_anchor;
      }
    }
    for (const auto& p : graph.priors()) {
      const int k = idx(p.key());
      if (k < 0) continue;  // the anchor is held fixed anyway
      const double w = RotationWeight(p.information(), options);
      sys.addDiagonal(k, w * I);
      B.block<3, 3>(3 * k, 0) += w * p.prior().rotation().matrix().transpose();
    }
    sys.factorize();
    const Eigen::MatrixXd X = sys.backSolve(B);

    std::map<Key, SO3> out{{anchor, anchor_rotation}};
    for (int k = 0; k < n; ++k) {
      out.emplace(idx.keys[k], SO3::FromMatrixNormalized(X.block<3, 3>(3 * k, 0).transpose()));
    }
    return out;
  }

  // Stage 2 (see TranslationsGivenRotations).
  Values translations(const PoseGraph& graph, const std::map<Key, SO3>& rotations,
                      const Vector3& anchor_translation, const ChordalOptions& options) {
    const int n = idx.size();
    auto rotation = [&](Key k) -> const Matrix3& {
      const auto it = rotations.find(k);
      if (it == rotations.end()) {
        throw InvalidInputError("TranslationsGivenRotations: no rotation for " + ToString(k));
      }
      return it->second.matrix();
    };
    // Residual of an edge, in the frame of a: R_a^T (t_b - t_a) - t_ab, weighted by the
    // translation information rotated from the measurement's frame into a's.
    sys.setZero();
    for (const auto& f : graph.factors()) {
      const int a = idx(f.a()), b = idx(f.b());
      const Matrix3& Ra = rotation(f.a());
      const Matrix3& Rab = f.measured().rotation().matrix();
      const Matrix3 W = Rab * TranslationWeight(f.information(), options) * Rab.transpose();
      const Matrix3 M = Ra * W * Ra.transpose();
      const Vector3 m = Ra * W * f.measured().translation();  // R_a W t_ab
      if (a >= 0) sys.addDiagonal(a, M);
      if (b >= 0) sys.addDiagonal(b, M);
      if (a >= 0 && b >= 0) {
        sys.add(sys.slot(a, b), -M);
        sys.rhs().segment<3>(3 * a) -= m;
        sys.rhs().segment<3>(3 * b) += m;
      } else if (a < 0) {
        sys.rhs().segment<3>(3 * b) += M * anchor_translation + m;
      } else {
        sys.rhs().segment<3>(3 * a) += M * anchor_translation - m;
      }
    }
    for (const auto& p : graph.priors()) {
      const int k = idx(p.key());
      if (k < 0) continue;
      const Matrix3& Rz = p.prior().rotation().matrix();
      const Matrix3 M = Rz * TranslationWeight(p.information(), options) * Rz.transpose();
      sys.addDiagonal(k, M);
      sys.rhs().segment<3>(3 * k) += M * p.prior().translation();
    }
    const Eigen::VectorXd t = sys.solve();

    Values out{{anchor, SE3(SO3(rotation(anchor)), anchor_translation)}};
    for (int k = 0; k < n; ++k) {
      out.emplace(idx.keys[k], SE3(SO3(rotation(idx.keys[k])), t.segment<3>(3 * k)));
    }
    return out;
  }
};

}  // namespace

std::map<Key, SO3> ChordalRotations(const PoseGraph& graph, const SO3& anchor_rotation,
                                    const ChordalOptions& options) {
  return ChordalProblem(graph).rotations(graph, anchor_rotation, options);
}

Values TranslationsGivenRotations(const PoseGraph& graph, const std::map<Key, SO3>& rotations,
                                  const Vector3& anchor_translation,
                                  const ChordalOptions& options) {
  return ChordalProblem(graph).translations(graph, rotations, anchor_translation, options);
}

Values ChordalInitialization(const PoseGraph& graph, const SE3& anchor_pose,
                             const ChordalOptions& options) {
  ChordalProblem problem(graph);
  const auto rotations = problem.rotations(graph, anchor_pose.rotation(), options);
  return problem.translations(graph, rotations, anchor_pose.translation(), options);
}

Values OdometryInitialization(const PoseGraph& graph, const SE3& anchor_pose) {
  const Key anchor = GaugeAnchor(graph);
  RequireAnchored(graph, anchor);
  std::unordered_map<Key, std::vector<size_t>> incident;
  const auto& factors = graph.factors();
  for (size_t i = 0; i < factors.size(); ++i) {
    incident[factors[i].a()].push_back(i);
    incident[factors[i].b()].push_back(i);
  }
  auto is_odometry = [](const RelativePoseFactor& f) {
    return f.a().robot == f.b().robot && f.a().isPose() && f.b().isPose() &&
           (f.a().index + 1 == f.b().index || f.b().index + 1 == f.a().index);
  };

  Values out;
  std::deque<size_t> odometry, other;  // edges to expand: odometry ones first
  auto visit = [&](Key k, const SE3& pose) {
    out.emplace(k, pose);
    for (size_t i : incident[k]) (is_odometry(factors[i]) ? odometry : other).push_back(i);
  };
  auto expand = [&] {
    while (!odometry.empty() || !other.empty()) {
      std::deque<size_t>& q = odometry.empty() ? other : odometry;
      const RelativePoseFactor& f = factors[q.front()];
      q.pop_front();
      const bool has_a = out.count(f.a()) > 0, has_b = out.count(f.b()) > 0;
      if (has_a && !has_b) {
        visit(f.b(), out.at(f.a()) * f.measured());
      } else if (has_b && !has_a) {
        visit(f.a(), out.at(f.b()) * f.measured().inverse());
      }
    }
  };
  visit(anchor, anchor_pose);
  expand();
  // Components that only a prior anchors start at their prior.
  for (const auto& p : graph.priors()) {
    if (out.count(p.key())) continue;
    visit(p.key(), p.prior());
    expand();
  }
  return out;
}

}  // namespace moslam
