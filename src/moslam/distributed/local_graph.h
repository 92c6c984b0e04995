// One robot's part of the pose graph as its distributed agent sees it (robot_agent.h): its
// variables, its inner factors and priors, its separators to other robots' variables, and which of
// its unknowns inner factors tie together. Immutable after construction; shared by every stage.
//
// Ownership is the robot in each key. Inner factors have both ends the robot's own; a separator
// has one end owned by another robot (a neighbour variable, numbered by a slot). The anchor (the
// first pose of robot 0, CONVENTIONS.md) is held at its initial value by the robot that owns it:
// it is not an unknown. The unknowns fall into groups connected through inner factors (the anchor
// does not join groups: it fixes each group it touches); a group can be solved only when the
// anchor, a prior or a usable separator ties it down.
#pragma once

#include <cstddef>
#include <map>
#include <set>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct Separator {
  std::size_t factor = 0;  // index into LocalGraph::factors()
  Key own, foreign;
  int foreign_robot = 0;
  int slot = 0;  // the foreign variable's index in LocalGraph::neighbours()
};

class LocalGraph {
 public:
  // `subgraph`: every factor touching a variable of `robot` (each must touch one). `initial`:
  // initial values; the robot's variables missing from it start at the identity. Throws
  // InvalidInputError on a factor or prior that touches none of the robot's variables,
  // UnderdeterminedError when the robot owns no variable.
  LocalGraph(int robot, const PoseGraph& subgraph, const Values& initial, const Key& anchor);

  int robot() const { return robot_; }
  const Key& anchor() const { return anchor_; }
  bool ownsAnchor() const { return owns_anchor_; }
  const SE3& initial(const Key& own_key) const { return initial_.at(own_key); }

  // The subgraph's factors and priors in canonical order (CanonicalBefore, pose_graph.h),
  // whatever order the subgraph lists them in, so that every sum over them rounds the same on a
  // robot that read its own file and in a driver that partitioned the whole graph.
  const std::vector<RelativePoseFactor>& factors() const { return factors_; }
  const std::vector<PriorFactor>& priors() const { return priors_; }
  const std::vector<std::size_t>& inner() const { return inner_; }  // indices into factors()
  const std::vector<Separator>& separators() const { return separators_; }

  const std::vector<Key>& own() const { return own_; }            // ordered, anchor included
  const std::vector<Key>& unknowns() const { return unknowns_; }  // own() without the anchor
  // Index of an unknown in unknowns(), -1 for any other key.
  int unknownIndex(const Key& key) const;

  const std::vector<Key>& neighbours() const { return neighbour_list_; }  // by slot, ordered
  const std::set<Key>& neighbourKeys() const { return neighbour_keys_; }
  int slot(const Key& key) const;  // -1 when not a neighbour variable
  std::set<int> neighbourRobots() const;
  // For each neighbouring robot, how many of its variables this robot needs.
  std::map<int, int> neighbourLinks() const;
  // For each neighbouring robot, which of this robot's variables it needs (ordered).
  const std::map<int, std::vector<Key>>& sharedWith() const { return shared_with_; }

  // Per unknown (by unknownIndex): whether its group of unknowns is tied down when the
  // separators with usable[s] are used.
  std::vector<bool> anchoredUnknowns(const std::vector<bool>& usable) const;

 private:
  // Construction, in order. The factors and priors of `subgraph`, inner or separators (the
  // robot's variables they touch returned); the neighbour variables' slots; the groups of unknowns
  // through inner factors, which of them the anchor or a prior fixes, and their separators.
  std::set<Key> takeFactors(const PoseGraph& subgraph);
  void numberNeighbours();
  void groupUnknowns();

  int robot_;
  Key anchor_;
  bool owns_anchor_ = false;
  std::vector<RelativePoseFactor> factors_;
  std::vector<PriorFactor> priors_;
  std::vector<std::size_t> inner_;
  std::vector<Separator> separators_;
  std::vector<Key> own_, unknowns_;
  std::map<Key, int> unknown_index_;
  std::set<Key> neighbour_keys_;
  std::vector<Key> neighbour_list_;
  std::map<Key, int> neighbour_slot_;
  std::map<int, std::vector<Key>> shared_with_;
  std::vector<int> group_of_;                             // per unknown
  std::vector<bool> group_fixed_;                         // per group of unknowns
  std::vector<std::vector<std::size_t>> group_separators_;  // per group: its separators
  Values initial_;                                        // own variables
};

}  // namespace moslam
