#include "moslam/graph/factors.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
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

// Validates `information` and returns its upper Cholesky factor U (U^T U = information).
Matrix6 CheckedSqrtInformation(const Matrix6& information, const std::string& what) {
  ValidateInformation(information, what);
  Eigen::LLT<Matrix6> llt(information);
  Matrix6 U = llt.matrixU();
  if (llt.info() != Eigen::Success || !U.allFinite()) {
    throw InvalidInputError(what + ": information matrix has no finite Cholesky factor "
                                   "(entries too large?)");
  }
  return U;
}

}  // namespace

void ValidateInformation(const Matrix6& information, const std::string& what) {
  if (!information.allFinite()) {
    throw InvalidInputError(what + ": information matrix has NaN or Inf entries");
  }
  const double scale = information.cwiseAbs().maxCoeff();
  if ((information - information.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    throw InvalidInputError(what + ": information matrix is not symmetric");
  }
  Eigen::SelfAdjointEigenSolver<Matrix6> eig(information);
  if (!eig.eigenvalues().allFinite()) {
    throw InvalidInputError(what + ": information matrix entries are too large (its eigenvalues "
                                   "overflow double precision)");
  }
  const double min_eig = eig.eigenvalues().minCoeff();
  if (!(min_eig > 0.0) || min_eig < 1e-14 * eig.eigenvalues().maxCoeff()) {
    std::ostringstream os;
    os << what << ": information matrix is not positive definite (smallest eigenvalue " << min_eig
       << "); a zero row, e.g. an unmeasured axis, needs a small positive weight instead";
    throw InvalidInputError(os.str());
  }
}

RelativePoseFactor::RelativePoseFactor(Key a, Key b, const SE3& measured,
                                       const Matrix6& information)
    : a_(a), b_(b), z_(measured), information_(Symmetrized(information)) {
  const std::string what = "factor " + ToString(a) + " -> " + ToString(b);
  if (a == b) throw InvalidInputError(what + ": both ends are the same variable");
  if (!IsFinite(measured)) throw InvalidInputError(what + ": measurement has NaN or Inf");
  ValidateInformation(information, what);  // the matrix as given: symmetry is checked here
  sqrt_information_ = CheckedSqrtInformation(information_, what);
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
  const std::string what = "prior on " + ToString(key);
  if (!IsFinite(prior)) throw InvalidInputError(what + ": prior has NaN or Inf");
  ValidateInformation(information, what);
  sqrt_information_ = CheckedSqrtInformation(information_, what);
}

Vector6 PriorFactor::residual(const SE3& x, Matrix6* H) const {
  return SE3::Log(z_.between(x), H);
}

double PriorFactor::cost(const SE3& x) const {
  return 0.5 * (sqrt_information_ * residual(x)).squaredNorm();
}

}  // namespace moslam
