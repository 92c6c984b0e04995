// libFuzzer target: ParseG2o on arbitrary bytes. The reader may only reject input with a
// moslam::Error; any other exception, a crash, a sanitizer report or a hang is a bug.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/io/g2o.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  for (const bool drop_coupling : {false, true}) {
    std::istringstream in(bytes);
    moslam::G2oReadOptions options;
    options.scheme =
        (size % 2 == 0) ? moslam::KeyScheme::kPosesOnly : moslam::KeyScheme::kWithObjects;
    options.drop_indefinite_coupling = drop_coupling;
    try {
      const moslam::Dataset d = moslam::ParseG2o(in, "fuzz.g2o", options);
      // What was accepted must be usable: every factor has SPD information (checked on
      // construction) and every key of the initial values is valid.
      for (const auto& factor : d.graph.factors()) {
        if (factor.a() == factor.b()) __builtin_trap();
        if (!factor.sqrtInformation().allFinite()) __builtin_trap();
      }
    } catch (const moslam::Error&) {
      // Rejected cleanly.
    }
  }
  return 0;
}
