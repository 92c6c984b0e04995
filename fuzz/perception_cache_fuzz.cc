// libFuzzer target: the perception cache decoder (experiments/perception_cache.h), which reads
// perceived runs back from disk. The input is a cache file without its trailing checksum; the
// harness appends the right checksum (and expects the fingerprint the file names) so that the
// fuzzer reaches the fields behind them, and also decodes the raw bytes as they are. The decoder
// may only reject input with moslam::InvalidInputError; what it accepts must encode back to the
// same bytes.
#include <cstddef>
#include <cstdint>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/experiments/perception_cache.h"
#include "sealed_input.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

void Decode(const std::string& bytes, std::uint64_t fingerprint) {
  using namespace moslam;
  try {
    const PerceivedRun run = DecodePerceivedRun(bytes, fingerprint);
    Require(run.metrics.size() == kPerceptionMetrics.size());
    Require(EncodePerceivedRun(run, fingerprint) == bytes);
  } catch (const InvalidInputError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  DecodeRawAndSealed(data, size, Decode);
  return 0;
}
