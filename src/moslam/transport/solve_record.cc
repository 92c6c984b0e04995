#include "moslam/transport/solve_record.h"

#include <Eigen/LU>
#include <cmath>

#include "moslam/common/errors.h"
#include "moslam/transport/record_bytes.h"

namespace moslam::transport_detail {
namespace {

constexpr std::uint8_t kMineIsAlpha = 1, kHeld = 2;  // team pair flags
constexpr std::uint8_t kUnlinked = 1;                 // solve record flags
// Smallest encodings, to bound a count by what is left before reserving anything.
constexpr std::size_t kKeyBytes = 2 + 1 + 8, kPoseBytes = 12 * 8;

void WriteKey(WireWriter& b, const Key& k) {
  b.u16(static_cast<std::uint16_t>(k.robot)).u8(static_cast<std::uint8_t>(k.kind)).u64(k.index);
}

void WritePose(WireWriter& b, const SE3& x) {
  const Matrix3& R = x.rotation().matrix();
  for (int i = 0; i < 9; ++i) b.f64(R(i));
  for (int i = 0; i < 3; ++i) b.f64(x.translation()(i));
}

Key ReadKey(ByteReader& p, const std::string& what) {
  Key k;
  k.robot = p.u16("key robot");
  const std::uint8_t kind = p.u8("key kind");
  if (kind > 1) throw InvalidInputError(what + ": unknown variable kind " + std::to_string(kind));
  k.kind = static_cast<VariableKind>(kind);
  k.index = p.u64("key index");
  if (k.index > kMaxKeyIndex) throw InvalidInputError(what + ": key index beyond 2^56 - 1");
  return k;
}

SE3 ReadPose(ByteReader& p, const std::string& what) {
  Matrix3 R;
  Vector3 t;
  for (int i = 0; i < 9; ++i) R(i) = p.f64("rotation");
  for (int i = 0; i < 3; ++i) t(i) = p.f64("translation");
  if (!R.allFinite() || !t.allFinite()) throw InvalidInputError(what + ": a pose is not finite");
  if (!((R.transpose() * R - Matrix3::Identity()).cwiseAbs().maxCoeff() <= 1e-6) ||
      !(R.determinant() > 0.0)) {
    throw InvalidInputError(what + ": a pose's rotation is not a rotation matrix");
  }
  return SE3(SO3(R), t);
}

}  // namespace

void AppendGroupRecord(const GroupRecord& record, std::vector<std::uint8_t>& out) {
  WireWriter b;
  b.u32(record.step).u16(static_cast<std::uint16_t>(record.robots.size()));
  for (int r : record.robots) b.u16(static_cast<std::uint16_t>(r));
  b.u32(static_cast<std::uint32_t>(record.team.size()));
  for (const TeamPair& t : record.team) {
    WriteKey(b, t.mine);
    WriteKey(b, t.other);
    b.u8(static_cast<std::uint8_t>((t.mine_is_alpha ? kMineIsAlpha : 0) | (t.held ? kHeld : 0)));
    if (t.held) {
      b.u32(static_cast<std::uint32_t>(t.copy.step));
      WritePose(b, t.copy.pose);
    }
  }
  out.insert(out.end(), b.data().begin(), b.data().end());
}

GroupRecord ReadGroupRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what) {
  ByteReader p = JournalRecordReader(bytes, offset, what);
  GroupRecord record;
  record.step = p.u32("step");
  const std::uint16_t n = p.u16("robot count");
  for (std::uint16_t i = 0; i < n; ++i) {
    const int r = p.u16("robot");
    if (!record.robots.empty() && r <= record.robots.back()) {
      throw InvalidInputError(what + ": the robots of a group record are not increasing");
    }
    record.robots.push_back(r);
  }
  const std::uint32_t m = p.count(2 * kKeyBytes + 1, "team pair");
  for (std::uint32_t i = 0; i < m; ++i) {
    TeamPair t;
    t.mine = ReadKey(p, what);
    t.other = ReadKey(p, what);
    const std::uint8_t flags = p.u8("flags");
    if (flags & ~(kMineIsAlpha | kHeld)) {
      throw InvalidInputError(what + ": unknown team pair flags " + std::to_string(flags));
    }
    if (!t.mine.isObject() || !t.other.isObject()) {
      throw InvalidInputError(what + ": a team pair names a pose, not two landmarks");
    }
    t.mine_is_alpha = flags & kMineIsAlpha;
    t.held = flags & kHeld;
    if (t.held) {
      t.copy.step = static_cast<int>(p.u32("held step"));
      if (t.copy.step < 0) throw InvalidInputError(what + ": a held copy's step exceeds 2^31");
      t.copy.pose = ReadPose(p, what);
    }
    record.team.push_back(t);
  }
  if (!p.atEnd()) p.fail("trailing bytes after a group record");
  return record;
}

void AppendSolveRecord(const SolveRecord& record, std::vector<std::uint8_t>& out) {
  WireWriter b;
  b.u32(record.step).u32(static_cast<std::uint32_t>(record.estimate.size()));
  for (const auto& [k, x] : record.estimate) {
    WriteKey(b, k);
    WritePose(b, x);
  }
  b.u32(static_cast<std::uint32_t>(record.held.size()));
  for (const auto& [k, h] : record.held) {
    WriteKey(b, k);
    b.u32(static_cast<std::uint32_t>(h.step));
    WritePose(b, h.pose);
  }
  b.u32(record.rotation_rounds).u32(record.pose_rounds).u32(record.refine_steps);
  b.u32(record.protocol_steps).u32(record.object_object).u32(record.team_factors);
  b.u8(static_cast<std::uint8_t>(record.refine_status));
  b.u8(record.unlinked ? kUnlinked : 0).u32(static_cast<std::uint32_t>(record.set_aside.size()));
  for (const auto& [alpha, beta] : record.set_aside) {
    WriteKey(b, alpha);
    WriteKey(b, beta);
  }
  b.u32(static_cast<std::uint32_t>(record.rejected.size()));
  for (std::uint32_t i : record.rejected) b.u32(i);
  out.insert(out.end(), b.data().begin(), b.data().end());
}

SolveRecord ReadSolveRecord(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                            const std::string& what) {
  ByteReader p = JournalRecordReader(bytes, offset, what);
  SolveRecord record;
  record.step = p.u32("step");
  const std::uint32_t n = p.count(kKeyBytes + kPoseBytes, "estimate");
  for (std::uint32_t i = 0; i < n; ++i) {
    const Key k = ReadKey(p, what);
    const SE3 x = ReadPose(p, what);
    if (!record.estimate.empty() && !(std::prev(record.estimate.end())->first < k)) {
      throw InvalidInputError(what + ": the keys of a solve record are not increasing");
    }
    record.estimate.emplace_hint(record.estimate.end(), k, x);
  }
  const std::uint32_t m = p.count(kKeyBytes + 4 + kPoseBytes, "held copy");
  for (std::uint32_t i = 0; i < m; ++i) {
    const Key k = ReadKey(p, what);
    HeldEstimate h;
    h.step = static_cast<int>(p.u32("held step"));
    if (h.step < 0) throw InvalidInputError(what + ": a held copy's step exceeds 2^31");
    h.pose = ReadPose(p, what);
    if (!k.isObject()) throw InvalidInputError(what + ": a held copy is not a landmark");
    if (!record.held.empty() && !(std::prev(record.held.end())->first < k)) {
      throw InvalidInputError(what + ": the held keys of a solve record are not increasing");
    }
    record.held.emplace_hint(record.held.end(), k, h);
  }
  record.rotation_rounds = p.u32("rotation rounds");
  record.pose_rounds = p.u32("pose rounds");
  record.refine_steps = p.u32("refine steps");
  record.protocol_steps = p.u32("protocol steps");
  record.object_object = p.u32("object object");
  record.team_factors = p.u32("team factors");
  const std::uint8_t status = p.u8("status");
  if (status > static_cast<std::uint8_t>(StageStatus::kNoDecreasingStep)) {
    throw InvalidInputError(what + ": unknown refine status " + std::to_string(status));
  }
  record.refine_status = static_cast<StageStatus>(status);
  const std::uint8_t flags = p.u8("flags");
  if (flags & ~kUnlinked) {
    throw InvalidInputError(what + ": unknown solve record flags " + std::to_string(flags));
  }
  record.unlinked = flags & kUnlinked;
  const std::uint32_t k = p.count(2 * kKeyBytes, "pair set aside");
  for (std::uint32_t i = 0; i < k; ++i) {
    const Key alpha = ReadKey(p, what);
    const Key beta = ReadKey(p, what);
    if (!alpha.isObject() || !beta.isObject() || alpha.robot == beta.robot) {
      throw InvalidInputError(what + ": a pair set aside is not two landmarks of two robots");
    }
    record.set_aside.emplace_back(alpha, beta);
  }
  const std::uint32_t f = p.count(4, "rejected factor");
  for (std::uint32_t i = 0; i < f; ++i) {
    const std::uint32_t index = p.u32("rejected factor");
    if (!record.rejected.empty() && index <= record.rejected.back()) {
      throw InvalidInputError(what + ": the rejected factors of a solve record are not "
                                     "increasing");
    }
    record.rejected.push_back(index);
  }
  if (!p.atEnd()) p.fail("trailing bytes after a solve record");
  return record;
}

}  // namespace moslam::transport_detail
