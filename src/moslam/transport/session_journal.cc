#include "moslam/transport/session_journal.h"

#include <algorithm>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/transport/record_bytes.h"

namespace moslam::transport_detail {
namespace {

// Version 2: an event record lists the pairs removed too (event_record.h).
constexpr char kJournalMagic[8] = {'M', 'O', 'S', 'L', 'R', 'D', 'V', '2'};
constexpr std::uint8_t kEventRecord = 2;
constexpr std::uint8_t kGroupRecord = 3;  // a group formed (batch: at the end)
constexpr std::uint8_t kSolveRecord = 4;  // online: a group solve finished
constexpr std::uint8_t kLeftRecord = 5;   // a partner found gone for good

// One record: its type byte, then `append`'s fields.
template <typename Fields, typename Append>
std::vector<std::uint8_t> Record(std::uint8_t type, const Fields& fields, Append append) {
  std::vector<std::uint8_t> r{type};
  append(fields, r);
  return r;
}

}  // namespace

SessionJournal::SessionJournal(const std::string& path, const SessionJournalRun& run,
                               const std::string& state_dir)
    : journal_(std::make_unique<Journal>(path)) {
  if (journal_->records().empty()) {
    journal_->append(JournalHeader(kJournalMagic, run.robot, run.fingerprint));
    return;
  }
  read(run, state_dir);
}

void SessionJournal::read(const SessionJournalRun& run, const std::string& state_dir) {
  const auto& records = journal_->records();
  const std::string& what = journal_->path();
  if (!IsJournalHeader(records.front(), kJournalMagic, run.robot, run.fingerprint, what)) {
    throw InvalidInputError("state directory " + state_dir +
                            " holds the rendezvous journal of another run (other robot, "
                            "scenario or options, or an older moslam): remove it or choose "
                            "another --out");
  }
  for (std::size_t i = 1; i < records.size(); ++i) {
    const std::vector<std::uint8_t>& record = records[i];
    const std::uint8_t type = JournalRecordReader(record, 0, what).u8("record type");
    switch (type) {
      case kLeftRecord: {
        const LeftRecord left = ReadLeftRecord(record, 1, what);
        if (left.robot >= run.num_robots) {
          throw InvalidInputError(what + ": a departure of a robot not among its partners");
        }
        contents_.left.push_back(left);
        break;
      }
      case kGroupRecord: {
        GroupRecord g = ReadGroupRecord(record, 1, what);
        if (!run.online && g.step != run.num_steps) {
          throw InvalidInputError(what + ": a batch journal's group record is not of the end");
        }
        if (g.robots.empty() || !std::binary_search(g.robots.begin(), g.robots.end(), run.robot) ||
            g.robots.back() >= run.num_robots) {
          throw InvalidInputError(what + ": a group record of robots not in the team");
        }
        const int step = static_cast<int>(g.step);
        contents_.groups[step] = std::move(g);  // the last attempt's
        ++contents_.group_records[step];
        break;
      }
      case kSolveRecord: {
        if (!run.online) throw InvalidInputError(what + ": a group solve in a batch journal");
        SolveRecord solve = ReadSolveRecord(record, 1, what);
        for (const auto& [k, x] : solve.estimate) {
          if (k.robot != run.robot) {
            throw InvalidInputError(what + ": a solve record holds another robot's variable");
          }
        }
        const int step = static_cast<int>(solve.step);
        contents_.solves[step] = std::move(solve);
        break;
      }
      case kEventRecord: {
        EventRecord event = ReadEventRecord(record, 1, what);
        if (event.event >= run.num_events) throw InvalidInputError(what + ": event out of range");
        const std::uint32_t index = event.event;
        contents_.events[index] = std::move(event);
        break;
      }
      default:
        throw InvalidInputError(what + ": unknown rendezvous journal record type " +
                                std::to_string(type));
    }
  }
  for (const auto& [step, solve] : contents_.solves) {
    if (!contents_.groups.count(step)) {
      throw InvalidInputError(what + ": the group solve of step " + std::to_string(step) +
                              " has no group record");
    }
  }
}

void SessionJournal::append(const EventRecord& record) {
  journal_->append(Record(kEventRecord, record, AppendEventRecord));
}
void SessionJournal::append(const GroupRecord& record) {
  journal_->append(Record(kGroupRecord, record, AppendGroupRecord));
}
void SessionJournal::append(const SolveRecord& record) {
  journal_->append(Record(kSolveRecord, record, AppendSolveRecord));
}
void SessionJournal::append(const LeftRecord& record) {
  journal_->append(Record(kLeftRecord, record, AppendLeftRecord));
}

}  // namespace moslam::transport_detail
