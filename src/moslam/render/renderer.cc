#include "moslam/render/renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

constexpr double kNearClip = 0.02;      // m: triangles are clipped to z >= this
constexpr double kFloorMaxDepth = 60.0;  // m: farther floor pixels show the background
constexpr int kNothing = -1;
constexpr int kFloor = -2;

std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// The walls of the world's rooms with door gaps where navigation edges cross a side.
Mesh BuildWalls(const World& world, double height, double door_width, const cv::Vec3b& colour) {
  Mesh m;
  m.closed = false;
  Material wall;
  wall.colour_bgr = colour;
  wall.secondary_bgr = cv::Vec3b(static_cast<uchar>(colour[0] * 0.93),
                                 static_cast<uchar>(colour[1] * 0.93),
                                 static_cast<uchar>(colour[2] * 0.93));
  wall.pattern = Material::Pattern::kStripes;
  wall.axis = 2;
  wall.period_m = 1.1;  // a subtle two-tone band (dado rail) so walls are not featureless
  const int wall_mat = m.addMaterial(wall);
  Material base;
  base.colour_bgr = base.secondary_bgr = cv::Vec3b(60, 60, 70);
  const int base_mat = m.addMaterial(base);
  const double base_h = std::min(0.1, 0.5 * height);
  std::vector<std::array<Vector2, 2>> done;
  for (const Room& r : world.rooms) {
    const std::array<Vector2, 4> c = {r.min, Vector2(r.max.x(), r.min.y()), r.max,
                                      Vector2(r.min.x(), r.max.y())};
    for (int k = 0; k < 4; ++k) {
      const Vector2 a = c[static_cast<std::size_t>(k)], b = c[static_cast<std::size_t>((k + 1) % 4)];
      // A side shared by two rooms is built once.
      bool dup = false;
      for (const auto& s : done) {
        if (((s[0] - a).norm() < 1e-9 && (s[1] - b).norm() < 1e-9) ||
            ((s[0] - b).norm() < 1e-9 && (s[1] - a).norm() < 1e-9)) {
          dup = true;
        }
      }
      if (dup) continue;
      done.push_back({a, b});
      const Vector2 d = b - a;
      const double len = d.norm();
      std::vector<std::pair<double, double>> gaps;
      for (const auto& [i, j] : world.navigation.edges) {
        const Vector2 p = world.navigation.nodes[static_cast<std::size_t>(i)];
        const Vector2 q = world.navigation.nodes[static_cast<std::size_t>(j)];
        const Vector2 e = q - p;
        const double den = d.x() * e.y() - d.y() * e.x();
        if (std::abs(den) < 1e-12) continue;
        const Vector2 ap = p - a;
        const double s = (ap.x() * e.y() - ap.y() * e.x()) / den;  // along the side
        const double t = (ap.x() * d.y() - ap.y() * d.x()) / den;  // along the edge
        if (s < 0.0 || s > 1.0 || t < 0.0 || t > 1.0) continue;
        gaps.emplace_back(s * len - 0.5 * door_width, s * len + 0.5 * door_width);
      }
      std::sort(gaps.begin(), gaps.end());
      std::vector<std::pair<double, double>> solid;
      double from = 0.0;
      for (const auto& g : gaps) {
        if (g.first > from) solid.emplace_back(from, std::min(g.first, len));
        from = std::max(from, g.second);
      }
      if (from < len) solid.emplace_back(from, len);
      const Vector2 dir = d / len;
      const Vector3 normal(-dir.y(), dir.x(), 0.0);
      for (const auto& [s0, s1] : solid) {
        if (s1 - s0 < 1e-6) continue;
        const Vector2 p0 = a + s0 * dir, p1 = a + s1 * dir;
        auto quad = [&](double z0, double z1, int mat) {
          m.addQuad(Vector3(p0.x(), p0.y(), z0), Vector3(p1.x(), p1.y(), z0),
                    Vector3(p1.x(), p1.y(), z1), Vector3(p0.x(), p0.y(), z1), normal, mat);
        };
        quad(0.0, base_h, base_mat);
        quad(base_h, height, wall_mat);
      }
    }
  }
  return m;
}

// Sutherland-Hodgman clip of a polygon to z >= kNearClip.
int ClipNear(const std::array<Vector3, 3>& in, std::array<Vector3, 4>& out) {
  int n = 0;
  for (int i = 0; i < 3; ++i) {
    const Vector3& a = in[static_cast<std::size_t>(i)];
    const Vector3& b = in[static_cast<std::size_t>((i + 1) % 3)];
    const bool ia = a.z() >= kNearClip, ib = b.z() >= kNearClip;
    if (ia) out[static_cast<std::size_t>(n++)] = a;
    if (ia != ib) {
      const double s = (kNearClip - a.z()) / (b.z() - a.z());
      out[static_cast<std::size_t>(n++)] = a + s * (b - a);
    }
  }
  return n;
}

cv::Vec3b Scale(const cv::Vec3b& c, double f) {
  return cv::Vec3b(cv::saturate_cast<uchar>(c[0] * f), cv::saturate_cast<uchar>(c[1] * f),
                   cv::saturate_cast<uchar>(c[2] * f));
}

// Z-buffered scan conversion of one screen triangle (vertex columns u, rows v, inverse depths
// iz): pixel centres inside it (edge functions >= 0) nearer than the buffer are written. Per
// row, the span inside all three edges is solved from the (linear) edge functions, and the
// inverse depth, affine in screen space, is evaluated along it.
void RasterizeTriangle(const std::array<double, 3>& u, const std::array<double, 3>& v,
                       const std::array<double, 3>& iz, int item, int triangle, cv::Mat& inv_z,
                       cv::Mat& item_buf, cv::Mat& tri_buf, cv::Mat& own_buf, int& own_pixels) {
  const int W = inv_z.cols, H = inv_z.rows;
  const double area = (u[1] - u[0]) * (v[2] - v[0]) - (v[1] - v[0]) * (u[2] - u[0]);
  if (std::abs(area) < 1e-12) return;
  const double sign = area > 0.0 ? 1.0 : -1.0;
  // Edge i (opposite vertex i): E_i(p) = a_i pu + b_i pv + c_i, >= 0 inside; E_i / |area| is
  // the barycentric weight of vertex i.
  std::array<double, 3> a{}, b{}, c{};
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    a[i] = sign * (v[j] - v[k]);
    b[i] = sign * (u[k] - u[j]);
    c[i] = sign * (u[j] * v[k] - u[k] * v[j]);
  }
  const double inv_area = 1.0 / std::abs(area);
  // Inverse depth as an affine function of (pu, pv).
  double za = 0.0, zb = 0.0, zc = 0.0;
  for (std::size_t i = 0; i < 3; ++i) {
    za += iz[i] * a[i] * inv_area;
    zb += iz[i] * b[i] * inv_area;
    zc += iz[i] * c[i] * inv_area;
  }
  const int vmin = std::max(0, static_cast<int>(std::ceil(std::min({v[0], v[1], v[2]}))));
  const int vmax = std::min(H - 1, static_cast<int>(std::floor(std::max({v[0], v[1], v[2]}))));
  const double umin_t = std::min({u[0], u[1], u[2]}), umax_t = std::max({u[0], u[1], u[2]});
  for (int row = vmin; row <= vmax; ++row) {
    double lo = std::max(0.0, std::ceil(umin_t)), hi = std::min(W - 1.0, std::floor(umax_t));
    bool empty = false;
    for (std::size_t i = 0; i < 3; ++i) {
      const double rest = b[i] * row + c[i];
      const double tol = 1e-9 * (std::abs(rest) + 1.0);
      if (std::abs(a[i]) < 1e-15) {
        if (rest < -tol) empty = true;
      } else if (a[i] > 0.0) {
        lo = std::max(lo, std::ceil(-rest / a[i] - 1e-9));
      } else {
        hi = std::min(hi, std::floor(-rest / a[i] + 1e-9));
      }
    }
    if (empty || lo > hi) continue;
    auto* zr = inv_z.ptr<double>(row);
    auto* it = item_buf.ptr<int>(row);
    auto* tr = tri_buf.ptr<int>(row);
    auto* own = own_buf.ptr<int>(row);
    const double z_row = zb * row + zc;
    for (int col = static_cast<int>(lo); col <= static_cast<int>(hi); ++col) {
      if (own[col] != item) {  // the item's own silhouette, whatever is in front of it
        own[col] = item;
        ++own_pixels;
      }
      const double z_inv = za * col + z_row;
      if (z_inv <= zr[col]) continue;
      zr[col] = z_inv;
      it[col] = item;
      tr[col] = triangle;
    }
  }
}

}  // namespace

double VisibleObject::visibleFraction() const {
  if (silhouette_pixels <= 0) return 0.0;
  const double unoccluded =
      std::min(1.0, static_cast<double>(visible_pixels) / static_cast<double>(silhouette_pixels));
  return unoccluded * std::clamp(in_image_fraction, 0.0, 1.0);
}

SceneStyle RandomSceneStyle(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto colour = [&](double lo, double hi) {
    const double base = lo + (hi - lo) * u(rng);
    // A warm or cool tint.
    const double tb = 0.85 + 0.3 * u(rng), tg = 0.85 + 0.3 * u(rng), tr = 0.85 + 0.3 * u(rng);
    return cv::Vec3b(cv::saturate_cast<uchar>(base * tb), cv::saturate_cast<uchar>(base * tg),
                     cv::saturate_cast<uchar>(base * tr));
  };
  SceneStyle s;
  s.floor_a_bgr = colour(90.0, 200.0);
  s.floor_b_bgr = Scale(s.floor_a_bgr, 0.75 + 0.2 * u(rng));
  s.floor_tile_m = 0.3 + 0.5 * u(rng);
  s.wall_bgr = colour(160.0, 240.0);
  s.background_bgr = colour(40.0, 110.0);
  const double az = 2.0 * 3.14159265358979323846 * u(rng);
  const double el = 0.8 + 0.6 * u(rng);  // rad above the horizon
  s.light_direction = Vector3(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  s.ambient = 0.35 + 0.2 * u(rng);
  s.diffuse = 0.45 + 0.25 * u(rng);
  return s;
}

void RenderConfig::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("RenderConfig: " + m); };
  try {
    intrinsics.validate();
  } catch (const InvalidInputError& e) {
    bad(std::string("intrinsics: ") + e.what());
  }
  if (!(min_depth > 0.0) || !std::isfinite(min_depth)) bad("min_depth must be positive");
  if (!(max_depth > min_depth) || !std::isfinite(max_depth)) bad("max_depth must be > min_depth");
  if (!(wall_height > 0.0) || !std::isfinite(wall_height)) bad("wall_height must be positive");
  if (!(door_width >= 0.0) || !std::isfinite(door_width)) bad("door_width must be >= 0");
  if (!(style.floor_tile_m > 0.0) || !std::isfinite(style.floor_tile_m)) {
    bad("style.floor_tile_m must be positive");
  }
  if (!style.light_direction.allFinite() || style.light_direction.norm() < 1e-9) {
    bad("style.light_direction must be a finite non-zero vector");
  }
  if (!(style.ambient >= 0.0) || !(style.diffuse >= 0.0) || !std::isfinite(style.ambient) ||
      !std::isfinite(style.diffuse)) {
    bad("style.ambient and style.diffuse must be >= 0");
  }
  depth_noise_model.validate("RenderConfig: depth_noise_model.");
  if (!(colour_noise_sigma >= 0.0) || !std::isfinite(colour_noise_sigma)) {
    bad("colour_noise_sigma must be >= 0");
  }
}

Renderer::Renderer(const World& world, const RenderConfig& config)
    : world_(world), config_(config) {
  config_.validate();
  ValidateWorld(world_, "Renderer world '" + world_.name + "'");
  models_.reserve(world_.classes.size());
  for (const auto& c : world_.classes) {
    model_labels_.push_back(c.label);
    models_.push_back(MakeObjectMesh(c));
  }
  if (config_.draw_walls) {
    walls_ = BuildWalls(world_, config_.wall_height, config_.door_width, config_.style.wall_bgr);
    if (walls_.size() > 0) items_.push_back({&walls_, SE3(), -1});
  }
  for (std::size_t i = 0; i < world_.objects.size(); ++i) {
    const Mesh* mesh = model(world_.objects[i].label);
    items_.push_back({mesh, world_.objects[i].pose, static_cast<int>(i)});
  }
}

const Mesh* Renderer::model(const std::string& label) const {
  for (std::size_t i = 0; i < model_labels_.size(); ++i) {
    if (model_labels_[i] == label) return &models_[i];
  }
  return nullptr;
}

namespace {

// The floor's pixels, by its analytic ray-plane intersection (before the objects).
void DrawFloor(const PinholeIntrinsics& K, const Matrix3& R_wc, const Vector3& c_w, cv::Mat& inv_z,
               cv::Mat& item_buf) {
  if (c_w.z() <= 0.0) return;
  for (int v = 0; v < K.height; ++v) {
    auto* iz = inv_z.ptr<double>(v);
    auto* it = item_buf.ptr<int>(v);
    const double y = (v - K.cy) / K.fy;
    for (int u = 0; u < K.width; ++u) {
      const Vector3 d = R_wc * Vector3((u - K.cx) / K.fx, y, 1.0);
      if (d.z() >= 0.0) continue;
      const double z = -c_w.z() / d.z();
      if (z > kFloorMaxDepth) continue;
      iz[u] = 1.0 / z;
      it[u] = kFloor;
    }
  }
}

// The sensor on the rendered depth and colour: the depth noise (with the frame's random stream),
// then the depth range and quantization (by the true depth, inverse in `inv_z`), then the colour
// noise from the same stream.
void ApplySensor(const RenderConfig& config, std::uint64_t frame_key, const cv::Mat& inv_z,
                 cv::Mat& depth, cv::Mat& colour) {
  const int H = depth.rows, W = depth.cols;
  cv::RNG rng(SplitMix64(SplitMix64(config.seed) ^ frame_key));
  if (config.depth_noise) {
    cv::Mat n(H, W, CV_32FC1);
    rng.fill(n, cv::RNG::NORMAL, 0.0, 1.0);
    for (int v = 0; v < H; ++v) {
      auto* d = depth.ptr<float>(v);
      const auto* e = n.ptr<float>(v);
      for (int u = 0; u < W; ++u) {
        if (d[u] <= 0.0f) continue;
        const double z = d[u];
        d[u] = static_cast<float>(z + config.depth_noise_model.sigma(z) * e[u]);
      }
    }
  }
  for (int v = 0; v < H; ++v) {
    auto* d = depth.ptr<float>(v);
    const auto* iz = inv_z.ptr<double>(v);
    for (int u = 0; u < W; ++u) {
      if (iz[u] <= 0.0) continue;
      const double z_true = 1.0 / iz[u];
      if (z_true < config.min_depth || z_true > config.max_depth) {
        d[u] = 0.0f;
      } else if (config.quantize_depth) {
        d[u] = static_cast<float>(std::round(static_cast<double>(d[u]) * 5000.0) / 5000.0);
      }
    }
  }
  if (config.colour_noise_sigma > 0.0) {
    cv::Mat n(H, W, CV_32FC3);
    rng.fill(n, cv::RNG::NORMAL, 0.0, config.colour_noise_sigma);
    colour += n;
  }
}

// The share of an object's projected extent box (its class extent's 8 corners) inside the image:
// 0 when a corner is behind the camera.
double InImageFraction(const PinholeIntrinsics& K, const SE3& camera_T_object,
                       const Vector3& extent) {
  const Vector3 half = 0.5 * extent;
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
  for (int k = 0; k < 8; ++k) {
    const Vector3 corner((k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                         (k & 4) ? half.z() : -half.z());
    const Vector3 q = camera_T_object.transformFrom(corner);
    if (q.z() <= kNearClip) return 0.0;
    const double pu = K.fx * q.x() / q.z() + K.cx, pv = K.fy * q.y() / q.z() + K.cy;
    umin = std::min(umin, pu);
    umax = std::max(umax, pu);
    vmin = std::min(vmin, pv);
    vmax = std::max(vmax, pv);
  }
  if (!(umax > umin && vmax > vmin)) return 0.0;
  const double iu = std::max(0.0, std::min(umax, K.width - 0.5) - std::max(umin, -0.5));
  const double iv = std::max(0.0, std::min(vmax, K.height - 0.5) - std::max(vmin, -0.5));
  return iu * iv / ((umax - umin) * (vmax - vmin));
}

}  // namespace

// One frame's z-buffer: per pixel the inverse depth (0 = nothing), the item and its triangle
// that won it, and the last item whose triangles covered it (each item's silhouette counted
// once); per item its pose in the camera and its silhouette in pixels.
struct Renderer::Raster {
  struct Pose {
    Matrix3 R;
    Vector3 t;
  };
  Raster(int H, int W, std::size_t items)
      : inv_z(H, W, CV_64FC1, cv::Scalar(0.0)),
        item_buf(H, W, CV_32SC1, cv::Scalar(kNothing)),
        tri_buf(H, W, CV_32SC1, cv::Scalar(0)),
        own_buf(H, W, CV_32SC1, cv::Scalar(kNothing)),
        camera_T_item(items),
        silhouette(items, 0) {}
  cv::Mat inv_z, item_buf, tri_buf, own_buf;
  std::vector<Pose> camera_T_item;
  std::vector<int> silhouette;
};

// What the shading found of each world object: its visible pixels, their bounding box, and its
// silhouette (from the raster).
struct Renderer::ObjectPixels {
  explicit ObjectPixels(std::size_t n, int W, int H)
      : count(n, 0), silhouette(n, 0), lo(n, cv::Point(W, H)), hi(n, cv::Point(-1, -1)) {}
  std::vector<int> count, silhouette;
  std::vector<cv::Point> lo, hi;
};

void Renderer::rasterizeItems(const SE3& camera_T_world, Raster& raster) const {
  const PinholeIntrinsics& K = config_.intrinsics;
  const int W = K.width, H = K.height;
  // Frustum side planes through the camera centre (inward normals), for culling whole items.
  const std::array<Vector3, 4> planes = {Vector3(K.fx, 0.0, 0.5 + K.cx).normalized(),
                                         Vector3(-K.fx, 0.0, W - 0.5 - K.cx).normalized(),
                                         Vector3(0.0, K.fy, 0.5 + K.cy).normalized(),
                                         Vector3(0.0, -K.fy, H - 0.5 - K.cy).normalized()};
  std::vector<Vector3> cam;
  for (std::size_t k = 0; k < items_.size(); ++k) {
    const Item& item = items_[k];
    const SE3 c_T_l = camera_T_world * item.world_T_local;
    raster.camera_T_item[k] = {c_T_l.rotation().matrix(), c_T_l.translation()};
    const Mesh& mesh = *item.mesh;
    if (item.object_index >= 0) {
      // Bounding-sphere culling.
      const auto [lo, hi] = mesh.bounds();
      const Vector3 centre = c_T_l.transformFrom(0.5 * (lo + hi));
      const double radius = 0.5 * (hi - lo).norm();
      bool outside = centre.z() + radius < kNearClip;
      for (const auto& n : planes) outside = outside || n.dot(centre) < -radius;
      if (outside) continue;
    }
    cam.resize(mesh.vertices.size());
    for (std::size_t i = 0; i < cam.size(); ++i) {
      cam[i] = raster.camera_T_item[k].R * mesh.vertices[i] + raster.camera_T_item[k].t;
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& tri = mesh.triangles[t];
      std::array<Vector3, 3> p = {cam[static_cast<std::size_t>(tri[0])],
                                  cam[static_cast<std::size_t>(tri[1])],
                                  cam[static_cast<std::size_t>(tri[2])]};
      if (mesh.closed && (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0]) >= 0.0) continue;
      bool culled = false;
      for (const auto& pl : planes) {
        culled = culled || (pl.dot(p[0]) < 0.0 && pl.dot(p[1]) < 0.0 && pl.dot(p[2]) < 0.0);
      }
      if (culled) continue;
      std::array<Vector3, 4> poly;
      int n = 3;
      if (p[0].z() < kNearClip || p[1].z() < kNearClip || p[2].z() < kNearClip) {
        n = ClipNear(p, poly);
        if (n < 3) continue;
      } else {
        poly = {p[0], p[1], p[2], p[2]};
      }
      // Screen coordinates and inverse depth of the polygon's vertices.
      std::array<double, 4> su{}, sv{}, siz{};
      for (int i = 0; i < n; ++i) {
        const Vector3& q = poly[static_cast<std::size_t>(i)];
        siz[static_cast<std::size_t>(i)] = 1.0 / q.z();
        su[static_cast<std::size_t>(i)] = K.fx * q.x() / q.z() + K.cx;
        sv[static_cast<std::size_t>(i)] = K.fy * q.y() / q.z() + K.cy;
      }
      for (int f = 1; f + 1 < n; ++f) {
        const std::array<std::size_t, 3> ix = {0, static_cast<std::size_t>(f),
                                               static_cast<std::size_t>(f + 1)};
        RasterizeTriangle({su[ix[0]], su[ix[1]], su[ix[2]]}, {sv[ix[0]], sv[ix[1]], sv[ix[2]]},
                          {siz[ix[0]], siz[ix[1]], siz[ix[2]]}, static_cast<int>(k),
                          static_cast<int>(t), raster.inv_z, raster.item_buf, raster.tri_buf,
                          raster.own_buf, raster.silhouette[k]);
      }
    }
  }
}

Renderer::ObjectPixels Renderer::shade(const Raster& raster, const SE3& world_T_camera,
                                       cv::Mat& colour, cv::Mat& depth,
                                       cv::Mat& instance_ids) const {
  const PinholeIntrinsics& K = config_.intrinsics;
  const int W = K.width, H = K.height;
  const Matrix3 R_wc = world_T_camera.rotation().matrix();
  const Vector3 c_w = world_T_camera.translation();
  const SceneStyle& st = config_.style;
  const Vector3 light = st.light_direction.normalized();
  ObjectPixels seen(world_.objects.size(), W, H);
  for (std::size_t k = 0; k < items_.size(); ++k) {
    if (items_[k].object_index >= 0) {
      seen.silhouette[static_cast<std::size_t>(items_[k].object_index)] = raster.silhouette[k];
    }
  }
  for (int v = 0; v < H; ++v) {
    const auto* iz = raster.inv_z.ptr<double>(v);
    const auto* it = raster.item_buf.ptr<int>(v);
    const auto* tr = raster.tri_buf.ptr<int>(v);
    auto* col = colour.ptr<cv::Vec3f>(v);
    auto* dep = depth.ptr<float>(v);
    auto* ids = instance_ids.ptr<int>(v);
    for (int u = 0; u < W; ++u) {
      if (it[u] == kNothing) {
        const cv::Vec3b& b = st.background_bgr;
        col[u] = cv::Vec3f(b[0], b[1], b[2]);
        continue;
      }
      const double z = 1.0 / iz[u];
      const Vector3 p_cam(z * (u - K.cx) / K.fx, z * (v - K.cy) / K.fy, z);
      cv::Vec3b base;
      Vector3 n_world;
      if (it[u] == kFloor) {
        const Vector3 pw = R_wc * p_cam + c_w;
        const auto ix = static_cast<long>(std::floor(pw.x() / st.floor_tile_m));
        const auto iy = static_cast<long>(std::floor(pw.y() / st.floor_tile_m));
        base = ((ix + iy) & 1L) != 0 ? st.floor_b_bgr : st.floor_a_bgr;
        // A small per-tile brightness variation (a hash of the tile), for texture.
        const auto h = SplitMix64(static_cast<std::uint64_t>(ix) * 73856093ULL ^
                                  static_cast<std::uint64_t>(iy) * 19349663ULL);
        base = Scale(base, 0.92 + 0.16 * static_cast<double>(h % 1000U) / 1000.0);
        n_world = Vector3::UnitZ();
      } else {
        const auto k = static_cast<std::size_t>(it[u]);
        const Item& item = items_[k];
        const auto t = static_cast<std::size_t>(tr[u]);
        const Raster::Pose& ct = raster.camera_T_item[k];
        const Vector3 p_local = ct.R.transpose() * (p_cam - ct.t);
        base = item.mesh->colourAt(t, p_local);
        Vector3 n_cam = ct.R * item.mesh->normal(t);
        if (!item.mesh->closed && n_cam.dot(p_cam) > 0.0) n_cam = -n_cam;
        n_world = R_wc * n_cam;
        if (item.object_index >= 0) {
          const auto o = static_cast<std::size_t>(item.object_index);
          ids[u] = world_.objects[o].id;
          ++seen.count[o];
          seen.lo[o].x = std::min(seen.lo[o].x, u);
          seen.lo[o].y = std::min(seen.lo[o].y, v);
          seen.hi[o].x = std::max(seen.hi[o].x, u);
          seen.hi[o].y = std::max(seen.hi[o].y, v);
        }
      }
      const double shade = st.ambient + st.diffuse * std::max(0.0, n_world.dot(light));
      col[u] = cv::Vec3f(static_cast<float>(base[0] * shade), static_cast<float>(base[1] * shade),
                         static_cast<float>(base[2] * shade));
      dep[u] = static_cast<float>(z);
    }
  }
  return seen;
}

std::vector<VisibleObject> Renderer::objectsSeen(const ObjectPixels& seen,
                                                 const SE3& camera_T_world) const {
  std::vector<VisibleObject> out;
  for (std::size_t o = 0; o < world_.objects.size(); ++o) {
    if (seen.count[o] == 0) continue;
    const ObjectInstance& obj = world_.objects[o];
    VisibleObject vo;
    vo.id = obj.id;
    vo.label = obj.label;
    vo.visible_pixels = seen.count[o];
    vo.silhouette_pixels = seen.silhouette[o];
    vo.box = cv::Rect(seen.lo[o], cv::Point(seen.hi[o].x + 1, seen.hi[o].y + 1));
    vo.camera_T_object = camera_T_world * obj.pose;
    vo.in_image_fraction = InImageFraction(config_.intrinsics, vo.camera_T_object,
                                           world_.findClass(obj.label)->extent);
    out.push_back(vo);
  }
  std::sort(out.begin(), out.end(),
            [](const VisibleObject& a, const VisibleObject& b) { return a.id < b.id; });
  return out;
}

RenderedFrame Renderer::render(const SE3& world_T_body, std::uint64_t frame_key,
                               double timestamp) const {
  if (!world_T_body.translation().allFinite() || !world_T_body.rotation().matrix().allFinite()) {
    throw InvalidInputError("Renderer::render: world_T_body is not finite");
  }
  const PinholeIntrinsics& K = config_.intrinsics;
  const int W = K.width, H = K.height;
  RenderedFrame out;
  out.world_T_camera = world_T_body * BodyFromCamera();
  const SE3 camera_T_world = out.world_T_camera.inverse();
  Raster raster(H, W, items_.size());
  if (config_.draw_floor) {
    DrawFloor(K, out.world_T_camera.rotation().matrix(), out.world_T_camera.translation(),
              raster.inv_z, raster.item_buf);
  }
  rasterizeItems(camera_T_world, raster);
  cv::Mat colour(H, W, CV_32FC3);
  cv::Mat depth(H, W, CV_32FC1, cv::Scalar(0.0f));
  out.instance_ids = cv::Mat(H, W, CV_32SC1, cv::Scalar(-1));
  const ObjectPixels seen = shade(raster, out.world_T_camera, colour, depth, out.instance_ids);
  ApplySensor(config_, frame_key, raster.inv_z, depth, colour);
  colour.convertTo(out.rgbd.rgb, CV_8UC3);
  out.rgbd.depth = depth;
  out.rgbd.intrinsics = K;
  out.rgbd.timestamp = timestamp;
  out.objects = objectsSeen(seen, camera_T_world);
  return out;
}

}  // namespace moslam
