// Factors of the moslam pose graph. Every measurement is one relative-pose ("between") residual:
//
//   r(a, b) = Log(z^-1 * a^-1 * b)            in R^6, tangent order (w, v)
//   cost    = 1/2 r^T Omega r                 Omega: 6x6 symmetric positive definite
//
//   odometry:      a = x_{alpha,i}, b = x_{alpha,i+1}, z = measured motion
//   object-pose:   a = x_{alpha,i}, b = o_{alpha,k},   z = object pose in the robot frame
//   object-object: a = o_{beta,l},  b = o_{alpha,k},   z = identity, Omega = Lambda
//
// A prior on one variable is r(x) = Log(z^-1 * x). Jacobians are with respect to right
// perturbations a Exp(da), b Exp(db) (see geometry/se3.h):
//   dr/db = Jr^-1(r),   dr/da = -Jr^-1(r) Ad(b^-1 a).
// This matches GTSAM's BetweenFactor<Pose3>/PriorFactor<Pose3> error, so costs are comparable.
#pragma once

#include "moslam/geometry/se3.h"
#include "moslam/graph/key.h"

namespace moslam {

// Throws InvalidInputError unless `information` is finite, symmetric (to 1e-9 relative) and
// positive definite. `what` prefixes the message.
void ValidateInformation(const Matrix6& information, const std::string& what);

class RelativePoseFactor {
 public:
  // Validates the measurement (finite) and the information (SPD); throws InvalidInputError.
  RelativePoseFactor(Key a, Key b, const SE3& measured, const Matrix6& information);

  Key a() const { return a_; }
  Key b() const { return b_; }
  const SE3& measured() const { return z_; }
  const Matrix6& information() const { return information_; }
  // Upper-triangular U with U^T U = Omega: the whitened residual is U r.
  const Matrix6& sqrtInformation() const { return sqrt_information_; }

  Vector6 residual(const SE3& xa, const SE3& xb, Matrix6* Ha = nullptr,
                   Matrix6* Hb = nullptr) const;
  double cost(const SE3& xa, const SE3& xb) const;

 private:
  Key a_, b_;
  SE3 z_;
  Matrix6 information_;
  Matrix6 sqrt_information_;
};

class PriorFactor {
 public:
  PriorFactor(Key key, const SE3& prior, const Matrix6& information);

  Key key() const { return key_; }
  const SE3& prior() const { return z_; }
  const Matrix6& information() const { return information_; }
  const Matrix6& sqrtInformation() const { return sqrt_information_; }

  Vector6 residual(const SE3& x, Matrix6* H = nullptr) const;
  double cost(const SE3& x) const;

 private:
  Key key_;
  SE3 z_;
  Matrix6 information_;
  Matrix6 sqrt_information_;
};

}  // namespace moslam
