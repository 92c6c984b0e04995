// libFuzzer target: what a restarted robot reads back from its journal (transport/journal.h): the
// record framing (length, CRC-32, a torn or corrupt tail) of journal.bin, and the protocol step
// records of the DGS node (transport/step_record.h), whose estimates and coarse shares go to the
// decoders of distributed/messages.h, and the rendezvous event records of a robot session
// (transport/event_record.h) and the group, solve and departure records of an online session
// (transport/solve_record.h, event_record.h), and a DGS node's whole journal as a restarted node
// reads it (transport/node_journal.h: the input's records, each a u16 length and its bytes,
// appended after the node's header, then replayed step by step). The first byte picks which; the
// rest is its input. A malformed input may only be rejected with a moslam::Error (the framing: cut
// at the first bad record); any other exception, a crash, a sanitizer report or a hang is a bug. A
// step, event, group, solve or departure record that is accepted must encode back to the same
// bytes.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/node_journal.h"
#include "moslam/transport/solve_record.h"
#include "moslam/transport/step_record.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

// One scratch file per fuzzing process and use, removed when the process exits.
std::string ScratchFile(const char* use) {
  std::string p = std::string("/tmp/moslam_journal_fuzz_") + use + "_" + std::to_string(::getpid());
  static std::vector<std::string>* to_remove = [] {
    auto* v = new std::vector<std::string>;
    std::atexit([] {
      for (const std::string& f : *to_remove) std::remove(f.c_str());
    });
    return v;
  }();
  to_remove->push_back(p);
  return p;
}

void Framing(const std::vector<std::uint8_t>& bytes) {
  static const std::string path = ScratchFile("framing");
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

// A node journal holding the input's records after its header, replayed as a restarted node
// does: the team and starts it reads, then steps 1, 2, ... (alternating stages) until one is
// missing or refused.
void NodeJournalReplay(const std::vector<std::uint8_t>& bytes) {
  using moslam::transport_detail::NodeJournal;
  static const std::string path = ScratchFile("node");
  std::remove(path.c_str());
  { NodeJournal fresh(path, 1, 42, "fuzz"); }  // the header
  {
    moslam::Journal raw(path);
    for (std::size_t i = 0; i + 2 <= bytes.size();) {
      const std::size_t n = bytes[i] | static_cast<std::size_t>(bytes[i + 1]) << 8;
      i += 2;
      const std::size_t take = n < bytes.size() - i ? n : bytes.size() - i;
      raw.append(std::vector<std::uint8_t>(bytes.begin() + static_cast<std::ptrdiff_t>(i),
                                           bytes.begin() + static_cast<std::ptrdiff_t>(i + take)));
      i += take;
    }
  }
  NodeJournal journal(path, 1, 42, "fuzz");
  Require(journal.starts() >= 0);
  for (int r : journal.team()) Require(r >= 0 && r <= 0xFFFF);
  std::set<int> left;
  bool done = false;
  for (std::uint32_t s = 1; s <= 64 && journal.replaying(); ++s) {
    const auto stage = s % 2 ? moslam::DgsStage::kRotation : moslam::DgsStage::kPose;
    if (!journal.replay(s, stage, left, done)) break;
  }
  for (int r : left) Require(r >= 0 && r <= 0xFFFF);
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
    switch (data[0] % 7) {
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
      case 5:
        RoundTrip(bytes, ReadLeftRecord, AppendLeftRecord);
        break;
      default:
        NodeJournalReplay(bytes);
    }
  } catch (const moslam::Error&) {
  }
  return 0;
}
