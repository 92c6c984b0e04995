#include "moslam/robust/max_clique.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>

namespace moslam {

ConsistencyGraph::ConsistencyGraph(int nodes)
    : n_(nodes), words_((nodes + 63) / 64),
      bits_(static_cast<std::size_t>(std::max(nodes, 0)) * static_cast<std::size_t>((nodes + 63) / 64), 0) {
  if (nodes < 0) throw std::invalid_argument("ConsistencyGraph: negative size");
}

void ConsistencyGraph::connect(int i, int j) {
  if (i < 0 || j < 0 || i >= n_ || j >= n_ || i == j) {
    throw std::out_of_range("ConsistencyGraph::connect(" + std::to_string(i) + ", " +
                            std::to_string(j) + ")");
  }
  bits_[static_cast<std::size_t>(i) * words_ + j / 64] |= std::uint64_t{1} << (j % 64);
  bits_[static_cast<std::size_t>(j) * words_ + i / 64] |= std::uint64_t{1} << (i % 64);
}

bool ConsistencyGraph::adjacent(int i, int j) const {
  return (bits_[static_cast<std::size_t>(i) * words_ + j / 64] >> (j % 64)) & 1u;
}

int ConsistencyGraph::degree(int i) const {
  int d = 0;
  for (int w = 0; w < words_; ++w) {
    d += __builtin_popcountll(bits_[static_cast<std::size_t>(i) * words_ + w]);
  }
  return d;
}

// The search works in a relabelled graph (nodes by decreasing degree: the colouring bound is
// tighter), on bit sets of candidate nodes.
struct CliqueSearch {
  int n, words;
  std::vector<std::uint64_t> adj;  // relabelled rows
  std::vector<int> label;          // relabelled -> original
  std::vector<int> current, best;
  long long explored = 0, max_nodes = 0;
  bool stopped = false;

  using Set = std::vector<std::uint64_t>;

  static bool Empty(const Set& s) {
    for (std::uint64_t w : s) {
      if (w) return false;
    }
    return true;
  }

  // Greedy colouring of `p`: nodes in colour order and the colour (1-based) of each, so that
  // colour[k] bounds the clique size among order[0..k].
  void colour(const Set& p, std::vector<int>& order, std::vector<int>& colours) const {
    order.clear();
    colours.clear();
    Set uncoloured = p;
    int c = 0;
    while (!Empty(uncoloured)) {
      ++c;
      Set q = uncoloured;
      while (!Empty(q)) {
        int w = 0;
        while (!q[static_cast<std::size_t>(w)]) ++w;
        const int v = w * 64 + __builtin_ctzll(q[static_cast<std::size_t>(w)]);
        q[static_cast<std::size_t>(w)] &= q[static_cast<std::size_t>(w)] - 1;  // drop v
        uncoloured[static_cast<std::size_t>(v / 64)] &= ~(std::uint64_t{1} << (v % 64));
        const std::uint64_t* row = &adj[static_cast<std::size_t>(v) * words];
        for (int k = 0; k < words; ++k) q[static_cast<std::size_t>(k)] &= ~row[k];
        order.push_back(v);
        colours.push_back(c);
      }
    }
  }

  void expand(Set p) {
    if (stopped) return;
    if (++explored > max_nodes) {
      stopped = true;
      return;
    }
    std::vector<int> order, colours;
    colour(p, order, colours);
    for (int k = static_cast<int>(order.size()) - 1; k >= 0; --k) {
      if (static_cast<int>(current.size()) + colours[static_cast<std::size_t>(k)] <=
          static_cast<int>(best.size())) {
        return;
      }
      const int v = order[static_cast<std::size_t>(k)];
      current.push_back(v);
      Set next(static_cast<std::size_t>(words));
      const std::uint64_t* row = &adj[static_cast<std::size_t>(v) * words];
      for (int w = 0; w < words; ++w) next[static_cast<std::size_t>(w)] = p[static_cast<std::size_t>(w)] & row[w];
      if (Empty(next)) {
        if (current.size() > best.size()) best = current;
      } else {
        expand(std::move(next));
      }
      current.pop_back();
      p[static_cast<std::size_t>(v / 64)] &= ~(std::uint64_t{1} << (v % 64));
      if (stopped) return;
    }
  }
};

CliqueResult MaximumClique(const ConsistencyGraph& graph, const std::vector<bool>& allowed,
                           long long max_nodes) {
  const int n = graph.size();
  if (!allowed.empty() && static_cast<int>(allowed.size()) != n) {
    throw std::invalid_argument("MaximumClique: allowed has the wrong size");
  }
  std::vector<int> nodes;
  for (int i = 0; i < n; ++i) {
    if (allowed.empty() || allowed[static_cast<std::size_t>(i)]) nodes.push_back(i);
  }
  CliqueResult result;
  if (nodes.empty()) return result;
  std::vector<int> degree(static_cast<std::size_t>(n));
  for (int i : nodes) degree[static_cast<std::size_t>(i)] = graph.degree(i);
  std::stable_sort(nodes.begin(), nodes.end(), [&](int a, int b) {
    return degree[static_cast<std::size_t>(a)] > degree[static_cast<std::size_t>(b)];
  });
  CliqueSearch s;
  s.n = static_cast<int>(nodes.size());
  s.words = (s.n + 63) / 64;
  s.label = nodes;
  s.max_nodes = max_nodes;
  s.adj.assign(static_cast<std::size_t>(s.n) * s.words, 0);
  for (int a = 0; a < s.n; ++a) {
    for (int b = a + 1; b < s.n; ++b) {
      if (!graph.adjacent(nodes[static_cast<std::size_t>(a)], nodes[static_cast<std::size_t>(b)])) continue;
      s.adj[static_cast<std::size_t>(a) * s.words + b / 64] |= std::uint64_t{1} << (b % 64);
      s.adj[static_cast<std::size_t>(b) * s.words + a / 64] |= std::uint64_t{1} << (a % 64);
    }
  }
  CliqueSearch::Set all(static_cast<std::size_t>(s.words), 0);
  for (int a = 0; a < s.n; ++a) all[static_cast<std::size_t>(a / 64)] |= std::uint64_t{1} << (a % 64);
  s.best = {0};  // any single node is a clique
  s.expand(all);
  for (int v : s.best) result.nodes.push_back(s.label[static_cast<std::size_t>(v)]);
  std::sort(result.nodes.begin(), result.nodes.end());
  result.exact = !s.stopped;
  result.explored = s.explored;
  return result;
}

}  // namespace moslam
