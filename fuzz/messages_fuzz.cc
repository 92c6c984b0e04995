// libFuzzer target: every decoder of bytes a robot receives from another (DGS estimates, control,
// coarse, weight and covariance messages of distributed/messages.h; the object lists and shared
// objects of a rendezvous, slam/rendezvous.h). The first byte picks the decoder, the rest is its
// input. A decoder may only reject input with a moslam::Error; any other exception, a crash, a
// sanitizer report or a hang is a bug. What a fixed-layout decoder accepts must encode back to
// the same bytes.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/slam/rendezvous.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

void Decode(std::uint8_t which, const std::vector<std::uint8_t>& bytes) {
  using namespace moslam;
  switch (which % 7) {
    case 0: {
      const Message m = DecodeMessage(bytes);
      Require(m.values.size() == m.keys.size() * static_cast<std::size_t>(StageDimension(m.stage)));
      Require(DecodeMessage(EncodeMessage(m)).keys == m.keys);
      break;
    }
    case 1:
      Require(EncodeControlMessage(DecodeControlMessage(bytes)) == bytes);
      break;
    case 2: {
      const CoarseMessage m = DecodeCoarseMessage(bytes);
      DecodeCoarseMessage(EncodeCoarseMessage(m));
      break;
    }
    case 3:
      Require(EncodeWeightMessage(DecodeWeightMessage(bytes)) == bytes);
      break;
    case 4:
      Require(EncodeCovarianceMessage(DecodeCovarianceMessage(bytes)) == bytes);
      break;
    case 5:
      DecodeObjectMap(EncodeObjectMap(DecodeObjectMap(bytes)));
      break;
    default:
      DecodeSharedObjects(EncodeSharedObjects(DecodeSharedObjects(bytes)));
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::vector<std::uint8_t> bytes(data + 1, data + size);
  try {
    Decode(data[0], bytes);
  } catch (const moslam::Error&) {
    // Rejected cleanly.
  }
  return 0;
}
