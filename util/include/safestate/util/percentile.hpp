// Percentiles of measured samples, one definition for every bench and tool (issue 35: there
// were four, with three different ranks). The nearest-rank method: the q-percentile is the
// smallest sample with at least a fraction q of all samples at or below it (rank ceil(q n)),
// so p100 is the maximum and no value is interpolated between two samples.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace safestate::util {

// `sorted` ascending; q in [0, 1]. An empty set gives T{}.
template <typename T>
[[nodiscard]] T percentile_sorted(const std::vector<T>& sorted, double q) {
  if (sorted.empty()) {
    return T{};
  }
  const double n = static_cast<double>(sorted.size());
  const double rank = std::ceil(std::clamp(q, 0.0, 1.0) * n);  // 1-based
  const std::size_t i = (rank < 1.0) ? 0U : static_cast<std::size_t>(rank) - 1U;
  return sorted[std::min(i, sorted.size() - 1U)];
}

// Sorts `v` (taken by value) and returns its q-percentile.
template <typename T>
[[nodiscard]] T percentile(std::vector<T> v, double q) {
  std::sort(v.begin(), v.end());
  return percentile_sorted(v, q);
}

}  // namespace safestate::util
