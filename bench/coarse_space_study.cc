// A study of the refinement's linear solver (src/moslam/distributed/dgs_driver.h), not a test:
// at one linearisation point of a graph split among robots, the Gauss-Newton system H d = -g is
// solved by conjugate gradients preconditioned as the refinement preconditions them (a forward
// block Gauss-Seidel sweep over the robots, each robot's block solved exactly, a Galerkin coarse
// correction, a backward sweep), with coarse spaces of K rigid pieces per robot: each robot's
// unknowns in key order cut into K contiguous pieces, each moved as a whole about the mean of its
// translations (K = 1: the refinement's coarse space, RefineCoarseSpace; K = 0: the sweeps alone).
// Against the exact step (sparse Cholesky) it reports, per K, the iterations to the refinement's
// stopping measure sqrt(res.z / res0.z0) <= 1e-2 and the share of the exact step's model decrease
// reached after a number of iterations; and where the exact step is large (per robot).
//
//   moslam_coarse_study <folder|file> [--robots N] [--pieces 0 1 16 64] [--max-iter 1000]
//
// The point: a folder of robots' files (e.g. what `moslam dgs ... --out DIR` wrote), or a single
// file split into --robots N contiguous blocks as `moslam dgs` splits it; its vertices are the
// linearisation point (a file without vertices: the chordal initialisation).
#include <CLI/CLI.hpp>
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "moslam/distributed/partition.h"
#include "moslam/geometry/so3.h"
#include "moslam/io/g2o.h"
#include "moslam/solver/initialization.h"

namespace {

using moslam::Key;
using moslam::Matrix6;
using moslam::PoseGraph;
using moslam::Values;
using SparseMatrix = Eigen::SparseMatrix<double>;
using Triplets = std::vector<Eigen::Triplet<double>>;

void AddBlock(Triplets& t, int i, int j, const Matrix6& m) {
  for (int a = 0; a < 6; ++a) {
    for (int b = 0; b < 6; ++b) t.emplace_back(6 * i + a, 6 * j + b, m(a, b));
  }
}

// The unknowns (every variable but the gauge anchor), by robot in key order.
struct Unknowns {
  std::map<Key, int> index;
  std::vector<Key> key;
  std::vector<std::vector<int>> of_robot;
};

Unknowns NumberUnknowns(const PoseGraph& graph, int robots) {
  Unknowns u;
  u.of_robot.resize(static_cast<std::size_t>(robots));
  const Key anchor = moslam::GaugeAnchor(graph);
  for (const Key& k : graph.keys()) {
    if (k == anchor) continue;
    const int i = static_cast<int>(u.key.size());
    u.index[k] = i;
    u.key.push_back(k);
    u.of_robot[static_cast<std::size_t>(k.robot)].push_back(i);
  }
  return u;
}

// H = J^T Omega J and g = J^T Omega r at x, right increments (graph/factors.h).
void Linearize(const PoseGraph& graph, const Values& x, const Unknowns& u, SparseMatrix* H,
               Eigen::VectorXd* g) {
  const int n = static_cast<int>(u.key.size());
  Triplets t;
  *g = Eigen::VectorXd::Zero(6 * n);
  for (const auto& f : graph.factors()) {
    Matrix6 Ja, Jb;
    const moslam::Vector6 r = f.residual(x.at(f.a()), x.at(f.b()), &Ja, &Jb);
    const Matrix6& W = f.information();
    const auto ia = u.index.find(f.a()), ib = u.index.find(f.b());
    const int a = ia == u.index.end() ? -1 : ia->second;
    const int b = ib == u.index.end() ? -1 : ib->second;
    if (a >= 0) {
      AddBlock(t, a, a, Ja.transpose() * W * Ja);
      g->segment<6>(6 * a) += Ja.transpose() * W * r;
    }
    if (b >= 0) {
      AddBlock(t, b, b, Jb.transpose() * W * Jb);
      g->segment<6>(6 * b) += Jb.transpose() * W * r;
    }
    if (a >= 0 && b >= 0) {
      AddBlock(t, a, b, Ja.transpose() * W * Jb);
      AddBlock(t, b, a, Jb.transpose() * W * Ja);
    }
  }
  for (const auto& p : graph.priors()) {
    const auto it = u.index.find(p.key());
    if (it == u.index.end()) continue;
    Matrix6 J;
    const moslam::Vector6 r = p.residual(x.at(p.key()), &J);
    AddBlock(t, it->second, it->second, J.transpose() * p.information() * J);
    g->segment<6>(6 * it->second) += J.transpose() * p.information() * r;
  }
  *H = SparseMatrix(6 * n, 6 * n);
  H->setFromTriplets(t.begin(), t.end());
}

// Selection of a set of unknowns' rows (6 each).
SparseMatrix Selection(const std::vector<int>& unknowns, int n) {
  Triplets t;
  for (std::size_t q = 0; q < unknowns.size(); ++q) {
    for (int a = 0; a < 6; ++a) {
      t.emplace_back(static_cast<int>(6 * q) + a, 6 * unknowns[q] + a, 1.0);
    }
  }
  SparseMatrix S(static_cast<Eigen::Index>(6 * unknowns.size()), 6 * n);
  S.setFromTriplets(t.begin(), t.end());
  return S;
}

// The symmetric block Gauss-Seidel sweeps over the robots, each block solved exactly.
class RobotSweeps {
 public:
  RobotSweeps(const SparseMatrix& H, const Unknowns& u) {
    const int n = static_cast<int>(u.key.size());
    for (const auto& members : u.of_robot) {
      if (members.empty()) continue;
      Robot r;
      const SparseMatrix S = Selection(members, n);
      r.rows = S * H;
      r.own = r.rows * SparseMatrix(S.transpose());
      r.solver = std::make_unique<Eigen::SimplicialLDLT<SparseMatrix>>(r.own);
      if (r.solver->info() != Eigen::Success)
        throw std::runtime_error("a robot's block is singular");
      for (int i : members) {
        for (int a = 0; a < 6; ++a) r.index.push_back(6 * i + a);
      }
      robots_.push_back(std::move(r));
    }
  }
  // One sweep on H z = b, robot after robot (forward or backward), from the z given.
  void sweep(const Eigen::VectorXd& b, Eigen::VectorXd& z, bool forward) const {
    const std::size_t m = robots_.size();
    for (std::size_t q = 0; q < m; ++q) {
      const Robot& r = robots_[forward ? q : m - 1 - q];
      const Eigen::VectorXd own = z(r.index);
      const Eigen::VectorXd rhs = b(r.index) - r.rows * z + r.own * own;
      // Evaluated first: Eigen 3.4 writes a Solve expression assigned to an indexed view wrongly.
      const Eigen::VectorXd solved = r.solver->solve(rhs);
      z(r.index) = solved;
    }
  }

 private:
  struct Robot {
    std::vector<int> index;
    SparseMatrix rows, own;
    std::unique_ptr<Eigen::SimplicialLDLT<SparseMatrix>> solver;
  };
  std::vector<Robot> robots_;
};

// The coarse space of K rigid pieces per robot: P (6n x 6 * pieces), the Galerkin matrix
// P^T H P factorized after Jacobi scaling (as CoarseSystem does).
class PieceCoarseSpace {
 public:
  PieceCoarseSpace(const SparseMatrix& H, const Unknowns& u, const Values& x, int pieces) {
    const int n = static_cast<int>(u.key.size());
    std::vector<int> piece(static_cast<std::size_t>(n));
    int count = 0;
    for (const auto& members : u.of_robot) {
      const int m = static_cast<int>(members.size());
      const int k = std::min(pieces, m);
      for (int q = 0; q < m; ++q) {
        piece[static_cast<std::size_t>(members[static_cast<std::size_t>(q)])] =
            count + static_cast<int>(static_cast<long>(q) * k / m);
      }
      count += k;
    }
    std::vector<Eigen::Vector3d> centre(static_cast<std::size_t>(count), Eigen::Vector3d::Zero());
    std::vector<int> size(static_cast<std::size_t>(count), 0);
    for (int i = 0; i < n; ++i) {
      const auto p = static_cast<std::size_t>(piece[static_cast<std::size_t>(i)]);
      centre[p] += x.at(u.key[static_cast<std::size_t>(i)]).translation();
      ++size[p];
    }
    for (std::size_t p = 0; p < centre.size(); ++p) centre[p] /= size[p];
    Triplets t;
    for (int i = 0; i < n; ++i) {
      const int p = piece[static_cast<std::size_t>(i)];
      Matrix6 S = Matrix6::Identity();
      S.bottomLeftCorner<3, 3>() = moslam::SO3::Hat(centre[static_cast<std::size_t>(p)]);
      const Matrix6 B = x.at(u.key[static_cast<std::size_t>(i)]).inverse().Adjoint() * S;
      for (int a = 0; a < 6; ++a) {
        for (int b = 0; b < 6; ++b) {
          if (B(a, b) != 0.0) t.emplace_back(6 * i + a, 6 * p + b, B(a, b));
        }
      }
    }
    P_ = SparseMatrix(6 * n, 6 * count);
    P_.setFromTriplets(t.begin(), t.end());
    const Eigen::MatrixXd A = Eigen::MatrixXd(SparseMatrix(P_.transpose() * H * P_));
    scale_ = A.diagonal().cwiseSqrt().cwiseInverse();
    llt_.compute(scale_.asDiagonal() * A * scale_.asDiagonal());
    if (llt_.info() != Eigen::Success)
      throw std::runtime_error("coarse matrix not positive definite");
  }
  Eigen::Index size() const { return P_.cols(); }
  // z += P (P^T H P)^-1 P^T r
  void correct(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    const Eigen::VectorXd y =
        scale_.asDiagonal() * llt_.solve(scale_.asDiagonal() * (P_.transpose() * r));
    z += P_ * y;
  }

 private:
  SparseMatrix P_;
  Eigen::VectorXd scale_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

void Study(const SparseMatrix& H, const Eigen::VectorXd& g, const Unknowns& u, const Values& x,
           const std::vector<int>& pieces, int max_iter) {
  const int n = static_cast<int>(u.key.size());
  const Eigen::VectorXd b = -g;
  Eigen::SimplicialLDLT<SparseMatrix> exact(H);
  if (exact.info() != Eigen::Success) throw std::runtime_error("H is not positive definite");
  const Eigen::VectorXd d = exact.solve(b);
  const double decrease = 0.5 * b.dot(d);  // the model's decrease at the exact step
  std::printf("unknowns %d, |g| %.3e; exact step: |d| %.3e, model decrease %.6e\n", n, g.norm(),
              d.norm(), decrease);
  for (std::size_t r = 0; r < u.of_robot.size(); ++r) {
    const auto& members = u.of_robot[r];
    const std::size_t m = members.size();
    std::printf("  robot %zu (%zu unknowns): largest |d_i| per tenth of its unknowns:", r, m);
    for (std::size_t tenth = 0; tenth < 10; ++tenth) {
      double largest = 0.0;
      for (std::size_t q = tenth * m / 10; q < (tenth + 1) * m / 10; ++q) {
        largest = std::max(largest, d.segment<6>(6 * members[q]).norm());
      }
      std::printf(" %.1e", largest);
    }
    std::printf("\n");
  }
  const RobotSweeps sweeps(H, u);
  const std::vector<int> report = {25, 50, 100, 200, 500, 1000, 2000, 5000};
  for (int k : pieces) {
    std::unique_ptr<PieceCoarseSpace> coarse;
    if (k > 0) coarse = std::make_unique<PieceCoarseSpace>(H, u, x, k);
    auto precondition = [&](const Eigen::VectorXd& r) {
      Eigen::VectorXd z = Eigen::VectorXd::Zero(r.size());
      sweeps.sweep(r, z, true);
      if (coarse) coarse->correct(r - H * z, z);
      sweeps.sweep(r, z, false);
      return z;
    };
    Eigen::VectorXd y = Eigen::VectorXd::Zero(6 * n), res = b, z = precondition(res), p = z;
    double rz = res.dot(z);
    const double rz0 = rz;
    int reached = -1;
    std::printf("K = %d (%ld coarse unknowns):", k, static_cast<long>(coarse ? coarse->size() : 0));
    for (int it = 1; it <= max_iter; ++it) {
      const Eigen::VectorXd Hp = H * p;
      const double alpha = rz / p.dot(Hp);
      y += alpha * p;
      res -= alpha * Hp;
      z = precondition(res);
      const double rz1 = res.dot(z);
      if (reached < 0 && std::sqrt(std::abs(rz1 / rz0)) <= 1e-2) reached = it;
      if (std::find(report.begin(), report.end(), it) != report.end()) {
        const double model = b.dot(y) - 0.5 * y.dot(H * y);
        std::printf(" [%d: %.4f]", it, model / decrease);
      }
      p = z + (rz1 / rz) * p;
      rz = rz1;
    }
    if (reached < 0) {
      std::printf("; measure above 1e-2 after %d iterations\n", max_iter);
    } else {
      std::printf("; measure <= 1e-2 after %d iterations\n", reached);
    }
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "The refinement's preconditioned conjugate gradients with K rigid pieces per robot "
      "as the coarse space, at one linearisation point, against the exact step"};
  std::string input;
  int robots = 0, max_iter = 1000;
  std::vector<int> pieces = {0, 1, 16, 64};
  app.add_option("input", input, "folder of robots' g2o files, or one g2o file")->required();
  app.add_option("--robots", robots, "split a single file into N robots")
      ->check(CLI::Range(1, 4096));
  app.add_option("--pieces", pieces,
                 "coarse pieces per robot, one run each (0: no coarse correction)")
      ->check(CLI::Range(0, 4096));
  app.add_option("--max-iter", max_iter, "conjugate-gradient iterations per run")
      ->check(CLI::Range(1, 100000));
  CLI11_PARSE(app, argc, argv);
  try {
    moslam::Dataset data = moslam::ReadG2o(input);
    PoseGraph graph = std::move(data.graph);
    Values x = data.initial.empty() ? moslam::ChordalInitialization(graph) : data.initial;
    if (robots > 0) {
      moslam::SplitGraph split = moslam::SplitIntoRobots(graph, x, robots);
      graph = std::move(split.graph);
      x = std::move(split.initial);
    }
    for (const Key& k : graph.keys()) {
      if (x.count(k) == 0) {
        throw std::runtime_error("variable " + moslam::ToString(k) +
                                 " has no vertex: the point must give every variable");
      }
    }
    const Unknowns u = NumberUnknowns(graph, graph.numRobots());
    SparseMatrix H;
    Eigen::VectorXd g;
    Linearize(graph, x, u, &H, &g);
    std::printf("%s: %d robots, cost %.10g at the point\n", input.c_str(), graph.numRobots(),
                graph.cost(x));
    Study(H, g, u, x, pieces, max_iter);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
