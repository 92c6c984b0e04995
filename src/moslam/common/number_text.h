// Numbers in the text files a user hands moslam (g2o graphs, TUM trajectories and sequences, YOLO
// labels), read one way whatever the process's locale: std::from_chars, the C locale's syntax
// ("0.5" is a half under a German locale too, where streams and strtod would stop at the point).
// A whole token only: a leading '+' is taken; blanks, hexadecimal ("0x1p3"), NaN and Inf are not.
#pragma once

#include <charconv>
#include <cmath>
#include <string>
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

// What a reader says of a token ParseNumberToken refused ("'1.5abc' is not a number"); `type`
// names the type asked for ("a double").
inline std::string NumberStatusReason(NumberStatus status, const char* type) {
  switch (status) {
    case NumberStatus::kOk:
      return "is a number";
    case NumberStatus::kNotANumber:
      return "is not a number";
    case NumberStatus::kOutOfRange:
      return std::string("is out of the range of ") + type;
    case NumberStatus::kNotFinite:
      break;
  }
  return "is not finite (NaN and Inf are not allowed)";
}

}  // namespace moslam
