// Numbers in the text files a user hands moslam (g2o graphs, TUM trajectories and sequences, YOLO
// labels), read one way whatever the process's locale: std::from_chars, the C locale's syntax
// ("0.5" is a half under a German locale too, where streams and strtod would stop at the point).
// A whole token only: a leading '+' is taken; blanks, hexadecimal ("0x1p3"), NaN and Inf are not.
#pragma once

#include <charconv>
#include <cmath>
#include <string_view>
#include <system_error>
#include <type_traits>

namespace moslam {

enum class NumberStatus { kOk, kNotANumber, kOutOfRange, kNotFinite };

// The token as a finite T (float, double or an integer type) into `value`; on any other status
// `value` is left as it was.
template <typename T>
NumberStatus ParseNumberToken(std::string_view token, T& value) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+') {
    token.remove_prefix(1);  // from_chars does not take a leading '+'
  }
  T parsed{};
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, parsed);
  if (ec == std::errc::result_out_of_range) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotANumber;
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(parsed)) return NumberStatus::kNotFinite;
  }
  value = parsed;
  return NumberStatus::kOk;
}

}  // namespace moslam
