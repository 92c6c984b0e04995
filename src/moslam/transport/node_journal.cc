#include "moslam/transport/node_journal.h"

#include <fmt/core.h>

#include "moslam/common/errors.h"
#include "moslam/transport/record_bytes.h"
#include "moslam/transport/step_record.h"

namespace moslam::transport_detail {
namespace {

constexpr char kJournalMagic[8] = {'M', 'O', 'S', 'L', 'J', 'N', 'L', '4'};

enum class RecordType : std::uint8_t {
  kHeader = 1,  // magic, robot, fingerprint
  kStart = 2,   // a process start
  kTeam = 3,    // the team's robots
  kStep = 4,    // a completed channel step: its number, stage and what it returned
  kLeft = 5,    // a robot left: robot, step
  kDone = 7,    // finished
};

std::vector<std::uint8_t> Tag(RecordType type) {
  return WireWriter().u8(static_cast<std::uint8_t>(type)).data();
}

}  // namespace

NodeJournal::NodeJournal(const std::string& path, int robot, std::uint64_t fingerprint,
                         const std::string& state_dir)
    : journal_(path) {
  const auto& records = journal_.records();
  if (records.empty()) {
    journal_.append(JournalHeader(kJournalMagic, robot, fingerprint));
    return;
  }
  const std::string& what = journal_.path();
  if (!IsJournalHeader(records[0], kJournalMagic, robot, fingerprint, what)) {
    throw InvalidInputError("state directory " + state_dir +
                            " holds the journal of another run (other robot, data or options, "
                            "or an older moslam): remove it or choose another --out");
  }
  for (std::size_t i = 1; i < records.size(); ++i) {
    ByteReader p = JournalRecordReader(records[i], 0, what);
    const auto type = static_cast<RecordType>(p.u8("record type"));
    switch (type) {
      case RecordType::kStart:
        ++starts_;
        break;
      case RecordType::kTeam: {
        const int n = p.u16("team size");
        for (int k = 0; k < n; ++k) team_.insert(p.u16("team robot"));
        break;
      }
      case RecordType::kStep:
      case RecordType::kLeft:
      case RecordType::kDone:
        pending_.push_back(i);
        break;
      default:
        throw InvalidInputError(what + ": unknown journal record type " +
                                std::to_string(static_cast<int>(type)));
    }
  }
}

std::optional<TeamStep> NodeJournal::replay(std::uint32_t s, DgsStage stage, std::set<int>& left,
                                            bool& done) {
  const std::string& what = journal_.path();
  while (next_ < pending_.size()) {
    const std::vector<std::uint8_t>& record = journal_.records()[pending_[next_++]];
    ByteReader p = JournalRecordReader(record, 0, what);
    const auto type = static_cast<RecordType>(p.u8("record type"));
    if (type == RecordType::kLeft) {
      left.insert(p.u16("robot"));
      (void)p.u32("step");
      continue;
    }
    if (type == RecordType::kDone) {
      done = true;
      continue;
    }
    StepRecord rec = ReadStepRecord(record, 1, what);
    if (rec.step != s || rec.stage != stage) {
      throw InvalidInputError(fmt::format(
          "{}: journal step {} ({}) where the program takes step {} ({}): damaged journal", what,
          rec.step, ToString(rec.stage), s, ToString(stage)));
    }
    return std::move(rec.result);
  }
  return std::nullopt;
}

void NodeJournal::recordStart() { journal_.append(Tag(RecordType::kStart)); }

void NodeJournal::recordTeam(const std::set<int>& team) {
  WireWriter b;
  b.u8(static_cast<std::uint8_t>(RecordType::kTeam)).u16(static_cast<std::uint16_t>(team.size()));
  for (int r : team) b.u16(static_cast<std::uint16_t>(r));
  journal_.append(b.data());
}

void NodeJournal::recordStep(std::uint32_t s, DgsStage stage, const TeamStep& got) {
  std::vector<std::uint8_t> bytes = Tag(RecordType::kStep);
  AppendStepRecord({s, stage, got}, bytes);
  journal_.append(bytes);
}

void NodeJournal::recordLeft(int robot, std::uint32_t s) {
  WireWriter b(1 + 2 + 4);  // reserved: one allocation (and no false -Wstringop-overflow)
  b.u8(static_cast<std::uint8_t>(RecordType::kLeft)).u16(static_cast<std::uint16_t>(robot)).u32(s);
  journal_.append(b.data());
}

void NodeJournal::recordDone() { journal_.append(Tag(RecordType::kDone)); }

}  // namespace moslam::transport_detail
