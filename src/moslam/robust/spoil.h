// Spoiled multi-robot pose graphs: wrong inter-robot loop closures added to a clean graph, to
// measure outlier rejection (`moslam spoil`; the robust tables of the README).
//
// A fraction P of the separators of the result are outliers: k = round(P / (1 - P) * n) are added
// to the n separators of the input. Each joins a pose of one robot to a pose of another (robots
// and poses uniform, both with poses, never an existing pair), with a uniformly random rotation, a
// translation of the length of a random existing separator in a uniformly random direction, and
// that separator's information: plausible to anything that looks at one factor alone.
// Deterministic for a seed.
//
// A graph of one robot: its loop closures take the separators' place (the factors between two
// of its poses that are not consecutive, which the robust solve treats as robust: gnc.h,
// DefaultRobustFactors), and each wrong one joins two of its poses that are not consecutive: the
// random loop closures of the robust single-robot benchmarks (e.g. INTEL, M3500 with outliers).
#pragma once

#include <cstdint>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct SpoilOptions {
  double fraction = 0.5;   // of the separators after spoiling, in [0, 1)
  std::uint32_t seed = 1;
  // The wrong factors in the x-y plane, as a planar graph's (2D g2o files): a rotation about z
  // by a uniform angle, a translation in a uniform direction of the plane.
  bool planar = false;
  // Throws InvalidInputError naming the bad field.
  void validate() const;
};

struct SpoiledGraph {
  PoseGraph graph;              // the input's factors, then the outliers
  std::vector<bool> outlier;    // per factor of graph
  int separators = 0;           // of the input (one robot: its loop closures)
  int added = 0;
  bool single_robot = false;  // the graph has one robot with poses: loop closures imitated
};

// Throws InvalidInputError when the graph has no pose or nothing to imitate (no separator; one
// robot: no loop closure).
SpoiledGraph SpoilSeparators(const PoseGraph& graph, const SpoilOptions& options);

}  // namespace moslam
