#include "moslam/render/object_models.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

using Vec2 = Eigen::Vector2d;

cv::Vec3b Bgr(int r, int g, int b) {
  return cv::Vec3b(static_cast<uchar>(b), static_cast<uchar>(g), static_cast<uchar>(r));
}

Material Solid(cv::Vec3b c) {
  Material m;
  m.colour_bgr = c;
  m.secondary_bgr = c;
  return m;
}

Material Stripes(cv::Vec3b a, cv::Vec3b b, int axis, double period) {
  Material m;
  m.colour_bgr = a;
  m.secondary_bgr = b;
  m.pattern = Material::Pattern::kStripes;
  m.axis = axis;
  m.period_m = period;
  return m;
}

Material Checker(cv::Vec3b a, cv::Vec3b b, int normal_axis, double period) {
  Material m = Stripes(a, b, normal_axis, period);
  m.pattern = Material::Pattern::kChecker;
  return m;
}

// Builds a model in the object frame: helpers take fractions-of-extent or absolute sizes.
class Builder {
 public:
  explicit Builder(const Vector3& extent) : e_(extent), h_(0.5 * extent) {}
  Mesh& mesh() { return mesh_; }
  const Vector3& e() const { return e_; }
  const Vector3& h() const { return h_; }
  double z0() const { return -h_.z(); }
  double top() const { return h_.z(); }
  int mat(const Material& m) { return mesh_.addMaterial(m); }
  void box(double x0, double x1, double y0, double y1, double z0, double z1, int m) {
    mesh_.addBox(Vector3(x0, y0, z0), Vector3(x1, y1, z1), m);
  }
  // Thickness t, limited to a fraction of the smallest extent so that tiny classes stay valid.
  double t(double metres) const { return std::min(metres, 0.15 * e_.minCoeff()); }

 private:
  Vector3 e_, h_;
  Mesh mesh_;
};

// Four square legs of width w at the corners of [x0, x1] x [y0, y1], from z0 to z1.
void Legs(Builder& b, double x0, double x1, double y0, double y1, double w, double za, double zb,
          int m) {
  for (const double x : {x0, x1 - w}) {
    for (const double y : {y0, y1 - w}) b.box(x, x + w, y, y + w, za, zb, m);
  }
}

void Chair(Builder& b) {
  const Vector3& h = b.h();
  const double leg = b.t(0.04), seat_t = b.t(0.05), back_t = b.t(0.05);
  const double seat_z = b.z0() + 0.5 * b.e().z();
  const int wood = b.mat(Solid(Bgr(120, 72, 40)));
  const int seat = b.mat(Checker(Bgr(40, 70, 170), Bgr(90, 140, 210), 2, 0.08));
  const int back = b.mat(Stripes(Bgr(170, 50, 40), Bgr(230, 200, 70), 2, 0.06));
  Legs(b, -h.x(), h.x(), -h.y(), h.y(), leg, b.z0(), seat_z - seat_t, wood);
  b.box(-h.x(), h.x(), -h.y(), h.y(), seat_z - seat_t, seat_z, seat);
  b.box(-h.x(), -h.x() + back_t, -h.y(), h.y(), seat_z, b.top(), back);
  // A cushion tie on the left of the seat front (breaks the left-right mirror symmetry of colour).
  const int tie = b.mat(Solid(Bgr(240, 240, 240)));
  b.box(h.x() - 0.3 * b.e().x(), h.x() - 0.05 * b.e().x(), 0.1 * h.y(), 0.6 * h.y(), seat_z,
        seat_z + b.t(0.015), tie);
  b.mesh().gradient = Vector3(0.5 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

void Table(Builder& b, bool coffee) {
  const Vector3& h = b.h();
  const double top_t = b.t(0.04), leg = b.t(0.06);
  const int top = b.mat(Stripes(Bgr(180, 120, 60), Bgr(150, 95, 45), 1, 0.09));
  const int legs = b.mat(Solid(Bgr(60, 45, 35)));
  const int drawer = b.mat(Stripes(Bgr(40, 120, 60), Bgr(230, 230, 210), 1, 0.12));
  const double zt = b.top() - top_t;
  const double inset = 0.04 * std::min(b.e().x(), b.e().y());
  Legs(b, -h.x() + inset, h.x() - inset, -h.y() + inset, h.y() - inset, leg, b.z0(), zt, legs);
  b.box(-h.x(), h.x(), -h.y(), h.y(), zt, b.top(), top);
  // A drawer under the top on the +x side, over the left (+y) part only.
  const double dz = coffee ? 0.25 * b.e().z() : 0.15 * b.e().z();
  b.box(h.x() - inset - leg, h.x() - inset, -0.1 * h.y(), 0.6 * h.y(), zt - dz, zt, drawer);
  if (coffee) {  // a lower shelf, towards -x
    const int shelf = b.mat(Checker(Bgr(200, 190, 170), Bgr(120, 100, 80), 2, 0.1));
    b.box(-h.x() + inset, 0.5 * h.x(), -h.y() + inset + leg, h.y() - inset - leg,
          b.z0() + 0.2 * b.e().z(), b.z0() + 0.2 * b.e().z() + top_t, shelf);
  }
  b.mesh().gradient = Vector3(0.4 / b.e().x(), 0.4 / b.e().y(), 0.0);
}

// Sofa (two seat cushions) or armchair (one), back at -x, arms at +-y.
void Seating(Builder& b, int cushions) {
  const Vector3& h = b.h();
  const double foot = 0.1 * b.e().z(), base_top = b.z0() + 0.48 * b.e().z();
  const double arm_w = 0.16 * std::min(b.e().y(), 1.0), back_d = 0.22 * b.e().x();
  const int frame = b.mat(Solid(Bgr(90, 60, 110)));
  const int feet = b.mat(Solid(Bgr(30, 25, 20)));
  const int cushion_a = b.mat(Checker(Bgr(200, 120, 60), Bgr(230, 180, 120), 2, 0.1));
  const int cushion_b = b.mat(Stripes(Bgr(60, 140, 160), Bgr(120, 200, 210), 1, 0.08));
  const int back = b.mat(Stripes(Bgr(110, 70, 140), Bgr(150, 110, 170), 2, 0.12));
  const int arm_left = b.mat(Solid(Bgr(200, 60, 70)));
  const int pillow = b.mat(Checker(Bgr(250, 220, 60), Bgr(40, 40, 40), 0, 0.06));
  const double fw = b.t(0.06);
  Legs(b, -h.x() + 0.02, h.x() - 0.02, -h.y() + 0.02, h.y() - 0.02, fw, b.z0(), b.z0() + foot,
       feet);
  b.box(-h.x(), h.x(), -h.y(), h.y(), b.z0() + foot, base_top - 0.1 * b.e().z(), frame);
  // Seat cushions between the arms, in front of the back.
  const double y0 = -h.y() + arm_w, y1 = h.y() - arm_w, cw = (y1 - y0) / cushions;
  for (int i = 0; i < cushions; ++i) {
    b.box(-h.x() + back_d, h.x(), y0 + i * cw, y0 + (i + 1) * cw,
          base_top - 0.1 * b.e().z(), base_top, i % 2 == 0 ? cushion_a : cushion_b);
  }
  b.box(-h.x(), -h.x() + back_d, -h.y(), h.y(), base_top - 0.1 * b.e().z(), b.top(), back);
  const double arm_top = b.z0() + 0.7 * b.e().z();
  b.box(-h.x() + back_d, h.x(), -h.y(), -h.y() + arm_w, base_top - 0.1 * b.e().z(), arm_top,
        frame);
  b.box(-h.x() + back_d, h.x(), h.y() - arm_w, h.y(), base_top - 0.1 * b.e().z(), arm_top,
        arm_left);
  // A pillow in the left (+y) corner against the back.
  const double pw = std::min(0.4, 0.35 * (y1 - y0));
  b.box(-h.x() + back_d, -h.x() + back_d + 0.12 * b.e().x(), y1 - pw, y1, base_top,
        base_top + 0.35 * (b.top() - base_top), pillow);
  b.mesh().gradient = Vector3(0.3 / b.e().x(), 0.35 / b.e().y(), 0.0);
}

void Bed(Builder& b) {
  const Vector3& h = b.h();
  const int frame = b.mat(Solid(Bgr(110, 80, 50)));
  const int mattress = b.mat(Solid(Bgr(235, 235, 225)));
  const int blanket = b.mat(Stripes(Bgr(50, 90, 170), Bgr(200, 60, 60), 0, 0.15));
  const int head = b.mat(Stripes(Bgr(90, 60, 40), Bgr(140, 100, 70), 1, 0.1));
  const int pillow = b.mat(Checker(Bgr(240, 240, 250), Bgr(180, 200, 240), 2, 0.05));
  const double ht = b.t(0.08), z_frame = b.z0() + 0.4 * b.e().z(), z_mat = b.z0() + 0.75 * b.e().z();
  b.box(-h.x(), -h.x() + ht, -h.y(), h.y(), b.z0(), b.top(), head);
  b.box(-h.x() + ht, h.x(), -h.y(), h.y(), b.z0() + 0.1 * b.e().z(), z_frame, frame);
  Legs(b, -h.x() + ht, h.x(), -h.y(), h.y(), b.t(0.08), b.z0(), b.z0() + 0.1 * b.e().z(), frame);
  const double blanket_x = -h.x() + ht + 0.3 * b.e().x();
  b.box(-h.x() + ht, blanket_x, -h.y() + 0.02, h.y() - 0.02, z_frame, z_mat, mattress);
  b.box(blanket_x, h.x(), -h.y(), h.y(), z_frame, z_mat + 0.02, blanket);
  // Two pillows of different heights at the head end.
  const double px0 = -h.x() + ht + 0.02, px1 = px0 + 0.22 * b.e().x();
  b.box(px0, px1, 0.05 * h.y(), 0.85 * h.y(), z_mat, z_mat + 0.12 * b.e().z(), pillow);
  b.box(px0, px1, -0.85 * h.y(), -0.05 * h.y(), z_mat, z_mat + 0.2 * b.e().z(), pillow);
  b.mesh().gradient = Vector3(0.2 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

void Shelf(Builder& b) {
  const Vector3& h = b.h();
  const double th = b.t(0.025);
  const int wood = b.mat(Stripes(Bgr(200, 160, 110), Bgr(180, 140, 95), 2, 0.05));
  const int back = b.mat(Solid(Bgr(240, 230, 200)));
  b.box(-h.x(), -h.x() + th, -h.y(), h.y(), b.z0(), b.top(), back);
  b.box(-h.x() + th, h.x(), -h.y(), -h.y() + th, b.z0(), b.top(), wood);
  b.box(-h.x() + th, h.x(), h.y() - th, h.y(), b.z0(), b.top(), wood);
  // Boards at uneven heights (fractions of the height), the lowest one on the floor.
  const std::vector<double> boards = {0.0, 0.22, 0.47, 0.66, 1.0};
  for (const double f : boards) {
    const double z = std::clamp(b.z0() + f * b.e().z(), b.z0(), b.top() - th);
    b.box(-h.x() + th, h.x(), -h.y() + th, h.y() - th, z, z + th, wood);
  }
  // Books: a few coloured blocks on some boards, packed towards +y on one, -y on another.
  const std::vector<cv::Vec3b> colours = {Bgr(200, 40, 40), Bgr(40, 90, 200), Bgr(40, 160, 70),
                                          Bgr(230, 200, 40), Bgr(120, 40, 150), Bgr(30, 30, 30)};
  std::vector<int> book_mats;
  for (const auto& c : colours) book_mats.push_back(b.mat(Solid(c)));
  const double inner = b.e().y() - 2 * th;
  auto books = [&](double board_f, double next_f, double from_y, double dir, int n, int first) {
    const double z = b.z0() + board_f * b.e().z() + th;
    const double space = (next_f - board_f) * b.e().z() - th;
    double y = from_y;
    for (int i = 0; i < n; ++i) {
      const double w = inner * (0.06 + 0.02 * ((i + first) % 3));
      const double hh = space * (0.55 + 0.12 * ((i + 2 * first) % 4));
      const double ya = dir > 0 ? y : y - w, yb = dir > 0 ? y + w : y;
      b.box(-h.x() + th, h.x() - 0.25 * b.e().x(), ya, yb, z, z + hh,
            book_mats[static_cast<std::size_t>(i + first) % book_mats.size()]);
      y += dir * w;
    }
  };
  books(0.22, 0.47, -h.y() + th, 1.0, 5, 0);
  books(0.47, 0.66, h.y() - th, -1.0, 3, 2);
  books(0.0, 0.22, -h.y() + th + 0.4 * inner, 1.0, 4, 4);
  b.mesh().gradient = Vector3(0.2 / b.e().x(), 0.3 / b.e().y(), 0.1 / b.e().z());
}

void Tv(Builder& b) {
  const Vector3& h = b.h();
  const double screen_t = std::min(0.01, 0.2 * b.e().x());
  const int body = b.mat(Solid(Bgr(45, 45, 50)));
  const int screen = b.mat(Checker(Bgr(30, 90, 200), Bgr(240, 150, 40), 0, 0.1));
  const int led = b.mat(Solid(Bgr(250, 30, 30)));
  const int back = b.mat(Stripes(Bgr(90, 90, 95), Bgr(60, 60, 65), 2, 0.04));
  const double bezel = 0.04 * b.e().z();
  // Body (thin front part) and a smaller box on the back, lower half.
  b.box(-0.1 * h.x(), h.x() - screen_t, -h.y(), h.y(), b.z0(), b.top(), body);
  b.box(-h.x(), -0.1 * h.x(), -0.6 * h.y(), 0.4 * h.y(), b.z0() + 0.1 * b.e().z(),
        b.z0() + 0.6 * b.e().z(), back);
  b.box(h.x() - screen_t, h.x(), -h.y() + bezel, h.y() - bezel, b.z0() + 2.5 * bezel,
        b.top() - bezel, screen);
  // A status light in the bottom bezel, towards the viewer's right (-y).
  b.box(h.x() - screen_t, h.x(), -0.8 * h.y(), -0.6 * h.y(), b.z0() + 0.5 * bezel,
        b.z0() + 1.8 * bezel, led);
  b.mesh().gradient = Vector3(0.0, 0.3 / b.e().y(), 0.4 / b.e().z());
}

void Plant(Builder& b) {
  const Vector3& h = b.h();
  const double r = std::min(h.x(), h.y());
  const int pot = b.mat(Stripes(Bgr(190, 90, 50), Bgr(230, 220, 200), 2, 0.05));
  const int mark = b.mat(Solid(Bgr(30, 60, 200)));
  const int leaf_a = b.mat(Checker(Bgr(40, 140, 40), Bgr(90, 190, 60), 2, 0.07));
  const int leaf_b = b.mat(Stripes(Bgr(30, 100, 50), Bgr(150, 200, 80), 2, 0.05));
  const int stem = b.mat(Solid(Bgr(90, 70, 40)));
  const double pot_top = b.z0() + 0.32 * b.e().z();
  b.mesh().addFrustum(Vec2(0, 0), b.z0(), pot_top, 0.55 * r, 0.75 * r, 10, pot);
  // A coloured label on the pot's +x side.
  b.box(0.5 * r, 0.68 * r, -0.15 * r, 0.25 * r, b.z0() + 0.1 * b.e().z(), b.z0() + 0.22 * b.e().z(),
        mark);
  b.mesh().addFrustum(Vec2(0.05 * r, -0.05 * r), pot_top, b.z0() + 0.6 * b.e().z(), 0.08 * r,
                      0.06 * r, 6, stem);
  // Foliage: cones of leaves, off-centre.
  b.mesh().addFrustum(Vec2(0.2 * r, 0.15 * r), pot_top + 0.05 * b.e().z(), b.top(), 0.75 * r,
                      0.1 * r, 9, leaf_a);
  b.mesh().addFrustum(Vec2(-0.3 * r, -0.25 * r), pot_top + 0.1 * b.e().z(),
                      b.z0() + 0.8 * b.e().z(), 0.6 * r, 0.1 * r, 7, leaf_b);
  b.mesh().gradient = Vector3(0.4 / b.e().x(), 0.25 / b.e().y(), 0.0);
}

void Fridge(Builder& b) {
  const Vector3& h = b.h();
  const int body = b.mat(Solid(Bgr(225, 228, 232)));
  const int door = b.mat(Stripes(Bgr(200, 210, 220), Bgr(235, 238, 240), 2, 0.3));
  const int handle = b.mat(Solid(Bgr(40, 40, 45)));
  const int panel = b.mat(Checker(Bgr(20, 40, 120), Bgr(60, 200, 220), 0, 0.03));
  const int note = b.mat(Solid(Bgr(240, 210, 30)));
  const double dt = b.t(0.03), split = b.z0() + 0.62 * b.e().z();
  b.box(-h.x(), h.x() - dt, -h.y(), h.y(), b.z0(), b.top(), body);
  const double f = h.x() - 0.006;  // door fronts; handles, display and note stand out to h.x()
  b.box(h.x() - dt, f, -h.y() + 0.01, h.y() - 0.01, b.z0() + 0.05, split - 0.01, door);
  b.box(h.x() - dt, f, -h.y() + 0.01, h.y() - 0.01, split + 0.01, b.top() - 0.01, door);
  // Handles on the left (+y) edge of both doors; a display and a note on the upper door.
  b.box(f, h.x(), 0.7 * h.y(), 0.8 * h.y(), split - 0.45 * b.e().z(), split - 0.1 * b.e().z(),
        handle);
  b.box(f, h.x(), 0.7 * h.y(), 0.8 * h.y(), split + 0.05 * b.e().z(), split + 0.2 * b.e().z(),
        handle);
  b.box(f, h.x(), -0.6 * h.y(), -0.1 * h.y(), split + 0.08 * b.e().z(), split + 0.16 * b.e().z(),
        panel);
  b.box(f, h.x(), -0.5 * h.y(), -0.2 * h.y(), b.z0() + 0.3 * b.e().z(), b.z0() + 0.4 * b.e().z(),
        note);
  b.mesh().gradient = Vector3(0.25 / b.e().x(), 0.35 / b.e().y(), 0.0);
}

void Counter(Builder& b) {
  const Vector3& h = b.h();
  const int carcass = b.mat(Solid(Bgr(235, 235, 230)));
  const int door_a = b.mat(Solid(Bgr(60, 120, 170)));
  const int door_b = b.mat(Stripes(Bgr(200, 200, 190), Bgr(170, 170, 160), 2, 0.05));
  const int top = b.mat(Checker(Bgr(60, 60, 60), Bgr(130, 130, 125), 2, 0.1));
  const int sink = b.mat(Solid(Bgr(180, 185, 195)));
  const int kick = b.mat(Solid(Bgr(30, 30, 30)));
  const int handle = b.mat(Solid(Bgr(220, 170, 40)));
  const double top_t = b.t(0.04), dt = b.t(0.02), kz = 0.1 * b.e().z();
  const double zt = b.top() - top_t;
  b.box(-h.x(), h.x() - 0.06, -h.y(), h.y(), b.z0(), b.z0() + kz, kick);
  b.box(-h.x(), h.x() - dt, -h.y(), h.y(), b.z0() + kz, zt, carcass);
  // Countertop: tiles, with a sink on the left (+y) third.
  const double sy = h.y() - 0.33 * b.e().y();
  b.box(-h.x(), h.x(), -h.y(), sy, zt, b.top(), top);
  b.box(-h.x(), h.x(), sy, h.y(), zt, b.top(), sink);
  // Fronts: doors of two kinds, drawers on the right (-y) end.
  const int n = std::max(2, static_cast<int>(std::round(b.e().y() / 0.5)));
  const double w = b.e().y() / n;
  for (int i = 0; i < n; ++i) {
    const double y0 = -h.y() + i * w + 0.005, y1 = -h.y() + (i + 1) * w - 0.005;
    const int m = i == 0 ? door_b : door_a;
    b.box(h.x() - dt, h.x() - 0.006, y0, y1, b.z0() + kz + 0.005, zt - 0.005, m);
    const double hy = i % 2 == 0 ? y1 - 0.15 * w : y0 + 0.05 * w;
    b.box(h.x() - 0.006, h.x(), hy, hy + 0.1 * w, zt - 0.15 * b.e().z(), zt - 0.05 * b.e().z(),
          handle);
  }
  b.mesh().gradient = Vector3(0.2 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

void Desk(Builder& b) {
  const Vector3& h = b.h();
  const int top = b.mat(Stripes(Bgr(160, 160, 165), Bgr(130, 130, 135), 1, 0.2));
  const int ped = b.mat(Stripes(Bgr(40, 60, 110), Bgr(200, 200, 210), 2, 0.12));
  const int leg = b.mat(Solid(Bgr(30, 30, 30)));
  const int panel = b.mat(Solid(Bgr(120, 80, 60)));
  const int screen = b.mat(Checker(Bgr(20, 20, 25), Bgr(60, 140, 220), 0, 0.05));
  const double top_t = b.t(0.03), zt = b.top() - top_t;
  b.box(-h.x(), h.x(), -h.y(), h.y(), zt, b.top() - 0.003, top);
  const double pw = std::min(0.45, 0.35 * b.e().y());
  b.box(-h.x() + 0.03, h.x() - 0.03, h.y() - pw, h.y() - 0.02, b.z0(), zt, ped);
  const double lw = b.t(0.05);
  b.box(-h.x() + 0.03, -h.x() + 0.03 + lw, -h.y() + 0.02, -h.y() + 0.02 + lw, b.z0(), zt, leg);
  b.box(h.x() - 0.03 - lw, h.x() - 0.03, -h.y() + 0.02, -h.y() + 0.02 + lw, b.z0(), zt, leg);
  b.box(-h.x() + 0.05, -h.x() + 0.05 + b.t(0.02), -h.y() + 0.02 + lw, h.y() - pw,
        b.z0() + 0.4 * b.e().z(), zt, panel);
  // A patterned desk mat on the top, right (-y) of the centre.
  b.box(-0.2 * h.x(), 0.6 * h.x(), -0.7 * h.y(), -0.1 * h.y(), b.top() - 0.003, b.top(), screen);
  b.mesh().gradient = Vector3(0.3 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

void Lamp(Builder& b) {
  const Vector3& h = b.h();
  const double r = std::min(h.x(), h.y());
  const int base = b.mat(Solid(Bgr(40, 40, 40)));
  const int pole = b.mat(Solid(Bgr(190, 170, 90)));
  const int shade = b.mat(Stripes(Bgr(245, 225, 170), Bgr(200, 90, 40), 2, 0.06));
  const int sw = b.mat(Solid(Bgr(220, 30, 30)));
  const double shade_z = b.top() - 0.28 * b.e().z();
  b.mesh().addFrustum(Vec2(-0.2 * r, 0.0), b.z0(), b.z0() + 0.04 * b.e().z(), 0.75 * r, 0.7 * r,
                      12, base);
  b.box(0.35 * r, 0.6 * r, -0.15 * r, 0.15 * r, b.z0() + 0.04 * b.e().z(),
        b.z0() + 0.06 * b.e().z(), sw);
  b.mesh().addFrustum(Vec2(-0.2 * r, 0.0), b.z0() + 0.04 * b.e().z(), shade_z + 0.05 * b.e().z(),
                      0.08 * r, 0.06 * r, 6, pole);
  b.mesh().addFrustum(Vec2(0.0, 0.0), shade_z, b.top(), 0.98 * r, 0.6 * r, 12, shade);
  b.mesh().gradient = Vector3(0.5 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

void Generic(Builder& b, const std::string& label) {
  const Vector3& h = b.h();
  const auto hash = static_cast<unsigned>(std::hash<std::string>{}(label));
  auto channel = [&](int shift) { return 60 + static_cast<int>((hash >> shift) % 160U); };
  const int a = b.mat(Checker(Bgr(channel(0), channel(8), channel(16)),
                              Bgr(channel(4), channel(12), channel(20)), 2, 0.1));
  const int c = b.mat(Solid(Bgr(channel(20), channel(2), channel(10))));
  b.box(-h.x(), h.x(), -h.y(), h.y(), b.z0(), b.z0() + 0.7 * b.e().z(), a);
  b.box(0.0, h.x(), -h.y(), 0.5 * h.y(), b.z0() + 0.7 * b.e().z(), b.top(), c);
  b.mesh().gradient = Vector3(0.3 / b.e().x(), 0.3 / b.e().y(), 0.0);
}

}  // namespace

Vector3 Mesh::normal(std::size_t t) const {
  const auto& tri = triangles[t];
  const Vector3& a = vertices[static_cast<std::size_t>(tri[0])];
  const Vector3 n = (vertices[static_cast<std::size_t>(tri[1])] - a)
                        .cross(vertices[static_cast<std::size_t>(tri[2])] - a);
  const double len = n.norm();
  return len > 0.0 ? Vector3(n / len) : Vector3(0.0, 0.0, 1.0);
}

double Mesh::area(std::size_t t) const {
  const auto& tri = triangles[t];
  const Vector3& a = vertices[static_cast<std::size_t>(tri[0])];
  return 0.5 * (vertices[static_cast<std::size_t>(tri[1])] - a)
                   .cross(vertices[static_cast<std::size_t>(tri[2])] - a)
                   .norm();
}

double Mesh::totalArea() const {
  double s = 0.0;
  for (std::size_t t = 0; t < triangles.size(); ++t) s += area(t);
  return s;
}

cv::Vec3b Mesh::colourAt(std::size_t t, const Vector3& p) const {
  const Material& m = materials[static_cast<std::size_t>(triangle_material[t])];
  bool second = false;
  if (m.pattern != Material::Pattern::kSolid) {
    auto band = [&](int axis) {
      return static_cast<long>(std::floor(p[axis] / m.period_m));
    };
    if (m.pattern == Material::Pattern::kStripes) {
      second = (band(m.axis) & 1L) != 0;
    } else {
      second = ((band((m.axis + 1) % 3) + band((m.axis + 2) % 3)) & 1L) != 0;
    }
  }
  const cv::Vec3b& c = second ? m.secondary_bgr : m.colour_bgr;
  const double g = std::clamp(1.0 + gradient.dot(p), 0.3, 1.7);
  return cv::Vec3b(cv::saturate_cast<uchar>(c[0] * g), cv::saturate_cast<uchar>(c[1] * g),
                   cv::saturate_cast<uchar>(c[2] * g));
}

int Mesh::addMaterial(const Material& m) {
  materials.push_back(m);
  return static_cast<int>(materials.size()) - 1;
}

void Mesh::addQuad(const Vector3& a, const Vector3& b, const Vector3& c, const Vector3& d,
                   const Vector3& outward, int material) {
  const int i = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), {a, b, c, d});
  const bool flip = (b - a).cross(c - a).dot(outward) < 0.0;
  if (flip) {
    triangles.emplace_back(i, i + 2, i + 1);
    triangles.emplace_back(i, i + 3, i + 2);
  } else {
    triangles.emplace_back(i, i + 1, i + 2);
    triangles.emplace_back(i, i + 2, i + 3);
  }
  triangle_material.push_back(material);
  triangle_material.push_back(material);
}

void Mesh::addBox(const Vector3& lo, const Vector3& hi, int material) {
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (const int side : {0, 1}) {
      Vector3 corner[4];
      for (int k = 0; k < 4; ++k) {
        Vector3 p;
        p[axis] = side == 0 ? lo[axis] : hi[axis];
        p[u] = (k == 1 || k == 2) ? hi[u] : lo[u];
        p[v] = (k >= 2) ? hi[v] : lo[v];
        corner[k] = p;
      }
      Vector3 out = Vector3::Zero();
      out[axis] = side == 0 ? -1.0 : 1.0;
      addQuad(corner[0], corner[1], corner[2], corner[3], out, material);
    }
  }
}

void Mesh::addFrustum(const Eigen::Vector2d& c, double z0, double z1, double r0, double r1,
                      int sides, int material) {
  sides = std::max(3, sides);
  auto ring = [&](int k, double r, double z) {
    const double a = 2.0 * kPi * k / sides;
    return Vector3(c.x() + r * std::cos(a), c.y() + r * std::sin(a), z);
  };
  for (int k = 0; k < sides; ++k) {
    const double a = 2.0 * kPi * (k + 0.5) / sides;
    const Vector3 out(std::cos(a), std::sin(a), 0.0);
    addQuad(ring(k, r0, z0), ring(k + 1, r0, z0), ring(k + 1, r1, z1), ring(k, r1, z1), out,
            material);
  }
  // Caps as fans around their centres.
  for (const int top : {0, 1}) {
    const double z = top ? z1 : z0, r = top ? r1 : r0;
    if (r <= 0.0) continue;
    const int centre = static_cast<int>(vertices.size());
    vertices.emplace_back(c.x(), c.y(), z);
    for (int k = 0; k < sides; ++k) {
      const int i = static_cast<int>(vertices.size());
      vertices.push_back(ring(k, r, z));
      vertices.push_back(ring(k + 1, r, z));
      // Counter-clockwise seen from +z is (centre, k, k+1); the bottom cap is reversed.
      if (top) {
        triangles.emplace_back(centre, i, i + 1);
      } else {
        triangles.emplace_back(centre, i + 1, i);
      }
      triangle_material.push_back(material);
    }
  }
}

std::pair<Vector3, Vector3> Mesh::bounds() const {
  if (vertices.empty()) return {Vector3::Zero(), Vector3::Zero()};
  Vector3 lo = vertices.front(), hi = vertices.front();
  for (const auto& v : vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  return {lo, hi};
}

Mesh MakeObjectMesh(const ObjectClass& c) {
  if (!c.extent.allFinite() || (c.extent.array() <= 0.0).any()) {
    throw InvalidInputError("MakeObjectMesh: class '" + c.label +
                            "' needs a positive finite extent");
  }
  Builder b(c.extent);
  const std::string& l = c.label;
  if (l == "chair") {
    Chair(b);
  } else if (l == "table") {
    Table(b, false);
  } else if (l == "coffee_table") {
    Table(b, true);
  } else if (l == "sofa") {
    Seating(b, 2);
  } else if (l == "armchair") {
    Seating(b, 1);
  } else if (l == "bed") {
    Bed(b);
  } else if (l == "shelf") {
    Shelf(b);
  } else if (l == "tv") {
    Tv(b);
  } else if (l == "plant") {
    Plant(b);
  } else if (l == "fridge") {
    Fridge(b);
  } else if (l == "counter") {
    Counter(b);
  } else if (l == "desk") {
    Desk(b);
  } else if (l == "lamp") {
    Lamp(b);
  } else {
    Generic(b, l);
  }
  return std::move(b.mesh());
}

ColoredPointSet SampleMeshSurface(const Mesh& mesh, double spacing_m, unsigned seed) {
  if (!(spacing_m > 0.0) || !std::isfinite(spacing_m)) {
    throw InvalidInputError("SampleMeshSurface: spacing_m must be positive and finite");
  }
  ColoredPointSet out;
  std::vector<double> cumulative(mesh.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    total += mesh.area(t);
    cumulative[t] = total;
  }
  if (total <= 0.0) return out;
  const double expected = total / (spacing_m * spacing_m);
  if (expected > 5e7) {
    throw InvalidInputError("SampleMeshSurface: spacing_m is too small for this mesh (" +
                            std::to_string(expected) + " points)");
  }
  const auto n = static_cast<std::size_t>(std::max(1.0, std::round(expected)));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  out.points.reserve(n);
  out.normals.reserve(n);
  out.colours_bgr.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double pick = u01(rng) * total;
    auto it = std::upper_bound(cumulative.begin(), cumulative.end(), pick);
    const auto t = static_cast<std::size_t>(
        std::min<std::ptrdiff_t>(it - cumulative.begin(),
                                 static_cast<std::ptrdiff_t>(mesh.size()) - 1));
    const auto& tri = mesh.triangles[t];
    const Vector3& a = mesh.vertices[static_cast<std::size_t>(tri[0])];
    const Vector3& b = mesh.vertices[static_cast<std::size_t>(tri[1])];
    const Vector3& c = mesh.vertices[static_cast<std::size_t>(tri[2])];
    const double s = std::sqrt(u01(rng)), r = u01(rng);
    const Vector3 p = (1.0 - s) * a + s * (1.0 - r) * b + s * r * c;
    out.points.push_back(p);
    out.normals.push_back(mesh.normal(t));
    out.colours_bgr.push_back(mesh.colourAt(t, p));
  }
  return out;
}

namespace {

// Moller-Trumbore: whether the ray o + s d (s > 0) hits triangle abc.
bool RayHitsTriangle(const Vector3& o, const Vector3& d, const Vector3& a, const Vector3& b,
                     const Vector3& c) {
  const Vector3 e1 = b - a, e2 = c - a;
  const Vector3 p = d.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-14) return false;
  const double inv = 1.0 / det;
  const Vector3 t = o - a;
  const double u = t.dot(p) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Vector3 q = t.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  return e2.dot(q) * inv > 0.0;
}

}  // namespace

ColoredPointSet KeepVisibleFromOutside(const Mesh& mesh, const ColoredPointSet& points,
                                       int num_views) {
  if (num_views < 1) throw InvalidInputError("KeepVisibleFromOutside: num_views must be >= 1");
  if (points.normals.size() != points.size() || points.colours_bgr.size() != points.size()) {
    throw InvalidInputError("KeepVisibleFromOutside: points, normals and colours differ in size");
  }
  const auto [lo, hi] = mesh.bounds();
  const Vector3 centre = 0.5 * (lo + hi);
  const double radius = 3.0 * std::max(1e-3, (hi - lo).norm());
  // Viewpoints: a Fibonacci spiral over the upper hemisphere (z from 0 to 1).
  std::vector<Vector3> views;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < num_views; ++i) {
    const double z = (i + 0.5) / num_views, r = std::sqrt(1.0 - z * z), a = golden * i;
    views.push_back(centre + radius * Vector3(r * std::cos(a), r * std::sin(a), z));
  }
  const double offset = 1e-7 * std::max(1.0, (hi - lo).norm());
  ColoredPointSet out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vector3 o = points.points[i] + offset * points.normals[i];
    bool seen = false;
    for (const Vector3& v : views) {
      const Vector3 d = v - o;
      if (d.dot(points.normals[i]) <= 0.0) continue;
      bool blocked = false;
      for (std::size_t t = 0; t < mesh.size() && !blocked; ++t) {
        const auto& tri = mesh.triangles[t];
        blocked = RayHitsTriangle(o, d, mesh.vertices[static_cast<std::size_t>(tri[0])],
                                  mesh.vertices[static_cast<std::size_t>(tri[1])],
                                  mesh.vertices[static_cast<std::size_t>(tri[2])]);
      }
      if (!blocked) {
        seen = true;
        break;
      }
    }
    if (!seen) continue;
    out.points.push_back(points.points[i]);
    out.normals.push_back(points.normals[i]);
    out.colours_bgr.push_back(points.colours_bgr[i]);
  }
  return out;
}

ColoredPointSet SampleVisibleSurface(const Mesh& mesh, double spacing_m, unsigned seed) {
  return KeepVisibleFromOutside(mesh, SampleMeshSurface(mesh, spacing_m, seed));
}

}  // namespace moslam
