// libFuzzer target: what a restarted robot reads back from its journal (transport/journal.h): the
// record framing (length, CRC-32, a torn or corrupt tail) of journal.bin, and the protocol step
// records of the DGS node (transport/step_record.h), whose estimates and coarse shares go to the
// decoders of distributed/messages.h, and the rendezvous event records of a robot session
// (transport/event_record.h). The first byte picks which; the rest is its input. A malformed
// input may only be rejected with a moslam::Error (the framing: cut at the first bad record); any
// other exception, a crash, a sanitizer report or a hang is a bug. A step or event record that is
// accepted must encode back to the same bytes.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/step_record.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

void Framing(const std::vector<std::uint8_t>& bytes) {
  static const std::string path = "/tmp/moslam_journal_fuzz_" + std::to_string(::getpid());
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    Require(f != nullptr);
    if (!bytes.empty()) Require(std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
    std::fclose(f);
  }
  std::size_t kept = 0;
  {
    moslam::Journal journal(path);
    for (const auto& r : journal.records()) kept += 8 + r.size();
    Require(kept + static_cast<std::size_t>(journal.truncatedBytes()) == bytes.size());
  }
  // Reopened after the cut: the same records, nothing more to cut.
  moslam::Journal again(path);
  std::size_t kept_again = 0;
  for (const auto& r : again.records()) kept_again += 8 + r.size();
  Require(kept_again == kept && again.truncatedBytes() == 0);
}

void Step(const std::vector<std::uint8_t>& bytes) {
  using namespace moslam::transport_detail;
  const StepRecord record = ReadStepRecord(bytes, 0, "fuzz");
  std::vector<std::uint8_t> again;
  AppendStepRecord(record, again);
  Require(again == bytes);
}

void Event(const std::vector<std::uint8_t>& bytes) {
  using namespace moslam::transport_detail;
  const EventRecord record = ReadEventRecord(bytes, 0, "fuzz");
  std::vector<std::uint8_t> again;
  AppendEventRecord(record, again);
  Require(again == bytes);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::vector<std::uint8_t> bytes(data + 1, data + size);
  try {
    switch (data[0] % 3) {
      case 0:
        Framing(bytes);
        break;
      case 1:
        Step(bytes);
        break;
      default:
        Event(bytes);
    }
  } catch (const moslam::Error&) {
  }
  return 0;
}
