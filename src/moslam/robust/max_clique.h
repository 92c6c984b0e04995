// Maximum cliques of consistency graphs, the combinatorial core of outlier rejection by pairwise
// consistency (PCM, Mangelson et al. 2018; CLIPPER): the nodes are candidate measurements or
// associations, an edge says two of them agree, and the largest set that agrees pairwise is a
// maximum clique.
//
// MaximumClique is exact: branch and bound with a greedy-colouring bound (Tomita and Seki's MCQ)
// on bit sets. Its worst case is exponential; `max_nodes` bounds the search (the result is then
// the largest clique found, with exact = false). Measured: 625 candidate chair associations of
// two 25-chair maps in well under a millisecond (robust_test).
#pragma once

#include <cstdint>
#include <vector>

namespace moslam {

class ConsistencyGraph {
 public:
  explicit ConsistencyGraph(int nodes);
  int size() const { return n_; }
  // An undirected edge (i != j).
  void connect(int i, int j);
  bool adjacent(int i, int j) const;
  int degree(int i) const;

 private:
  friend struct CliqueSearch;
  int n_, words_;
  std::vector<std::uint64_t> bits_;  // n_ rows of words_ words
};

struct CliqueResult {
  std::vector<int> nodes;  // increasing
  bool exact = true;       // false: the search stopped at max_nodes
  long long explored = 0;  // branch-and-bound nodes
};

// A maximum clique among the nodes with allowed[i] (all when empty).
CliqueResult MaximumClique(const ConsistencyGraph& graph, const std::vector<bool>& allowed = {},
                           long long max_nodes = 2000000);

}  // namespace moslam
