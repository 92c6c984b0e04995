#include "moslam/pose_estimation/depth_smoothing.h"

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

bool Finite(const OrganizedPoint& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && p.z > 0.0f;
}

// The angle between neighbouring pixels' rays (1 / fx) from two finite points of one row:
// x / z = (u - cx) / fx is exact whatever the depth noise. 0 if the cloud has no such pair.
double RayPitch(const OrganizedCloud& cloud, const std::vector<int>& indices) {
  const std::size_t w = cloud.width;
  for (std::size_t k = 1; k < indices.size(); ++k) {
    const auto a = static_cast<std::size_t>(indices[k - 1]);
    const auto b = static_cast<std::size_t>(indices[k]);
    if (a / w != b / w || a % w == b % w) continue;
    const double du = static_cast<double>(b % w) - static_cast<double>(a % w);
    const double pitch = (cloud[b].x / cloud[b].z - cloud[a].x / cloud[a].z) / du;
    if (std::isfinite(pitch) && pitch > 0.0) return pitch;
  }
  return 0.0;
}

// The smoothed inverse depth of segment point i (noise sigma at its depth): a weighted least
// squares fit of q = 1 / z on (1, dx, dy) over the segment's points within config.radius
// laterally (dx, dy in metres at its depth; weights Gaussian in that distance and in the depth
// difference, range_sigmas * sigma), its constant term; the weighted mean when fewer than
// min_neighbours points or too little lateral spread (a one-pixel-wide strip) leave the plane
// undetermined.
double FittedInverseDepth(const OrganizedCloud& cloud, const std::vector<char>& in_segment,
                          std::size_t i, double pitch, double sigma,
                          const DepthSmoothingConfig& config) {
  const std::size_t w = cloud.width, h = cloud.height;
  const double spatial_var = 0.25 * config.radius * config.radius;  // (radius / 2)^2
  const OrganizedPoint& p = cloud[i];
  const double z = p.z;
  const double rx = p.x / z, ry = p.y / z;
  const int window =
      std::min(config.max_window, static_cast<int>(std::ceil(config.radius / (z * pitch))));
  const double range_var = 2.0 * std::pow(config.range_sigmas * sigma, 2);
  const int u0 = static_cast<int>(i % w), v0 = static_cast<int>(i / w);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  int used = 0;
  for (int v = std::max(0, v0 - window); v <= std::min(static_cast<int>(h) - 1, v0 + window); ++v) {
    for (int u = std::max(0, u0 - window); u <= std::min(static_cast<int>(w) - 1, u0 + window);
         ++u) {
      const std::size_t j = static_cast<std::size_t>(v) * w + static_cast<std::size_t>(u);
      if (!in_segment[j]) continue;
      const OrganizedPoint& q = cloud[j];
      const double dx = z * (q.x / q.z - rx), dy = z * (q.y / q.z - ry);
      const double d2 = dx * dx + dy * dy;
      if (d2 > config.radius * config.radius) continue;
      const double dz = static_cast<double>(q.z) - z;
      const double weight = std::exp(-0.5 * d2 / spatial_var - 0.5 * dz * dz / range_var);
      const Eigen::Vector3d phi(1.0, dx, dy);
      A.noalias() += weight * phi * phi.transpose();
      b.noalias() += weight * phi / static_cast<double>(q.z);
      ++used;
    }
  }
  double inverse_depth = b(0) / A(0, 0);  // the weighted mean
  if (used >= config.min_neighbours) {
    // The fit needs lateral spread in both directions: the weighted covariance of (dx, dy)
    // must not be degenerate (a one-pixel-wide strip).
    const Eigen::Vector2d mean = A.block<2, 1>(1, 0) / A(0, 0);
    const Eigen::Matrix2d cov = A.block<2, 2>(1, 1) / A(0, 0) - mean * mean.transpose();
    const double min_spread = std::pow(0.1 * config.radius, 2);
    if (cov.determinant() > min_spread * min_spread && cov.trace() > 2.0 * min_spread) {
      const Eigen::Vector3d coefficients = A.ldlt().solve(b);
      if (coefficients.allFinite() && coefficients(0) > 0.0) inverse_depth = coefficients(0);
    }
  }
  return inverse_depth;
}

}  // namespace

void DepthSmoothingConfig::validate(const std::string& prefix) const {
  auto require = [&](bool ok, const char* field, const char* what) {
    if (!ok) throw InvalidInputError(prefix + field + " " + what);
  };
  require(std::isfinite(radius) && radius > 0.0, "radius", "must be positive (m)");
  require(std::isfinite(range_sigmas) && range_sigmas > 0.0, "range_sigmas", "must be positive");
  require(max_window >= 1 && max_window <= 64, "max_window", "must be in [1, 64] pixels");
  require(min_neighbours >= 3, "min_neighbours", "must be >= 3 (a linear fit has 3 unknowns)");
  require(std::isfinite(min_noise) && min_noise >= 0.0, "min_noise", "must be >= 0 (m)");
}

OrganizedCloud::Ptr SmoothAlongRays(const OrganizedCloud& cloud, const std::vector<int>& indices,
                                    const AxialDepthNoise& noise,
                                    const DepthSmoothingConfig& config) {
  config.validate();
  noise.validate("SmoothAlongRays noise model: ");
  if (cloud.height <= 1 || cloud.width == 0) {
    throw InvalidInputError(
        "SmoothAlongRays: the cloud is not organized (height " + std::to_string(cloud.height) +
        "); smoothing along rays needs the pixel grid of the RGB-D frame");
  }
  const std::size_t n = cloud.size();
  std::vector<char> in_segment(n, 0);
  for (int index : indices) {
    if (index < 0 || static_cast<std::size_t>(index) >= n || !Finite(cloud[index])) {
      throw InvalidInputError("SmoothAlongRays: segment index " + std::to_string(index) +
                              " is outside the cloud or has no finite depth; the indices must "
                              "be those of the segment's points in this frame's cloud");
    }
    in_segment[static_cast<std::size_t>(index)] = 1;
  }

  auto out = std::make_shared<OrganizedCloud>();
  out->reserve(indices.size());
  for (int index : indices) out->push_back(cloud[index]);
  out->is_dense = true;
  const double pitch = RayPitch(cloud, indices);
  if (!config.enabled || pitch <= 0.0) return out;

  for (std::size_t k = 0; k < indices.size(); ++k) {
    const auto i = static_cast<std::size_t>(indices[k]);
    const OrganizedPoint& p = cloud[i];
    const double z = p.z;
    const double sigma = noise.sigma(z);
    if (sigma < config.min_noise) continue;
    const double inverse_depth = FittedInverseDepth(cloud, in_segment, i, pitch, sigma, config);
    if (!(inverse_depth > 0.0) || !std::isfinite(inverse_depth)) continue;
    const float scale = static_cast<float>((1.0 / inverse_depth) / z);
    OrganizedPoint& o = (*out)[k];
    o.x = p.x * scale;
    o.y = p.y * scale;
    o.z = p.z * scale;
  }
  return out;
}

}  // namespace moslam
