// libFuzzer target: what a restarted robot reads back from its journal (transport/journal.h): the
// record framing (length, CRC-32, a torn or corrupt tail) of journal.bin, and the protocol step
// records of the DGS node (transport/step_record.h), whose estimates and coarse shares go to the
// decoders of distributed/messages.h, and the rendezvous event records of a robot session
// (transport/event_record.h) and the group, solve and departure records of an online session
// (transport/solve_record.h, event_record.h). The first byte picks which; the rest is its
// input. A malformed input may only be rejected with a moslam::Error (the framing: cut at the
// first bad record); any other exception, a crash, a sanitizer report or a hang is a bug. A
// step, event, group, solve or departure record that is accepted must encode back to the same
// bytes.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/solve_record.h"
#include "moslam/transport/step_record.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

void Framing(const std::vector<std::uint8_t>& bytes) {
  // One scratch file per fuzzing process, removed when the process exits.
  static const std::string path = [] {
    std::string p = "/tmp/moslam_journal_fuzz_" + std::to_string(::getpid());
    static std::string* to_remove = new std::string(p);
    std::atexit([] { std::remove(to_remove->c_str()); });
    return p;
  }();
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

// A record the reader accepts must encode back to the same bytes.
template <typename Read, typename Append>
void RoundTrip(const std::vector<std::uint8_t>& bytes, Read read, Append append) {
  const auto record = read(bytes, 0, "fuzz");
  std::vector<std::uint8_t> again;
  append(record, again);
  Require(again == bytes);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace moslam::transport_detail;
  if (size == 0) return 0;
  const std::vector<std::uint8_t> bytes(data + 1, data + size);
  try {
    switch (data[0] % 6) {
      case 0:
        Framing(bytes);
        break;
      case 1:
        RoundTrip(bytes, ReadStepRecord, AppendStepRecord);
        break;
      case 2:
        RoundTrip(bytes, ReadEventRecord, AppendEventRecord);
        break;
      case 3:
        RoundTrip(bytes, ReadGroupRecord, AppendGroupRecord);
        break;
      case 4:
        RoundTrip(bytes, ReadSolveRecord, AppendSolveRecord);
        break;
      default:
        RoundTrip(bytes, ReadLeftRecord, AppendLeftRecord);
    }
  } catch (const moslam::Error&) {
  }
  return 0;
}
