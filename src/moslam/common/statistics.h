// Summary statistics of samples, for the experiments' and benchmarks' reports.
#pragma once

#include <algorithm>
#include <limits>
#include <vector>

namespace moslam {

// The median (the mean of the two middle values for an even count); NaN when empty.
inline double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The arithmetic mean; NaN when empty.
inline double Mean(const std::vector<double>& v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

}  // namespace moslam
