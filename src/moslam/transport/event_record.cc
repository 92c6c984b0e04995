#include "moslam/transport/event_record.h"

#include <set>

#include "moslam/common/errors.h"
#include "moslam/transport/record_bytes.h"

namespace moslam::transport_detail {

void AppendEventRecord(const EventRecord& record, std::vector<std::uint8_t>& out) {
  WireWriter b;
  b.u32(record.event);
  for (const ObjectPairs* list : {&record.pairs, &record.removed}) {
    b.u32(static_cast<std::uint32_t>(list->size()));
    for (const auto& [a, c] : *list) b.u32(a).u32(c);
  }
  out.insert(out.end(), b.data().begin(), b.data().end());
}

EventRecord ReadEventRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what) {
  ByteReader p = JournalRecordReader(bytes, offset, what);
  EventRecord record;
  record.event = p.u32("event");
  for (ObjectPairs* list : {&record.pairs, &record.removed}) {
    const std::uint32_t n = p.count(8, "pair");
    std::set<std::uint32_t> alpha, beta;
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::uint32_t a = p.u32("alpha object"), c = p.u32("beta object");
      if (!alpha.insert(a).second || !beta.insert(c).second) {
        throw InvalidInputError(what + ": a rendezvous record uses object " +
                                std::to_string(alpha.count(a) ? a : c) + " twice in one list");
      }
      list->emplace_back(a, c);
    }
  }
  if (!p.atEnd()) p.fail("trailing bytes after a rendezvous record");
  return record;
}

void AppendLeftRecord(const LeftRecord& record, std::vector<std::uint8_t>& out) {
  WireWriter b;
  b.u16(record.robot).u32(record.step);
  out.insert(out.end(), b.data().begin(), b.data().end());
}

LeftRecord ReadLeftRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                          const std::string& what) {
  ByteReader p = JournalRecordReader(bytes, offset, what);
  LeftRecord record;
  record.robot = p.u16("robot");
  record.step = p.u32("step");
  if (!p.atEnd()) p.fail("trailing bytes after a departure record");
  return record;
}

}  // namespace moslam::transport_detail
