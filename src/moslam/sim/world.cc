#include "moslam/sim/world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

SE3 YawPose(double x, double y, double z, double yaw) {
  return SE3(SO3::Exp(Vector3(0.0, 0.0, yaw)), Vector3(x, y, z));
}

// Height of an object's centre above the floor: standing on the floor, except the tv (on a stand).
double CentreHeight(const World& world, const std::string& label) {
  const ObjectClass* c = world.findClass(label);
  const double half = c != nullptr ? 0.5 * c->extent.z() : 0.5;
  return label == "tv" ? 0.5 + half : half;
}

void AddObject(World& world, const std::string& label, double x, double y, double yaw) {
  ObjectInstance o;
  o.id = static_cast<int>(world.objects.size());
  o.label = label;
  o.pose = YawPose(x, y, CentreHeight(world, label), yaw);
  world.objects.push_back(o);
}

int AddNode(NavigationGraph& nav, double x, double y) {
  nav.nodes.emplace_back(x, y);
  return static_cast<int>(nav.nodes.size()) - 1;
}

double DistanceToSegment(const Vector2& p, const Vector2& a, const Vector2& b) {
  const Vector2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

bool Finite(const Vector3& v) { return v.allFinite(); }

}  // namespace

std::vector<std::vector<int>> NavigationGraph::neighbours() const {
  std::vector<std::vector<int>> out(nodes.size());
  for (const auto& [i, j] : edges) {
    out.at(static_cast<std::size_t>(i)).push_back(j);
    out.at(static_cast<std::size_t>(j)).push_back(i);
  }
  return out;
}

const ObjectClass* World::findClass(const std::string& label) const {
  for (const auto& c : classes) {
    if (c.label == label) return &c;
  }
  return nullptr;
}

const ObjectInstance& World::object(int id) const {
  for (const auto& o : objects) {
    if (o.id == id) return o;
  }
  throw InvalidInputError("world '" + name + "' has no object with id " + std::to_string(id));
}

void ValidateWorld(const World& world, const std::string& what) {
  auto bad = [&](const std::string& msg) { throw InvalidInputError(what + ": " + msg); };
  std::set<std::string> labels;
  for (std::size_t i = 0; i < world.classes.size(); ++i) {
    const auto& c = world.classes[i];
    const std::string at = "classes[" + std::to_string(i) + "]";
    if (c.label.empty()) bad(at + ".label is empty");
    if (!labels.insert(c.label).second) bad(at + ".label '" + c.label + "' is declared twice");
    if (!Finite(c.extent) || (c.extent.array() <= 0.0).any()) {
      bad(at + ".extent must be three positive finite numbers");
    }
  }
  std::set<int> ids;
  for (std::size_t i = 0; i < world.objects.size(); ++i) {
    const auto& o = world.objects[i];
    const std::string at = "objects[" + std::to_string(i) + "]";
    if (o.id < 0) bad(at + ".id must be >= 0");
    if (!ids.insert(o.id).second) bad(at + ".id " + std::to_string(o.id) + " is used twice");
    if (labels.count(o.label) == 0) bad(at + ".label '" + o.label + "' is not a declared class");
    if (!Finite(o.pose.translation()) || !o.pose.rotation().matrix().allFinite()) {
      bad(at + " has a non-finite pose");
    }
  }
  for (std::size_t i = 0; i < world.rooms.size(); ++i) {
    const auto& r = world.rooms[i];
    if (!r.min.allFinite() || !r.max.allFinite() || (r.min.array() >= r.max.array()).any()) {
      bad("rooms[" + std::to_string(i) + "] needs finite min < max on both axes");
    }
  }
  const auto& nav = world.navigation;
  const int n = static_cast<int>(nav.nodes.size());
  for (int i = 0; i < n; ++i) {
    if (!nav.nodes[static_cast<std::size_t>(i)].allFinite()) {
      bad("navigation.nodes[" + std::to_string(i) + "] is not finite");
    }
  }
  std::set<std::pair<int, int>> seen;
  for (std::size_t e = 0; e < nav.edges.size(); ++e) {
    const auto [i, j] = nav.edges[e];
    const std::string at = "navigation.edges[" + std::to_string(e) + "]";
    if (i < 0 || j < 0 || i >= n || j >= n) {
      bad(at + " joins a node that does not exist (" + std::to_string(n) + " nodes)");
    }
    if (i == j) bad(at + " is a self-loop");
    if (!seen.insert({std::min(i, j), std::max(i, j)}).second) bad(at + " is duplicated");
  }
}

std::vector<ObjectClass> StandardObjectClasses() {
  return {
      {"chair", Vector3(0.5, 0.5, 0.9)},   {"table", Vector3(1.2, 0.8, 0.75)},
      {"coffee_table", Vector3(0.6, 1.0, 0.45)}, {"sofa", Vector3(0.9, 2.0, 0.85)},
      {"armchair", Vector3(0.9, 0.9, 0.9)}, {"bed", Vector3(2.0, 1.6, 0.6)},
      {"shelf", Vector3(0.35, 0.8, 1.8)},  {"tv", Vector3(0.1, 1.1, 0.65)},
      {"plant", Vector3(0.4, 0.4, 1.0)},   {"fridge", Vector3(0.7, 0.7, 1.8)},
      {"counter", Vector3(0.6, 2.0, 0.9)}, {"desk", Vector3(0.7, 1.4, 0.75)},
      {"lamp", Vector3(0.3, 0.3, 1.5)},
  };
}

void Chairs25Config::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("Chairs25Config: " + m); };
  if (rows < 1 || cols < 1) bad("rows and cols must be >= 1");
  if (rows * cols > 100000) bad("rows * cols must be <= 100000");
  if (!(spacing > 0.0) || !std::isfinite(spacing)) bad("spacing must be positive and finite");
}

World MakeChairs25World(const Chairs25Config& config) {
  config.validate();
  World w;
  w.name = "chairs25";
  w.classes = StandardObjectClasses();
  std::mt19937 rng(config.seed);
  std::uniform_real_distribution<double> yaw(-kPi, kPi);
  const double s = config.spacing;
  for (int i = 0; i < config.rows; ++i) {
    for (int j = 0; j < config.cols; ++j) AddObject(w, "chair", i * s, j * s, yaw(rng));
  }
  // Aisles: a (rows+1) x (cols+1) lattice of nodes between the chairs, 4-connected.
  auto node = [&](int i, int j) { return i * (config.cols + 1) + j; };
  for (int i = 0; i <= config.rows; ++i) {
    for (int j = 0; j <= config.cols; ++j) AddNode(w.navigation, (i - 0.5) * s, (j - 0.5) * s);
  }
  for (int i = 0; i <= config.rows; ++i) {
    for (int j = 0; j <= config.cols; ++j) {
      if (i < config.rows) w.navigation.edges.emplace_back(node(i, j), node(i + 1, j));
      if (j < config.cols) w.navigation.edges.emplace_back(node(i, j), node(i, j + 1));
    }
  }
  w.rooms.push_back({"hall", Vector2(-s, -s), Vector2(config.rows * s, config.cols * s)});
  return w;
}

World MakeHouseWorld() {
  World w;
  w.name = "house";
  w.classes = StandardObjectClasses();
  w.rooms.push_back({"living", Vector2(0.0, 0.0), Vector2(7.0, 5.0)});
  w.rooms.push_back({"kitchen", Vector2(7.0, 0.0), Vector2(12.0, 5.0)});
  const double h = kPi / 2.0;
  // Living room.
  AddObject(w, "sofa", 3.5, 4.45, -h);
  AddObject(w, "tv", 3.5, 0.25, h);
  AddObject(w, "coffee_table", 3.5, 2.5, 0.0);
  AddObject(w, "armchair", 2.4, 2.5, 0.0);
  AddObject(w, "armchair", 4.6, 2.5, kPi);
  AddObject(w, "shelf", 0.25, 2.5, 0.0);
  AddObject(w, "shelf", 6.0, 4.75, -h);
  AddObject(w, "plant", 0.4, 0.4, 0.3);
  AddObject(w, "plant", 6.6, 0.4, 1.1);
  AddObject(w, "plant", 1.2, 4.6, -0.7);
  AddObject(w, "lamp", 0.4, 4.6, 0.0);
  // Kitchen.
  AddObject(w, "fridge", 11.6, 4.6, kPi);
  AddObject(w, "counter", 9.5, 0.3, h);
  AddObject(w, "counter", 11.7, 2.2, kPi);
  AddObject(w, "table", 9.5, 2.5, 0.0);
  AddObject(w, "chair", 9.1, 1.95, h);
  AddObject(w, "chair", 9.9, 1.95, h);
  AddObject(w, "chair", 9.1, 3.05, -h);
  AddObject(w, "chair", 9.9, 3.05, -h);
  AddObject(w, "plant", 7.4, 4.6, 2.0);
  // Navigation: a ring in each room, joined through the door (x = 7, 2 < y < 3).
  auto& nav = w.navigation;
  const int l0 = AddNode(nav, 1.5, 1.5), l1 = AddNode(nav, 3.5, 1.5), l2 = AddNode(nav, 5.5, 1.5);
  const int l3 = AddNode(nav, 5.5, 3.5), l4 = AddNode(nav, 3.5, 3.5), l5 = AddNode(nav, 1.5, 3.5);
  const int dl = AddNode(nav, 6.3, 2.5), dk = AddNode(nav, 7.7, 2.5);
  const int k0 = AddNode(nav, 8.5, 1.5), k1 = AddNode(nav, 10.5, 1.5);
  const int k2 = AddNode(nav, 10.5, 3.5), k3 = AddNode(nav, 8.5, 3.5);
  nav.edges = {{l0, l1}, {l1, l2}, {l2, l3}, {l3, l4}, {l4, l5}, {l5, l0}, {l2, dl}, {l3, dl},
               {dl, dk}, {dk, k0}, {dk, k3}, {k0, k1}, {k1, k2}, {k2, k3}};
  return w;
}

void GeneratedWorldConfig::validate() const {
  auto bad = [](const std::string& m) { throw InvalidInputError("GeneratedWorldConfig: " + m); };
  if (rooms_x < 1 || rooms_y < 1) bad("rooms_x and rooms_y must be >= 1");
  if (rooms_x * rooms_y > 10000) bad("rooms_x * rooms_y must be <= 10000");
  if (!(room_size >= 4.0) || !std::isfinite(room_size)) bad("room_size must be >= 4 m and finite");
  if (!(corridor_length > 0.0) || !std::isfinite(corridor_length)) {
    bad("corridor_length must be positive and finite");
  }
  if (!(extra_door_probability >= 0.0 && extra_door_probability <= 1.0)) {
    bad("extra_door_probability must be in [0, 1]");
  }
  if (min_objects_per_room < 0 || max_objects_per_room < min_objects_per_room) {
    bad("need 0 <= min_objects_per_room <= max_objects_per_room");
  }
  if (max_objects_per_room > 50) bad("max_objects_per_room must be <= 50");
  if (!(object_clearance >= 0.0) || !std::isfinite(object_clearance)) {
    bad("object_clearance must be >= 0 and finite");
  }
  if (!(object_separation >= 0.0) || !std::isfinite(object_separation)) {
    bad("object_separation must be >= 0 and finite");
  }
}

namespace {

// MakeGeneratedWorld in three stages drawn from one random sequence, in this order: the rooms
// and their rings of navigation nodes, the doors between rooms, the furniture.
class GeneratedWorldBuilder {
 public:
  explicit GeneratedWorldBuilder(const GeneratedWorldConfig& config)
      : config_(config),
        rng_(config.seed),
        nx_(config.rooms_x),
        ny_(config.rooms_y),
        S_(config.room_size),
        pitch_(config.room_size + config.corridor_length),
        q_(S_ / 4.0),
        ring_(static_cast<std::size_t>(nx_ * ny_)),
        room_type_(ring_.size()) {
    w_.name = "generated";
    w_.classes = StandardObjectClasses();
  }

  World build() && {
    rooms();
    doors();
    furnish();
    return std::move(w_);
  }

 private:
  int roomId(int i, int j) const { return i * ny_ + j; }
  Vector2 centre(int i, int j) const {
    return Vector2(i * pitch_ + S_ / 2.0, j * pitch_ + S_ / 2.0);
  }

  // Room types and rings: nodes (c-q, c-q), (c+q, c-q), (c+q, c+q), (c-q, c+q).
  void rooms() {
    const std::vector<std::string> types = {"living", "kitchen", "bedroom", "office"};
    for (int i = 0; i < nx_; ++i) {
      for (int j = 0; j < ny_; ++j) {
        const auto r = static_cast<std::size_t>(roomId(i, j));
        room_type_[r] =
            types[std::uniform_int_distribution<std::size_t>(0, types.size() - 1)(rng_)];
        const Vector2 c = centre(i, j);
        w_.rooms.push_back({room_type_[r] + "_" + std::to_string(r),
                            Vector2(i * pitch_, j * pitch_),
                            Vector2(i * pitch_ + S_, j * pitch_ + S_)});
        ring_[r] = {AddNode(w_.navigation, c.x() - q_, c.y() - q_),
                    AddNode(w_.navigation, c.x() + q_, c.y() - q_),
                    AddNode(w_.navigation, c.x() + q_, c.y() + q_),
                    AddNode(w_.navigation, c.x() - q_, c.y() + q_)};
        for (int k = 0; k < 4; ++k) {
          w_.navigation.edges.emplace_back(ring_[r][k], ring_[r][(k + 1) % 4]);
        }
      }
    }
  }

  // Doors: a random spanning tree of the room grid (randomised Kruskal) plus extra doors.
  void doors() {
    struct Door {
      int a, b;
      bool along_x;
    };
    std::vector<Door> candidates;
    for (int i = 0; i < nx_; ++i) {
      for (int j = 0; j < ny_; ++j) {
        if (i + 1 < nx_) candidates.push_back({roomId(i, j), roomId(i + 1, j), true});
        if (j + 1 < ny_) candidates.push_back({roomId(i, j), roomId(i, j + 1), false});
      }
    }
    std::shuffle(candidates.begin(), candidates.end(), rng_);
    std::vector<int> parent(ring_.size());
    for (std::size_t r = 0; r < parent.size(); ++r) parent[r] = static_cast<int>(r);
    auto find = [&](int x) {
      while (parent[static_cast<std::size_t>(x)] != x) {
        x = parent[static_cast<std::size_t>(x)] =
            parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      }
      return x;
    };
    for (const Door& d : candidates) {
      const int ra = find(d.a), rb = find(d.b);
      const bool tree = ra != rb;
      if (tree) parent[static_cast<std::size_t>(ra)] = rb;
      if (!tree && u01_(rng_) >= config_.extra_door_probability) continue;
      addDoor(d.a, d.b, d.along_x);
    }
  }

  // Door nodes just inside each room's wall, each joined to the two ring nodes on that side.
  void addDoor(int room_a, int room_b, bool along_x) {
    const double inset = 0.8;  // door nodes sit this far inside the wall
    const auto& A = ring_[static_cast<std::size_t>(room_a)];
    const auto& B = ring_[static_cast<std::size_t>(room_b)];
    const Vector2 ca = w_.navigation.nodes[static_cast<std::size_t>(A[0])] + Vector2(q_, q_);
    const Vector2 cb = w_.navigation.nodes[static_cast<std::size_t>(B[0])] + Vector2(q_, q_);
    const Vector2 dir = along_x ? Vector2(1.0, 0.0) : Vector2(0.0, 1.0);
    const Vector2 pa = ca + (S_ / 2.0 - inset) * dir, pb = cb - (S_ / 2.0 - inset) * dir;
    const int na = AddNode(w_.navigation, pa.x(), pa.y());
    const int nb = AddNode(w_.navigation, pb.x(), pb.y());
    // Ring sides: +x side is nodes 1, 2; -x side 0, 3; +y side 2, 3; -y side 0, 1.
    const std::pair<int, int> side_a = along_x ? std::pair{A[1], A[2]} : std::pair{A[2], A[3]};
    const std::pair<int, int> side_b = along_x ? std::pair{B[0], B[3]} : std::pair{B[0], B[1]};
    w_.navigation.edges.emplace_back(na, side_a.first);
    w_.navigation.edges.emplace_back(na, side_a.second);
    w_.navigation.edges.emplace_back(nb, side_b.first);
    w_.navigation.edges.emplace_back(nb, side_b.second);
    w_.navigation.edges.emplace_back(na, nb);
  }

  // Furniture: per room, a random selection from its type's inventory, placed by rejection
  // sampling away from the navigation edges and from each other, at a random yaw.
  void furnish() {
    const std::map<std::string, std::vector<std::string>> inventory = {
        {"living", {"sofa", "coffee_table", "tv", "armchair", "shelf", "plant", "lamp"}},
        {"kitchen", {"fridge", "counter", "table", "chair", "chair", "plant"}},
        {"bedroom", {"bed", "shelf", "lamp", "plant", "desk", "chair"}},
        {"office", {"desk", "chair", "shelf", "plant", "lamp", "desk"}},
    };
    std::uniform_real_distribution<double> yaw(-kPi, kPi);
    for (int i = 0; i < nx_; ++i) {
      for (int j = 0; j < ny_; ++j) {
        const auto r = static_cast<std::size_t>(roomId(i, j));
        std::vector<std::string> items = inventory.at(room_type_[r]);
        std::shuffle(items.begin(), items.end(), rng_);
        const int count = std::uniform_int_distribution<int>(config_.min_objects_per_room,
                                                             config_.max_objects_per_room)(rng_);
        const Vector2 lo(i * pitch_ + 0.4, j * pitch_ + 0.4);
        const Vector2 hi(i * pitch_ + S_ - 0.4, j * pitch_ + S_ - 0.4);
        for (int k = 0; k < count; ++k) {
          const std::string& label = items[static_cast<std::size_t>(k) % items.size()];
          for (int attempt = 0; attempt < 200; ++attempt) {
            const Vector2 p(lo.x() + (hi.x() - lo.x()) * u01_(rng_),
                            lo.y() + (hi.y() - lo.y()) * u01_(rng_));
            if (!clear(p)) continue;
            placed_.push_back(p);
            AddObject(w_, label, p.x(), p.y(), yaw(rng_));
            break;
          }
        }
      }
    }
  }

  // Whether p keeps the clearance from every navigation edge and the separation from every
  // object placed.
  bool clear(const Vector2& p) const {
    for (const auto& [a, b] : w_.navigation.edges) {
      if (DistanceToSegment(p, w_.navigation.nodes[static_cast<std::size_t>(a)],
                            w_.navigation.nodes[static_cast<std::size_t>(b)]) <
          config_.object_clearance) {
        return false;
      }
    }
    for (const Vector2& m : placed_) {
      if ((m - p).norm() < config_.object_separation) return false;
    }
    return true;
  }

  const GeneratedWorldConfig& config_;
  std::mt19937 rng_;
  std::uniform_real_distribution<double> u01_{0.0, 1.0};
  const int nx_, ny_;
  const double S_, pitch_;
  const double q_;  // half side of each room's ring of nodes
  std::vector<std::array<int, 4>> ring_;
  std::vector<std::string> room_type_;
  std::vector<Vector2> placed_;
  World w_;
};

}  // namespace

World MakeGeneratedWorld(const GeneratedWorldConfig& config) {
  config.validate();
  return GeneratedWorldBuilder(config).build();
}

GeneratedWorldConfig GeneratedWorldForTeam(int num_robots, unsigned seed) {
  if (num_robots < 1) throw InvalidInputError("GeneratedWorldForTeam: num_robots must be >= 1");
  GeneratedWorldConfig c;
  const int rooms = std::max(4, (num_robots + 1) / 2);
  c.rooms_x = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(rooms))));
  c.rooms_y = (rooms + c.rooms_x - 1) / c.rooms_x;
  c.seed = seed;
  return c;
}

World MakeScenarioWorld(const std::string& scenario, unsigned seed, int num_robots) {
  if (scenario == "chairs25") {
    Chairs25Config c;
    c.seed = seed;
    return MakeChairs25World(c);
  }
  if (scenario == "house") return MakeHouseWorld();
  if (scenario == "generated") return MakeGeneratedWorld(GeneratedWorldForTeam(num_robots, seed));
  throw InvalidInputError("unknown scenario '" + scenario +
                          "' (expected chairs25, house or generated)");
}

// ---------------------------------------------------------------------------------------------
// JSON

namespace {

using nlohmann::json;

json Vec(const Eigen::VectorXd& v) {
  json a = json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

class JsonReader {
 public:
  explicit JsonReader(std::string name) : name_(std::move(name)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& msg) const {
    throw InvalidInputError(name_ + ": " + where + ": " + msg);
  }

  // Requires exactly the keys `allowed` (all of them) in object `j`.
  void requireKeys(const json& j, const std::string& where,
                   const std::vector<std::string>& allowed) const {
    if (!j.is_object()) fail(where, "expected an object");
    for (const auto& k : allowed) {
      if (!j.contains(k)) fail(where, "missing key '" + k + "'");
    }
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end()) {
        fail(where, "unknown key '" + it.key() + "'");
      }
    }
  }

  double number(const json& j, const std::string& where) const {
    if (!j.is_number()) fail(where, "expected a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(where, "not a finite number");
    return v;
  }

  Eigen::VectorXd vec(const json& j, const std::string& where, int n) const {
    if (!j.is_array() || static_cast<int>(j.size()) != n) {
      fail(where, "expected an array of " + std::to_string(n) + " numbers");
    }
    Eigen::VectorXd v(n);
    for (int i = 0; i < n; ++i) {
      v[i] = number(j[static_cast<std::size_t>(i)], where + "[" + std::to_string(i) + "]");
    }
    return v;
  }

  std::string string(const json& j, const std::string& where) const {
    if (!j.is_string()) fail(where, "expected a string");
    return j.get<std::string>();
  }

  int integer(const json& j, const std::string& where) const {
    if (!j.is_number_integer()) fail(where, "expected an integer");
    const auto v = j.get<std::int64_t>();
    if (v < -2147483647 || v > 2147483647) fail(where, "integer out of range");
    return static_cast<int>(v);
  }

  const json& array(const json& j, const std::string& where) const {
    if (!j.is_array()) fail(where, "expected an array");
    return j;
  }

 private:
  std::string name_;
};

}  // namespace

std::string WorldToJson(const World& world) {
  json j;
  j["format"] = "moslam-world";
  j["version"] = 1;
  j["name"] = world.name;
  j["classes"] = json::array();
  for (const auto& c : world.classes) {
    j["classes"].push_back({{"label", c.label}, {"extent", Vec(c.extent)}});
  }
  j["objects"] = json::array();
  for (const auto& o : world.objects) {
    const Eigen::Vector4d q = o.pose.rotation().quaternionWxyz();
    j["objects"].push_back({{"id", o.id},
                            {"label", o.label},
                            {"translation", Vec(o.pose.translation())},
                            {"rotation", {q[1], q[2], q[3], q[0]}}});
  }
  j["rooms"] = json::array();
  for (const auto& r : world.rooms) {
    j["rooms"].push_back({{"name", r.name}, {"min", Vec(r.min)}, {"max", Vec(r.max)}});
  }
  json nodes = json::array(), edges = json::array();
  for (const auto& n : world.navigation.nodes) nodes.push_back(Vec(n));
  for (const auto& [a, b] : world.navigation.edges) edges.push_back({a, b});
  j["navigation"] = {{"nodes", nodes}, {"edges", edges}};
  return j.dump(1);
}

World WorldFromJson(const std::string& text, const std::string& name) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InvalidInputError(name + ": not valid JSON: " + e.what());
  }
  const JsonReader rd(name);
  rd.requireKeys(j, "top level",
                 {"format", "version", "name", "classes", "objects", "rooms", "navigation"});
  if (rd.string(j["format"], "format") != "moslam-world") {
    rd.fail("format", "expected \"moslam-world\"");
  }
  if (rd.integer(j["version"], "version") != 1) rd.fail("version", "only version 1 is supported");
  World w;
  w.name = rd.string(j["name"], "name");
  for (std::size_t i = 0; i < rd.array(j["classes"], "classes").size(); ++i) {
    const std::string at = "classes[" + std::to_string(i) + "]";
    const json& c = j["classes"][i];
    rd.requireKeys(c, at, {"label", "extent"});
    w.classes.push_back({rd.string(c["label"], at + ".label"), rd.vec(c["extent"], at + ".extent", 3)});
  }
  for (std::size_t i = 0; i < rd.array(j["objects"], "objects").size(); ++i) {
    const std::string at = "objects[" + std::to_string(i) + "]";
    const json& o = j["objects"][i];
    rd.requireKeys(o, at, {"id", "label", "translation", "rotation"});
    ObjectInstance inst;
    inst.id = rd.integer(o["id"], at + ".id");
    inst.label = rd.string(o["label"], at + ".label");
    const Eigen::VectorXd t = rd.vec(o["translation"], at + ".translation", 3);
    const Eigen::VectorXd q = rd.vec(o["rotation"], at + ".rotation", 4);
    // Any other finite quaternion is normalised, whatever its norm (SO3::FromQuaternion).
    if ((q.array() == 0.0).all()) rd.fail(at + ".rotation", "zero quaternion");
    inst.pose = SE3(SO3::FromQuaternion(q[3], q[0], q[1], q[2]), t);
    w.objects.push_back(inst);
  }
  for (std::size_t i = 0; i < rd.array(j["rooms"], "rooms").size(); ++i) {
    const std::string at = "rooms[" + std::to_string(i) + "]";
    const json& r = j["rooms"][i];
    rd.requireKeys(r, at, {"name", "min", "max"});
    w.rooms.push_back({rd.string(r["name"], at + ".name"), rd.vec(r["min"], at + ".min", 2),
                       rd.vec(r["max"], at + ".max", 2)});
  }
  const json& nav = j["navigation"];
  rd.requireKeys(nav, "navigation", {"nodes", "edges"});
  for (std::size_t i = 0; i < rd.array(nav["nodes"], "navigation.nodes").size(); ++i) {
    w.navigation.nodes.push_back(
        rd.vec(nav["nodes"][i], "navigation.nodes[" + std::to_string(i) + "]", 2));
  }
  for (std::size_t i = 0; i < rd.array(nav["edges"], "navigation.edges").size(); ++i) {
    const std::string at = "navigation.edges[" + std::to_string(i) + "]";
    const json& e = nav["edges"][i];
    if (!e.is_array() || e.size() != 2) rd.fail(at, "expected [i, j]");
    w.navigation.edges.emplace_back(rd.integer(e[0], at + "[0]"), rd.integer(e[1], at + "[1]"));
  }
  ValidateWorld(w, name);
  return w;
}

void SaveWorld(const std::string& path, const World& world) {
  std::ofstream out(path);
  if (!out) throw Error("cannot write world file '" + path + "'");
  out << WorldToJson(world) << "\n";
  if (!out) throw Error("error while writing world file '" + path + "'");
}

World LoadWorld(const std::string& path) { return WorldFromJson(ReadWholeFileOrThrow(path), path); }

}  // namespace moslam
