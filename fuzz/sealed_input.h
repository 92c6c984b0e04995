// The two decodings each cache-file harness runs (template cache, perception cache): the input as
// it is, and sealed with the checksum both formats end with (ByteWriter::seal, SealedBody),
// so that the fuzzer reaches the fields behind the checksum. The fingerprint the decoder expects
// is the one the input names (its bytes 8-15, after an 8-byte magic).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "moslam/common/byte_io.h"

template <class Decode>
void DecodeRawAndSealed(const std::uint8_t* data, std::size_t size, const Decode& decode) {
  const std::string raw(reinterpret_cast<const char*>(data), size);
  std::uint64_t fingerprint = 0;
  if (size >= 16) std::memcpy(&fingerprint, data + 8, sizeof(fingerprint));
  decode(raw, fingerprint);
  moslam::ByteWriter sealed;
  sealed.bytes(raw);
  sealed.seal();
  decode(sealed.data(), fingerprint);
}
