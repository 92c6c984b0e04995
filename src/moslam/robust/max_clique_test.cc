#include "moslam/robust/max_clique.h"

#include <gtest/gtest.h>

#include <random>

namespace moslam {
namespace {

// The largest clique by enumerating every subset (small graphs only).
int BruteForceClique(const ConsistencyGraph& g) {
  const int n = g.size();
  int best = 0;
  for (unsigned mask = 1; mask < (1u << n); ++mask) {
    int size = 0;
    bool clique = true;
    for (int i = 0; i < n && clique; ++i) {
      if (!(mask >> i & 1u)) continue;
      ++size;
      for (int j = i + 1; j < n && clique; ++j) {
        if ((mask >> j & 1u) && !g.adjacent(i, j)) clique = false;
      }
    }
    if (clique) best = std::max(best, size);
  }
  return best;
}

bool IsClique(const ConsistencyGraph& g, const std::vector<int>& nodes) {
  for (std::size_t a = 0; a < nodes.size(); ++a) {
    for (std::size_t b = a + 1; b < nodes.size(); ++b) {
      if (!g.adjacent(nodes[a], nodes[b])) return false;
    }
  }
  return true;
}

TEST(MaximumClique, EqualsBruteForceOnRandomGraphs) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 1 + static_cast<int>(rng() % 14);
    const double density = static_cast<double>(rng() % 100) / 100.0;
    ConsistencyGraph g(n);
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) {
        if (static_cast<double>(rng() % 1000) / 1000.0 < density) g.connect(i, j);
      }
    }
    const CliqueResult r = MaximumClique(g);
    ASSERT_TRUE(r.exact);
    EXPECT_TRUE(IsClique(g, r.nodes));
    EXPECT_EQ(static_cast<int>(r.nodes.size()), BruteForceClique(g)) << "trial " << trial;
  }
}

TEST(MaximumClique, FindsAPlantedCliqueAmongManyNodesAndHonoursAllowed) {
  std::mt19937 rng(7);
  const int n = 700;
  ConsistencyGraph g(n);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      if (rng() % 100 < 2) g.connect(i, j);  // sparse noise: cliques of 3-4 by chance
    }
  }
  const std::vector<int> planted = {5, 77, 130, 222, 301, 409, 555, 690};
  for (std::size_t a = 0; a < planted.size(); ++a) {
    for (std::size_t b = a + 1; b < planted.size(); ++b) g.connect(planted[a], planted[b]);
  }
  const CliqueResult r = MaximumClique(g);
  EXPECT_TRUE(r.exact);
  EXPECT_EQ(r.nodes, planted);
  std::vector<bool> allowed(n, true);
  allowed[130] = false;
  const CliqueResult without = MaximumClique(g, allowed);
  EXPECT_EQ(without.nodes.size(), planted.size() - 1);
  for (int v : without.nodes) EXPECT_NE(v, 130);
  // A search bound reports that it stopped.
  EXPECT_FALSE(MaximumClique(g, {}, 3).exact);
}

TEST(MaximumClique, EdgeCases) {
  EXPECT_TRUE(MaximumClique(ConsistencyGraph(0)).nodes.empty());
  ConsistencyGraph g(3);
  EXPECT_EQ(MaximumClique(g).nodes.size(), 1u);  // no edge: any single node
  EXPECT_THROW(g.connect(0, 0), std::out_of_range);
  EXPECT_THROW(g.connect(0, 3), std::out_of_range);
  EXPECT_THROW(MaximumClique(g, {true}), std::invalid_argument);
}

}  // namespace
}  // namespace moslam
