#include "moslam/transport/step_record.h"

#include <cmath>

#include "moslam/common/errors.h"
#include "moslam/transport/record_bytes.h"

namespace moslam::transport_detail {

void AppendStepRecord(const StepRecord& record, std::vector<std::uint8_t>& out) {
  WireWriter b;
  b.u32(record.step).u8(static_cast<std::uint8_t>(record.stage));
  const TeamStep& got = record.result;
  b.u16(static_cast<std::uint16_t>(got.reports.size()));
  for (const auto& [r, rep] : got.reports) {
    const auto flags = static_cast<std::uint8_t>((rep.sent ? 1 : 0) | (rep.initialised ? 2 : 0) |
                                                 (rep.coarse_ready ? 4 : 0) |
                                                 (rep.has_share ? 8 : 0) |
                                                 (rep.weights ? 16 : 0) |
                                                 (rep.covariance ? 32 : 0));
    b.u16(static_cast<std::uint16_t>(r)).u8(flags);
    b.f64(rep.change).f64(rep.bound).f64(rep.value[0]).f64(rep.value[1]);
  }
  b.u32(static_cast<std::uint32_t>(got.estimates.size()));
  for (const Message& m : got.estimates) b.sized(EncodeMessage(m));
  b.u16(static_cast<std::uint16_t>(got.shares.size()));
  for (const auto& [r, m] : got.shares) b.sized(EncodeCoarseMessage(m));
  b.u16(static_cast<std::uint16_t>(got.weights.size()));
  for (const auto& [r, m] : got.weights) b.sized(EncodeWeightMessage(m));
  b.u16(static_cast<std::uint16_t>(got.covariances.size()));
  for (const auto& [r, m] : got.covariances) b.sized(EncodeCovarianceMessage(m));
  out.insert(out.end(), b.data().begin(), b.data().end());
}

StepRecord ReadStepRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                          const std::string& what) {
  ByteReader p = JournalRecordReader(bytes, offset, what);
  StepRecord record;
  record.step = p.u32("step");
  const std::uint8_t stage = p.u8("stage");
  if (stage < 1 || stage > 3) {
    throw InvalidInputError(what + ": step record with unknown stage " + std::to_string(stage));
  }
  record.stage = static_cast<DgsStage>(stage);
  TeamStep& got = record.result;
  const std::uint16_t reports = p.u16("report count");
  int previous = -1;
  for (std::uint16_t k = 0; k < reports; ++k) {
    const int r = p.u16("robot");
    const std::uint8_t flags = p.u8("flags");
    if (r <= previous) throw InvalidInputError(what + ": step record reports out of order");
    if (flags > 63) throw InvalidInputError(what + ": step record with unknown report flags");
    previous = r;
    TeamReport rep;
    rep.sent = (flags & 1) != 0;
    rep.initialised = (flags & 2) != 0;
    rep.coarse_ready = (flags & 4) != 0;
    rep.has_share = (flags & 8) != 0;
    rep.weights = (flags & 16) != 0;
    rep.covariance = (flags & 32) != 0;
    rep.change = p.f64("change");
    rep.bound = p.f64("bound");
    rep.value[0] = p.f64("value");
    rep.value[1] = p.f64("value");
    if (std::isnan(rep.change) || rep.change < 0.0 || std::isnan(rep.bound) || rep.bound < 0.0 ||
        !std::isfinite(rep.value[0]) || !std::isfinite(rep.value[1])) {
      throw InvalidInputError(what + ": step record with an invalid report of robot " +
                              std::to_string(r));
    }
    got.reports[r] = rep;
  }
  const std::uint32_t messages = p.u32("message count");
  for (std::uint32_t k = 0; k < messages; ++k) {
    got.estimates.push_back(DecodeMessage(p.sized("estimates")));
  }
  // A list of per-robot messages, each from a robot whose report announced it, once.
  const auto read_announced = [&](auto& into, const auto& decode, bool TeamReport::*announced,
                                  const char* kind) {
    const std::uint16_t n = p.u16(kind);
    for (std::uint16_t k = 0; k < n; ++k) {
      auto m = decode(p.sized(kind));
      const auto it = got.reports.find(m.sender);
      if (it == got.reports.end() || !(it->second.*announced) || into.count(m.sender)) {
        throw InvalidInputError(what + ": step record with " + kind + " of robot " +
                                std::to_string(m.sender));
      }
      into[m.sender] = std::move(m);
    }
  };
  read_announced(got.shares, DecodeCoarseMessage, &TeamReport::has_share,
                 "an unannounced coarse share");
  read_announced(got.weights, DecodeWeightMessage, &TeamReport::weights, "unannounced weights");
  read_announced(got.covariances, DecodeCovarianceMessage, &TeamReport::covariance,
                 "an unannounced covariance");
  if (!p.atEnd()) p.fail("trailing bytes after a step record");
  return record;
}

}  // namespace moslam::transport_detail
