// Procedural coloured triangle meshes of the simulation's object classes, and their sampling to
// coloured, oriented point sets (the registration templates of pose_estimation/).
//
// Frame (sim/world.h): the object frame is centred on the object's centre, x forward (the side a
// person faces when using it: a chair's seat front, a tv's screen, a fridge's door), y left, z up;
// the mesh fits inside the class extent [-e/2, e/2] and its lowest point lies at z = -e.z / 2
// (on the floor for objects standing on it). Units: metres.
//
// Every model is built from parts (boxes, prisms, frustums) with a material each, and is made
// asymmetric in shape or colour so that a partial view fixes its orientation (notes/frontend.md
// item 6): parts sit off-centre (a chair's backrest at -x, a desk's drawer pedestal at +y, a
// lamp's arm towards +x), materials carry stripe/checker patterns, and the whole object's
// brightness varies linearly along its x and y axes (Mesh::gradient).
//
// Colours are procedural: Mesh::colourAt(triangle, point) evaluates the triangle's material (and
// the gradient) at any point of the object frame, so the renderer and the sampler colour every
// pixel/point the same way without texture images.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/render/point_set.h"
#include "moslam/sim/world.h"

namespace moslam {

struct Material {
  enum class Pattern { kSolid, kStripes, kChecker };
  cv::Vec3b colour_bgr{128, 128, 128};
  cv::Vec3b secondary_bgr{64, 64, 64};  // the pattern's second colour
  Pattern pattern = Pattern::kSolid;
  int axis = 0;             // kStripes: stripes across this object axis (0 x, 1 y, 2 z);
                            // kChecker: the two axes other than this one
  double period_m = 0.1;    // length of one colour band (m)
};

struct Mesh {
  std::vector<Vector3> vertices;
  // Vertex indices, counter-clockwise seen from outside: the normal (b - a) x (c - a) points out.
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int> triangle_material;  // per triangle, index into materials
  std::vector<Material> materials;
  // Brightness factor 1 + gradient . p (clamped to [0.3, 1.7]) applied to every colour.
  Vector3 gradient = Vector3::Zero();
  // When false (walls), triangles are seen from both sides (the renderer does not cull them).
  bool closed = true;

  std::size_t size() const { return triangles.size(); }
  Vector3 normal(std::size_t triangle) const;  // unit, outward
  double area(std::size_t triangle) const;     // m^2
  double totalArea() const;
  // Colour (BGR) of `triangle`'s material at `point` (mesh frame), with the gradient applied.
  cv::Vec3b colourAt(std::size_t triangle, const Vector3& point) const;

  // Building blocks (used by the models; public for tests and custom models). Each returns the
  // index of the material it added. Boxes are axis-aligned, given by their min and max corners;
  // prisms/frustums stand on z = z0, axis along z, with `sides` >= 3 side faces.
  int addMaterial(const Material& m);
  void addBox(const Vector3& min, const Vector3& max, int material);
  void addFrustum(const Eigen::Vector2d& centre_xy, double z0, double z1, double radius_bottom,
                  double radius_top, int sides, int material);
  // A planar quad a-b-c-d (in order around it); `outward` chooses which side is the front.
  void addQuad(const Vector3& a, const Vector3& b, const Vector3& c, const Vector3& d,
               const Vector3& outward, int material);
  // Axis-aligned bounds of the vertices (min, max); zero for an empty mesh.
  std::pair<Vector3, Vector3> bounds() const;
};

// The model of one class, sized by its extent. The labels of StandardObjectClasses() get their
// own shapes; any other label gets a generic block: a box over the full footprint from the
// bottom to 70% of the height, and a box over x in [0, e.x/2], y in [-e.y/2, e.y/4] above it up to
// the top (colours derived from the label).
// Throws InvalidInputError when the extent is not positive and finite.
Mesh MakeObjectMesh(const ObjectClass& object_class);

// Area-uniform random points on the mesh surface: about totalArea / spacing^2 points (at least
// one per mesh with positive area), each with its triangle's outward unit normal and its colour.
// Deterministic for a given seed. Throws InvalidInputError when spacing_m is not positive and
// finite or when the mesh has more than 5e7 expected points.
ColoredPointSet SampleMeshSurface(const Mesh& mesh, double spacing_m, unsigned seed);

// The points of `points` (sampled on `mesh`) that a camera outside the object can see: a point is
// kept when the ray from it towards at least one of `num_views` viewpoints (evenly spread over the
// upper hemisphere, at 3x the mesh's size, elevation 0 to 90 deg), starting on the side its
// normal points to, leaves the mesh without hitting a triangle. This removes the faces where two
// parts touch (a leg's top under a seat) and the bottom faces on the floor, which no camera sees.
// Throws InvalidInputError when num_views < 1 or the sizes of `points` disagree.
ColoredPointSet KeepVisibleFromOutside(const Mesh& mesh, const ColoredPointSet& points,
                                       int num_views = 40);

// SampleMeshSurface followed by KeepVisibleFromOutside: the registration template of a class.
ColoredPointSet SampleVisibleSurface(const Mesh& mesh, double spacing_m, unsigned seed);

}  // namespace moslam
