// Simulated worlds of objects for multi-robot object SLAM (paper Section 3.1).
//
// A world is a set of object instances (a class label and an SE(3) pose world_T_object, the pose
// of the object's centre; x forward, z up), the object classes they use (a label and a 3D extent:
// full size along the object's x, y, z in metres), optional rooms (axis-aligned rectangles, for
// plots) and a navigation graph (2D nodes on the floor and undirected edges) along which the robots
// drive (sim/robots.h). The world frame has z up and the floor at z = 0.
//
// Scenarios (all seeded and reproducible; the same config gives the same world bit for bit):
//   chairs25   25 chairs on a 5x5 grid (spacing 2.5 m), each at a random yaw; the robots drive
//              the aisles between them (a 6x6 lattice of nodes, 4-connected).
//   house      the furniture of a living room and a kitchen joined by a door, hand-placed.
//   generated  rooms on a grid joined by corridors, furniture per room (room types living,
//              kitchen, bedroom, office), for large teams (16-128 robots).
//
// JSON file (SaveWorld / LoadWorld), schema version 1:
//   {
//     "format": "moslam-world", "version": 1,
//     "name": "chairs25",
//     "classes":  [ {"label": "chair", "extent": [0.5, 0.5, 0.9]}, ... ],
//     "objects":  [ {"id": 0, "label": "chair",
//                    "translation": [x, y, z], "rotation": [qx, qy, qz, qw]}, ... ],
//     "rooms":    [ {"name": "living", "min": [x, y], "max": [x, y]}, ... ],
//     "navigation": {"nodes": [[x, y], ...], "edges": [[i, j], ...]}
//   }
// Units are metres; quaternions are in the g2o order (qx qy qz qw) and are normalised on load.
// Every key above is required ("rooms" may be an empty array) and no other key is accepted.
// Loading rejects, with InvalidInputError naming the file and what is wrong: malformed JSON, a
// wrong format/version, missing or unknown keys, wrong types or array sizes, non-finite numbers,
// an empty or duplicated class label, a non-positive extent, an object whose label is not a
// declared class, duplicated or negative object ids, a zero quaternion, a room with min >= max,
// an edge to a node that does not exist, a self-loop or a duplicated edge.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "moslam/geometry/se3.h"

namespace moslam {

using Vector2 = Eigen::Vector2d;

struct ObjectClass {
  std::string label;
  Vector3 extent = Vector3::Ones();  // full size along the object's x, y, z (m)
};

struct ObjectInstance {
  int id = 0;         // unique in its world; the ground-truth identity used for evaluation
  std::string label;  // one of the world's classes
  SE3 pose;           // world_T_object (centre of the object)
};

struct Room {
  std::string name;
  Vector2 min = Vector2::Zero();
  Vector2 max = Vector2::Ones();
};

struct NavigationGraph {
  std::vector<Vector2> nodes;              // floor positions (m)
  std::vector<std::pair<int, int>> edges;  // undirected, indices into nodes
  // neighbours[i]: the nodes joined to node i, in edge order.
  std::vector<std::vector<int>> neighbours() const;
};

struct World {
  std::string name;
  std::vector<ObjectClass> classes;
  std::vector<ObjectInstance> objects;
  std::vector<Room> rooms;
  NavigationGraph navigation;

  // nullptr when no class has this label.
  const ObjectClass* findClass(const std::string& label) const;
  // The object with this id; throws InvalidInputError when there is none.
  const ObjectInstance& object(int id) const;
};

// Throws InvalidInputError naming the first inconsistency (the rules listed for loading above).
// `what` prefixes the message (e.g. the file name).
void ValidateWorld(const World& world, const std::string& what = "world");

// The object classes of every scenario: chair, table, coffee_table, sofa, armchair, bed, shelf,
// tv, plant, fridge, counter, desk, lamp.
std::vector<ObjectClass> StandardObjectClasses();

struct Chairs25Config {
  int rows = 5;
  int cols = 5;
  double spacing = 2.5;  // m between neighbouring chairs (and between aisles)
  unsigned seed = 1;     // the chairs' yaws
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};
World MakeChairs25World(const Chairs25Config& config = {});

// Hand-placed, deterministic: a 7 x 5 m living room (sofa, armchairs, coffee table, tv, shelves,
// plants, lamp) and a 5 x 5 m kitchen (fridge, counters, dining table with four chairs, plant)
// joined by a door.
World MakeHouseWorld();

struct GeneratedWorldConfig {
  int rooms_x = 3;
  int rooms_y = 3;
  double room_size = 6.0;        // m, square rooms
  double corridor_length = 2.0;  // m between the walls of neighbouring rooms
  // Every room is reachable (a random spanning tree of the room grid); each other pair of
  // neighbouring rooms is also joined with this probability, making loops.
  double extra_door_probability = 0.3;
  int min_objects_per_room = 3;
  int max_objects_per_room = 6;
  double object_clearance = 0.7;   // m between an object's centre and any navigation edge
  double object_separation = 1.0;  // m between object centres
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};
World MakeGeneratedWorld(const GeneratedWorldConfig& config = {});

// A generated-world config sized for a team: about two robots per room (at least 2 x 2 rooms).
GeneratedWorldConfig GeneratedWorldForTeam(int num_robots, unsigned seed = 1);

// "chairs25" | "house" | "generated" (the latter sized by GeneratedWorldForTeam(num_robots)).
// Throws InvalidInputError on an unknown scenario name.
World MakeScenarioWorld(const std::string& scenario, unsigned seed = 1, int num_robots = 6);

// JSON text of the schema above (full double precision: a round trip is exact up to the
// quaternion normalisation). `name` is used in error messages.
std::string WorldToJson(const World& world);
World WorldFromJson(const std::string& text, const std::string& name = "<string>");
// Throws moslam::Error when the file cannot be written / InvalidInputError when it cannot be read.
void SaveWorld(const std::string& path, const World& world);
World LoadWorld(const std::string& path);

}  // namespace moslam
