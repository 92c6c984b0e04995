// FNV-1a 64 (Fowler-Noll-Vo): the project's one non-cryptographic hash of bytes, for keys and
// fingerprints that only need to change when their input does (journal runs, template cache).
#pragma once

#include <cstddef>
#include <cstdint>

namespace moslam {

constexpr std::uint64_t kFnvOffset = 1469598103934665603ull;
constexpr std::uint64_t kFnvPrime = 1099511628211ull;

// FNV-1a 64 of `n` bytes, continuing from `state` (chain calls to hash several buffers).
inline std::uint64_t Fnv1a64(const void* data, std::size_t n, std::uint64_t state = kFnvOffset) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) state = (state ^ p[i]) * kFnvPrime;
  return state;
}

}  // namespace moslam
