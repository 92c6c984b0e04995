#include "moslam/render/rgbd.h"

#include <cmath>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

PinholeIntrinsics PinholeIntrinsics::FromHorizontalFov(int width, int height,
                                                       double horizontal_fov_deg) {
  if (!(horizontal_fov_deg > 0.0 && horizontal_fov_deg < 180.0)) {
    throw InvalidInputError("PinholeIntrinsics: horizontal_fov_deg must be in (0, 180), got " +
                            std::to_string(horizontal_fov_deg));
  }
  PinholeIntrinsics k;
  k.width = width;
  k.height = height;
  const double half = 0.5 * horizontal_fov_deg * 3.14159265358979323846 / 180.0;
  k.fx = k.fy = 0.5 * width / std::tan(half);
  k.cx = 0.5 * (width - 1);
  k.cy = 0.5 * (height - 1);
  k.validate();
  return k;
}

void PinholeIntrinsics::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("PinholeIntrinsics: " + m); };
  if (width <= 0 || width > 16384) bad("width must be in [1, 16384]");
  if (height <= 0 || height > 16384) bad("height must be in [1, 16384]");
  if (!(fx > 0.0) || !std::isfinite(fx)) bad("fx must be positive and finite");
  if (!(fy > 0.0) || !std::isfinite(fy)) bad("fy must be positive and finite");
  if (!std::isfinite(cx)) bad("cx must be finite");
  if (!std::isfinite(cy)) bad("cy must be finite");
}

void AxialDepthNoise::validate(const std::string& prefix) const {
  auto bad = [&](const std::string& field, const std::string& m) {
    throw InvalidInputError(prefix + field + " " + m);
  };
  if (!(a >= 0.0) || !std::isfinite(a)) bad("a", "must be >= 0 and finite");
  if (!(b >= 0.0) || !std::isfinite(b)) bad("b", "must be >= 0 and finite");
  if (!std::isfinite(z0)) bad("z0", "must be finite");
}

SE3 BodyFromCamera() {
  // Columns: the camera's x (right), y (down), z (forward) axes expressed in the body frame.
  Matrix3 R;
  R << 0.0, 0.0, 1.0,  //
      -1.0, 0.0, 0.0,  //
      0.0, -1.0, 0.0;
  return SE3(SO3(R), Vector3::Zero());
}

}  // namespace moslam
