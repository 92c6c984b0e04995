#include "moslam/graph/factors.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

bool IsFinite(const SE3& x) {
  return x.rotation().matrix().allFinite() && x.translation().allFinite();
}

Matrix6 Symmetrized(const Matrix6& information) {
  return 0.5 * information + 0.5 * information.transpose();  // no overflow near DBL_MAX
}

// Whether the symmetric part S of `information` has condition number below 1e14: its smallest
// eigenvalue is at least 1e-14 times its largest. The test of ValidateInformation, decided
// exactly by an eigen-decomposition only when a cheap certificate cannot: with S = U^T U
// (Cholesky), lambda_min(S) = 1 / ||U^-1||_2^2 >= 1 / ||U^-1||_F^2 and lambda_max(S) <=
// trace(S), so 1 / ||U^-1||_F^2 >= 1e-14 trace(S) proves it (it holds for every information
// matrix that is not nearly singular; the eigen-decomposition costs ten times the Cholesky).
struct InformationCheck {
  bool symmetric = false, finite = false, positive_definite = false;
  double min_eigenvalue = 0.0;  // set when the eigen-decomposition ran
  Matrix6 U = Matrix6::Zero();  // the upper Cholesky factor of S when positive definite
};

InformationCheck CheckInformation(const Matrix6& information) {
  InformationCheck c;
  c.finite = information.allFinite();
  if (!c.finite) return c;
  const double scale = information.cwiseAbs().maxCoeff();
  c.symmetric = (information - information.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale;
  if (!c.symmetric) return c;
  const Matrix6 S = Symmetrized(information);
  const Eigen::LLT<Matrix6> llt(S);
  if (llt.info() == Eigen::Success) {
    c.U = llt.matrixU();
    const Matrix6 U_inv = c.U.triangularView<Eigen::Upper>().solve(Matrix6::Identity());
    const double bound = 1.0 / U_inv.squaredNorm();  // <= lambda_min
    if (c.U.allFinite() && std::isfinite(bound) && bound >= 1e-14 * S.trace()) {
      c.positive_definite = true;
      return c;
    }
  }
  Eigen::SelfAdjointEigenSolver<Matrix6> eig(S, Eigen::EigenvaluesOnly);
  c.min_eigenvalue = eig.eigenvalues().minCoeff();
  c.positive_definite = eig.eigenvalues().allFinite() && c.min_eigenvalue > 0.0 &&
                        c.min_eigenvalue >= 1e-14 * eig.eigenvalues().maxCoeff() &&
                        llt.info() == Eigen::Success && c.U.allFinite();
  if (!eig.eigenvalues().allFinite()) c.finite = false;  // overflow inside the decomposition
  return c;
}

// Throws InvalidInputError unless the check passed; `what()` names the factor (built only here).
template <typename What>
const Matrix6& RequireValid(const InformationCheck& c, What what) {
  if (c.positive_definite) return c.U;
  if (!c.finite) {
    throw InvalidInputError(what() + ": information matrix has NaN or Inf entries (or entries "
                                     "so large that its eigenvalues overflow double precision)");
  }
  if (!c.symmetric) throw InvalidInputError(what() + ": information matrix is not symmetric");
  std::ostringstream os;
  os << what() << ": information matrix is not positive definite (smallest eigenvalue "
     << c.min_eigenvalue
     << "); a zero row, e.g. an unmeasured axis, needs a small positive weight instead";
  throw InvalidInputError(os.str());
}

}  // namespace

void ValidateInformation(const Matrix6& information, const std::string& what) {
  RequireValid(CheckInformation(information), [&] { return what; });
}

RelativePoseFactor::RelativePoseFactor(Key a, Key b, const SE3& measured,
                                       const Matrix6& information)
    : a_(a), b_(b), z_(measured), information_(Symmetrized(information)) {
  const auto what = [&] { return "factor " + ToString(a) + " -> " + ToString(b); };
  if (a == b) throw InvalidInputError(what() + ": both ends are the same variable");
  if (!IsFinite(measured)) throw InvalidInputError(what() + ": measurement has NaN or Inf");
  sqrt_information_ = RequireValid(CheckInformation(information), what);
}

Vector6 RelativePoseFactor::residual(const SE3& xa, const SE3& xb, Matrix6* Ha,
                                     Matrix6* Hb) const {
  const SE3 ab = xa.between(xb);
  const SE3 e = z_.between(ab);  // z^-1 a^-1 b
  if (!Ha && !Hb) return SE3::Log(e);
  Matrix6 Jlog;
  const Vector6 r = SE3::Log(e, &Jlog);
  if (Hb) *Hb = Jlog;
  // e(a Exp(d)) = e Exp(-Ad(b^-1 a) d)
  if (Ha) *Ha = -Jlog * ab.inverse().Adjoint();
  return r;
}

double RelativePoseFactor::cost(const SE3& xa, const SE3& xb) const {
  return 0.5 * (sqrt_information_ * residual(xa, xb)).squaredNorm();
}

PriorFactor::PriorFactor(Key key, const SE3& prior, const Matrix6& information)
    : key_(key), z_(prior), information_(Symmetrized(information)) {
  const auto what = [&] { return "prior on " + ToString(key); };
  if (!IsFinite(prior)) throw InvalidInputError(what() + ": prior has NaN or Inf");
  sqrt_information_ = RequireValid(CheckInformation(information), what);
}

Vector6 PriorFactor::residual(const SE3& x, Matrix6* H) const {
  return SE3::Log(z_.between(x), H);
}

double PriorFactor::cost(const SE3& x) const {
  return 0.5 * (sqrt_information_ * residual(x)).squaredNorm();
}

}  // namespace moslam
