// Test-only helpers: central-difference derivatives under the right-perturbation convention of
// se3.h, and the fixtures every Jacobian is checked at (random, near identity, near pi).
#pragma once

#include <Eigen/Dense>
#include <random>
#include <vector>

#include "moslam/geometry/se3.h"

namespace moslam::test {

// Local coordinates of a value type: vectors subtract, groups take Log(a^-1 b).
inline Eigen::VectorXd Local(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return b - a; }
inline Eigen::VectorXd Local(const SE3& a, const SE3& b) { return SE3::Log(a.between(b)); }
inline Eigen::VectorXd Local(const SO3& a, const SO3& b) { return SO3::Log(a.inverse() * b); }

inline SE3 Perturb(const SE3& x, const Eigen::VectorXd& d) { return x.retract(d); }
inline SO3 Perturb(const SO3& x, const Eigen::VectorXd& d) { return x * SO3::Exp(d); }
inline Eigen::VectorXd Perturb(const Eigen::VectorXd& x, const Eigen::VectorXd& d) { return x + d; }

inline int Dim(const SE3&) { return 6; }
inline int Dim(const SO3&) { return 3; }
inline int Dim(const Eigen::VectorXd& x) { return static_cast<int>(x.size()); }

// d f(x (+) d) / d d at d = 0 by central differences; f's value type must have Local().
template <typename F, typename X>
Eigen::MatrixXd NumericalDerivative(F&& f, const X& x, double h = 1e-6) {
  const auto fx = f(x);
  const int n = Dim(x);
  Eigen::MatrixXd J(Local(fx, fx).size(), n);
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd d = Eigen::VectorXd::Zero(n);
    d(i) = h;
    J.col(i) = (Local(fx, f(Perturb(x, d))) - Local(fx, f(Perturb(x, -d)))) / (2.0 * h);
  }
  return J;
}

// Poses at which every Jacobian is checked: seeded random ones, rotations of 1e-5 rad and of
// pi - 1e-5 rad about random axes, and the identity.
inline std::vector<SE3> LieFixtures(unsigned seed = 7, int num_random = 20) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  auto axis = [&] { return Vector3(n01(rng), n01(rng), n01(rng)).normalized(); };
  auto trans = [&] { return Vector3(3.0 * n01(rng), 3.0 * n01(rng), 3.0 * n01(rng)); };
  std::vector<SE3> out{SE3()};
  for (int i = 0; i < num_random; ++i) {
    std::uniform_real_distribution<double> angle(0.0, 3.14159);
    out.emplace_back(SO3::Exp(angle(rng) * axis()), trans());
  }
  for (double angle : {1e-5, 3.14159265358979323846 - 1e-5}) {
    for (int i = 0; i < 4; ++i) out.emplace_back(SO3::Exp(angle * axis()), trans());
  }
  return out;
}

}  // namespace moslam::test
