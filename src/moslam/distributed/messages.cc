#include "moslam/distributed/messages.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <tuple>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/geometry/so3.h"

namespace moslam {

const double* Message::entry(std::size_t i) const {
  return values.data() + i * static_cast<std::size_t>(StageDimension(stage));
}

namespace {

void RequirePoseStage(DgsStage stage) {
  if (StageDimension(stage) != 6) {
    throw InvalidInputError("DGS message: a pose entry needs a stage of dimension 6, not " +
                            std::to_string(StageDimension(stage)));
  }
}

}  // namespace

void Message::appendPose(const Key& key, const SE3& pose) {
  RequirePoseStage(stage);
  keys.push_back(key);
  const Vector3 w = SO3::Log(pose.rotation());
  values.insert(values.end(), w.data(), w.data() + 3);
  values.insert(values.end(), pose.translation().data(), pose.translation().data() + 3);
}

SE3 Message::pose(std::size_t i) const {
  RequirePoseStage(stage);
  const double* v = entry(i);
  return SE3(SO3::Exp(Vector3(v[0], v[1], v[2])), Vector3(v[3], v[4], v[5]));
}

namespace {

// 7 bits a byte: 63 bits, enough for index << 1 | kind.
constexpr std::size_t kMaxKeyVarintBytes = 9;

bool ValidStage(std::uint8_t s) { return s >= 1 && s <= 3; }

// The first two bytes of every message: its magic byte and the protocol version. Throws
// "<message>: bad magic byte (not <noun>)" or "<message>: unsupported version V".
void ReadMagicAndVersion(ByteReader& r, std::uint8_t magic, const std::string& noun) {
  if (r.u8("magic") != magic) r.fail("bad magic byte (not " + noun + ")");
  const std::uint8_t version = r.u8("version");
  if (version != kMessageVersion) r.fail("unsupported version " + std::to_string(version));
}

std::uint64_t PackKey(const Key& key) {
  return (key.index << 1) | static_cast<std::uint64_t>(key.kind);
}

}  // namespace

std::vector<std::uint8_t> EncodeMessage(const Message& m) {
  const int dim = StageDimension(m.stage);
  if (m.sender < 0 || m.sender > kMaxMessageRobot) {
    throw InvalidInputError("DGS message: sender robot " + std::to_string(m.sender) +
                            " outside [0, 65535]");
  }
  if (m.values.size() != m.keys.size() * static_cast<std::size_t>(dim)) {
    throw InvalidInputError("DGS message: " + std::to_string(m.values.size()) + " values for " +
                            std::to_string(m.keys.size()) + " keys of dimension " +
                            std::to_string(dim));
  }
  if (m.keys.size() > 0xFFFFFFFFu) throw InvalidInputError("DGS message: too many entries");
  for (std::size_t i = 0; i < m.keys.size(); ++i) {
    const Key& k = m.keys[i];
    if (k.robot != m.sender) {
      throw InvalidInputError("DGS message: key " + ToString(k) + " is not robot " +
                              std::to_string(m.sender) + "'s (a robot sends only its own)");
    }
    if (k.index > kMaxKeyIndex) throw InvalidInputError("DGS message: key index >= 2^56");
    if (i > 0 && !(m.keys[i - 1] < k)) {
      throw InvalidInputError("DGS message: keys not strictly increasing at " + ToString(k));
    }
  }
  for (double v : m.values) {
    if (!std::isfinite(v)) throw InvalidInputError("DGS message: non-finite estimate");
  }
  std::size_t size = kMessageHeaderBytes + m.values.size() * 8;
  for (const Key& k : m.keys) size += VarintSize(PackKey(k));
  WireWriter w(size);
  w.u8(kMessageMagic);
  w.u8(kMessageVersion);
  w.u8(static_cast<std::uint8_t>(m.stage));
  w.u8(m.initialised ? 1 : 0);
  w.u16(static_cast<std::uint16_t>(m.sender));
  w.u16(0);
  w.u32(m.iteration);
  w.u32(static_cast<std::uint32_t>(m.keys.size()));
  for (std::size_t i = 0; i < m.keys.size(); ++i) {
    w.varint(PackKey(m.keys[i]));
    const double* e = m.entry(i);
    for (int d = 0; d < dim; ++d) w.f64(e[d]);
  }
  return w.take();
}

Message DecodeMessage(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "DGS message");
  r.need(kMessageHeaderBytes, "header");
  Message m;
  ReadMagicAndVersion(r, kMessageMagic, "a DGS message");
  const std::uint8_t stage = r.u8("stage");
  if (!ValidStage(stage)) {
    r.fail("unknown stage " + std::to_string(stage));
  }
  m.stage = static_cast<DgsStage>(stage);
  const std::uint8_t flags = r.u8("flags");
  if ((flags & ~1u) != 0) {
    r.fail("unknown flag bits " + std::to_string(flags));
  }
  m.initialised = (flags & 1u) != 0;
  m.sender = r.u16("sender");
  if (r.u16("reserved") != 0) r.fail("reserved field not zero");
  m.iteration = r.u32("iteration");
  const std::uint32_t count = r.u32("entry count");
  const std::size_t dim = static_cast<std::size_t>(StageDimension(m.stage));
  const std::size_t min_entry = 1 + 8 * dim;
  if (count > r.left() / min_entry) {
    r.fail("entry count " + std::to_string(count) + " exceeds what the " +
           std::to_string(r.left()) + " payload bytes can hold");
  }
  m.keys.reserve(count);
  m.values.reserve(count * dim);
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::uint64_t packed = r.varint("key", kMaxKeyVarintBytes);
    if ((packed >> 1) > kMaxKeyIndex) {
      r.fail("key index >= 2^56 at entry " + std::to_string(i));
    }
    Key key{m.sender, static_cast<VariableKind>(packed & 1u), packed >> 1};
    if (!m.keys.empty() && !(m.keys.back() < key)) {
      r.fail("keys not strictly increasing at entry " + std::to_string(i));
    }
    m.keys.push_back(key);
    for (std::size_t d = 0; d < dim; ++d) {
      const double v = r.f64("estimate");
      if (!std::isfinite(v)) {
        r.fail("non-finite estimate at entry " + std::to_string(i));
      }
      m.values.push_back(v);
    }
  }
  if (r.left() != 0) {
    r.fail(std::to_string(r.left()) + " trailing bytes after the last entry");
  }
  return m;
}

namespace {

std::uint8_t AllowedControlFlags(ControlKind kind) {
  switch (kind) {
    case ControlKind::kBroadcast:
      return kStopLinearSolve;
    case ControlKind::kStepDecision:
      return kAcceptStep | kRefineFinished | kHalveStep;
    default:
      return 0;
  }
}

bool ValidControlKind(std::uint8_t k) { return k >= 1 && k <= 4; }

void CheckControl(const ControlMessage& m) {
  if (!ValidControlKind(static_cast<std::uint8_t>(m.kind))) {
    throw InvalidInputError("DGS control message: unknown kind " +
                            std::to_string(static_cast<int>(m.kind)));
  }
  if (m.sender < 0 || m.sender > kMaxMessageRobot) {
    throw InvalidInputError("DGS control message: sender robot " + std::to_string(m.sender) +
                            " outside [0, 65535]");
  }
  if ((m.flags & ~AllowedControlFlags(m.kind)) != 0) {
    throw InvalidInputError("DGS control message: flag bits " + std::to_string(m.flags) +
                            " not defined for kind " + std::to_string(static_cast<int>(m.kind)));
  }
  if (m.kind == ControlKind::kStepDecision && (m.flags & kHalveStep) != 0 &&
      m.flags != kHalveStep) {
    throw InvalidInputError(
        "DGS control message: a step decision that halves the step (flag 4) "
        "can neither accept it nor finish, got flags " +
        std::to_string(m.flags));
  }
  for (double v : m.value) {
    if (!std::isfinite(v)) throw InvalidInputError("DGS control message: non-finite value");
  }
}

}  // namespace

std::vector<std::uint8_t> EncodeControlMessage(const ControlMessage& m) {
  CheckControl(m);
  WireWriter w(kControlMessageBytes);
  w.u8(kControlMagic);
  w.u8(kMessageVersion);
  w.u8(static_cast<std::uint8_t>(m.kind));
  w.u8(m.flags);
  w.u16(static_cast<std::uint16_t>(m.sender));
  w.u16(0);
  w.u32(m.round);
  w.u32(m.sweep);
  w.f64(m.value[0]);
  w.f64(m.value[1]);
  return w.take();
}

ControlMessage DecodeControlMessage(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "DGS control message");
  if (bytes.size() != kControlMessageBytes) {
    r.fail(std::to_string(bytes.size()) + " bytes, expected " +
           std::to_string(kControlMessageBytes));
  }
  ReadMagicAndVersion(r, kControlMagic, "a control message");
  ControlMessage m;
  const std::uint8_t kind = r.u8("kind");
  if (!ValidControlKind(kind)) {
    r.fail("unknown kind " + std::to_string(kind));
  }
  m.kind = static_cast<ControlKind>(kind);
  m.flags = r.u8("flags");
  m.sender = r.u16("sender");
  if (r.u16("reserved") != 0) {
    r.fail("reserved field not zero");
  }
  m.round = r.u32("round");
  m.sweep = r.u32("sweep");
  m.value[0] = r.f64("value");
  m.value[1] = r.f64("value");
  CheckControl(m);
  return m;
}

namespace {

// Which sections a coarse message of each kind carries (messages.h).
struct CoarseLayout {
  bool center, diagonal, residual;
  bool matrix_blocks;  // blocks of k*k (else k*ncols)
};

CoarseLayout LayoutOf(CoarseKind kind) {
  switch (kind) {
    case CoarseKind::kShare:
      return {true, true, true, true};
    case CoarseKind::kSolution:
      return {false, false, false, false};
    case CoarseKind::kMatrix:
      return {true, true, false, true};
    case CoarseKind::kResidual:
      return {false, false, true, false};
    case CoarseKind::kPieceMatrix:
      return {true, false, false, false};
    case CoarseKind::kPieceResidual:
    case CoarseKind::kPieceSolution:
      return {false, false, false, false};
  }
  throw InvalidInputError("DGS coarse message: unknown kind");
}

bool KnownKind(std::uint8_t kind) { return kind >= 1 && kind <= 7; }

bool PieceKind(CoarseKind kind) {
  return kind == CoarseKind::kPieceMatrix || kind == CoarseKind::kPieceResidual ||
         kind == CoarseKind::kPieceSolution;
}

// Sizes of a piece message's values: a piece's (centre 3, or 6 of a residual) and a block's.
std::size_t PieceValues(CoarseKind kind) { return kind == CoarseKind::kPieceMatrix ? 3 : 6; }
std::size_t PieceBlockValues(CoarseKind kind) { return kind == CoarseKind::kPieceMatrix ? 36 : 6; }

// The stages a kind belongs to: the two-level DGS (rotation, pose) shares and solves; the
// preconditioner of conjugate gradients (pose stage, refinement) sends its matrix and residuals
// apart (and solves).
bool StageAllowed(CoarseKind kind, DgsStage stage) {
  const bool two_stage = stage == DgsStage::kRotation || stage == DgsStage::kPose;
  switch (kind) {
    case CoarseKind::kShare:
      return two_stage;
    case CoarseKind::kSolution:
      return two_stage || stage == DgsStage::kRefine;
    case CoarseKind::kMatrix:
    case CoarseKind::kResidual:  // the preconditioner of conjugate gradients
      return stage == DgsStage::kPose || stage == DgsStage::kRefine;
    case CoarseKind::kPieceMatrix:
    case CoarseKind::kPieceResidual:
    case CoarseKind::kPieceSolution:
      return stage == DgsStage::kRefine;
  }
  return false;
}

// The piece kinds' own rules (messages.h), after CheckCoarse's common ones.
void CheckPieces(const CoarseMessage& m, const std::function<void(const std::string&)>& fail) {
  const bool piece = PieceKind(m.kind);
  if (!piece) {
    if (!m.pieces.empty() || !m.piece_blocks.empty()) fail("pieces in a message of robots");
    return;
  }
  if (m.k != 6 || m.ncols != 1) fail("a piece message has k = 6 and ncols = 1");
  if (!m.diagonal.empty() || !m.residual.empty() || !m.blocks.empty()) {
    fail("a piece message carries no robot blocks");
  }
  if (m.kind == CoarseKind::kPieceMatrix && m.center.size() != 3) {
    fail("a piece matrix needs its reference point (a centre of size 3)");
  }
  if (m.kind == CoarseKind::kPieceSolution && !m.pieces.empty()) fail("pieces in a solution");
  if (m.kind == CoarseKind::kPieceResidual && !m.piece_blocks.empty()) fail("blocks in a residual");
  if (m.pieces.size() > kMaxCoarsePieces) fail("too many pieces");
  if (m.piece_blocks.size() > kMaxCoarsePieceBlocks) fail("too many piece blocks");
  auto finite = [&](const std::vector<double>& v) {
    for (double d : v) {
      if (!std::isfinite(d)) fail("non-finite value");
    }
  };
  for (std::size_t i = 0; i < m.pieces.size(); ++i) {
    if (i > 0 && m.pieces[i].id <= m.pieces[i - 1].id) fail("pieces not increasing");
    if (m.pieces[i].values.size() != PieceValues(m.kind)) fail("piece of the wrong size");
    finite(m.pieces[i].values);
  }
  auto has_piece = [&](std::uint32_t id) {
    return std::binary_search(
        m.pieces.begin(), m.pieces.end(), CoarsePiece{id, {}},
        [](const CoarsePiece& a, const CoarsePiece& b) { return a.id < b.id; });
  };
  for (std::size_t i = 0; i < m.piece_blocks.size(); ++i) {
    const CoarsePieceBlock& b = m.piece_blocks[i];
    if (b.robot < 0 || b.robot > kMaxMessageRobot) fail("block robot outside [0, 65535]");
    if (i > 0) {
      const CoarsePieceBlock& a = m.piece_blocks[i - 1];
      if (std::make_tuple(b.row_piece, b.robot, b.piece) <=
          std::make_tuple(a.row_piece, a.robot, a.piece)) {
        fail("piece blocks not increasing");
      }
    }
    if (m.kind == CoarseKind::kPieceMatrix ? !has_piece(b.row_piece) : b.row_piece != 0) {
      fail("a block's row piece is not among the message's pieces");
    }
    if (b.values.size() != PieceBlockValues(m.kind)) fail("piece block of the wrong size");
    finite(b.values);
  }
}

void CheckCoarse(const CoarseMessage& m) {
  auto fail = [](const std::string& why) {
    throw InvalidInputError("DGS coarse message: " + why);
  };
  if (!KnownKind(static_cast<std::uint8_t>(m.kind))) fail("unknown kind");
  if (!StageAllowed(m.kind, m.stage)) fail("stage not allowed for the kind");
  if (m.sender < 0 || m.sender > kMaxMessageRobot) fail("sender outside [0, 65535]");
  if (m.k < 1 || m.k > kMaxCoarseK || m.ncols < 1 || m.ncols > 16) {
    fail("k must be in [1, " + std::to_string(kMaxCoarseK) + "] and ncols in [1, 16]");
  }
  const CoarseLayout layout = LayoutOf(m.kind);
  const std::size_t kk = static_cast<std::size_t>(m.k * m.k);
  const std::size_t kc = static_cast<std::size_t>(m.k * m.ncols);
  if (m.diagonal.size() != (layout.diagonal ? kk : 0)) fail("diagonal of the wrong size");
  if (m.residual.size() != (layout.residual ? kc : 0)) fail("residual of the wrong size");
  if (m.center.size() != 0 && (m.center.size() != 3 || !layout.center)) {
    fail("centre of size other than 0 or 3 (or in a message without one)");
  }
  if (m.kind == CoarseKind::kResidual && !m.blocks.empty()) fail("a residual carries no blocks");
  CheckPieces(m, fail);
  if (m.blocks.size() > kMaxMessageRobot) fail("too many blocks");
  int previous = -1;
  auto finite = [&](const std::vector<double>& v) {
    for (double d : v) {
      if (!std::isfinite(d)) fail("non-finite value");
    }
  };
  finite(m.center);
  finite(m.diagonal);
  finite(m.residual);
  for (const auto& [robot, values] : m.blocks) {
    if (robot <= previous || robot > kMaxMessageRobot) fail("block robots not increasing");
    previous = robot;
    if (values.size() != (layout.matrix_blocks ? kk : kc)) fail("block of the wrong size");
    finite(values);
  }
}

}  // namespace

std::vector<std::uint8_t> EncodeCoarseMessage(const CoarseMessage& m) {
  CheckCoarse(m);
  const std::size_t block =
      LayoutOf(m.kind).matrix_blocks ? m.k * m.k : m.k * m.ncols;
  WireWriter w(kMessageHeaderBytes + 8 * (m.center.size() + m.diagonal.size() + m.residual.size()) +
               m.blocks.size() * (2 + 8 * block));
  w.u8(kCoarseMagic);
  w.u8(kMessageVersion);
  w.u8(static_cast<std::uint8_t>(m.stage));
  w.u8(static_cast<std::uint8_t>(m.kind));
  w.u16(static_cast<std::uint16_t>(m.sender));
  w.u16(static_cast<std::uint16_t>(m.blocks.size()));
  w.u32(m.iteration);
  w.u8(static_cast<std::uint8_t>(m.k));
  w.u8(static_cast<std::uint8_t>(m.ncols));
  w.u8(static_cast<std::uint8_t>(m.center.size()));
  w.u8(0);
  for (double d : m.center) w.f64(d);
  for (double d : m.diagonal) w.f64(d);
  for (double d : m.residual) w.f64(d);
  for (const auto& [robot, values] : m.blocks) {
    w.u16(static_cast<std::uint16_t>(robot));
    for (double d : values) w.f64(d);
  }
  if (m.kind != CoarseKind::kPieceSolution && PieceKind(m.kind)) {
    w.u32(static_cast<std::uint32_t>(m.pieces.size()));
    for (const CoarsePiece& p : m.pieces) {
      w.u32(p.id);
      for (double d : p.values) w.f64(d);
    }
  }
  if (m.kind != CoarseKind::kPieceResidual && PieceKind(m.kind)) {
    w.u32(static_cast<std::uint32_t>(m.piece_blocks.size()));
    for (const CoarsePieceBlock& b : m.piece_blocks) {
      if (m.kind == CoarseKind::kPieceMatrix) w.u32(b.row_piece);
      w.u16(static_cast<std::uint16_t>(b.robot));
      w.u32(b.piece);
      for (double d : b.values) w.f64(d);
    }
  }
  return w.take();
}

CoarseMessage DecodeCoarseMessage(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "DGS coarse message");
  ReadMagicAndVersion(r, kCoarseMagic, "a coarse message");
  CoarseMessage m;
  const std::uint8_t stage = r.u8("stage");
  if (stage < static_cast<std::uint8_t>(DgsStage::kRotation) ||
      stage > static_cast<std::uint8_t>(DgsStage::kRefine)) {
    r.fail("unknown stage " + std::to_string(stage));
  }
  m.stage = static_cast<DgsStage>(stage);
  const std::uint8_t kind = r.u8("kind");
  if (!KnownKind(kind)) {
    r.fail("unknown kind " + std::to_string(kind));
  }
  m.kind = static_cast<CoarseKind>(kind);
  if (!StageAllowed(m.kind, m.stage)) {
    r.fail("kind " + std::to_string(kind) + " does not belong to stage " + std::to_string(stage));
  }
  m.sender = r.u16("sender");
  const std::size_t count = r.u16("block count");
  m.iteration = r.u32("iteration");
  m.k = r.u8("k");
  m.ncols = r.u8("ncols");
  if (m.k < 1 || m.k > kMaxCoarseK || m.ncols < 1 || m.ncols > 16) {
    r.fail("k must be in [1, " + std::to_string(kMaxCoarseK) + "] and ncols in [1, 16]");
  }
  const std::size_t centre = r.u8("center size");
  if (r.u8("reserved") != 0) {
    r.fail("reserved field not zero");
  }
  const CoarseLayout layout = LayoutOf(m.kind);
  if (centre != 0 && (centre != 3 || !layout.center)) {
    r.fail("center size " + std::to_string(centre) + " (0, or 3 in a share or a matrix)");
  }
  if (m.kind == CoarseKind::kResidual && count != 0) {
    r.fail("a residual carries no blocks");
  }
  auto doubles = [&](std::size_t n) {
    std::vector<double> v(n);
    for (double& d : v) d = r.f64("value");
    return v;
  };
  if (PieceKind(m.kind)) {
    if (m.k != 6 || m.ncols != 1 || count != 0) {
      r.fail("a piece message has k = 6, ncols = 1 and no robot blocks");
    }
    if ((m.kind == CoarseKind::kPieceMatrix) != (centre == 3)) {
      r.fail("center size " + std::to_string(centre) + " (3 in a piece matrix, else 0)");
    }
    m.center = doubles(centre);
    if (m.kind != CoarseKind::kPieceSolution) {
      const std::uint32_t pieces = r.u32("piece count");
      if (pieces > kMaxCoarsePieces) {
        r.fail("more than " + std::to_string(kMaxCoarsePieces) + " pieces");
      }
      const std::size_t each = PieceValues(m.kind);
      r.need(pieces * (4 + 8 * each), "pieces");
      m.pieces.resize(pieces);
      for (CoarsePiece& p : m.pieces) {
        p.id = r.u32("piece id");
        p.values = doubles(each);
      }
    }
    if (m.kind != CoarseKind::kPieceResidual) {
      const std::uint32_t blocks = r.u32("piece block count");
      if (blocks > kMaxCoarsePieceBlocks) {
        r.fail("more than " + std::to_string(kMaxCoarsePieceBlocks) + " piece blocks");
      }
      const bool matrix = m.kind == CoarseKind::kPieceMatrix;
      const std::size_t each = PieceBlockValues(m.kind);
      r.need(blocks * ((matrix ? 10 : 6) + 8 * each), "piece blocks");
      m.piece_blocks.resize(blocks);
      for (CoarsePieceBlock& b : m.piece_blocks) {
        if (matrix) b.row_piece = r.u32("row piece");
        b.robot = r.u16("block robot");
        b.piece = r.u32("block piece");
        b.values = doubles(each);
      }
    }
    if (r.left() != 0) r.fail(std::to_string(r.left()) + " trailing bytes");
    CheckCoarse(m);
    return m;
  }
  const std::size_t kk = static_cast<std::size_t>(m.k * m.k);
  const std::size_t kc = static_cast<std::size_t>(m.k * m.ncols);
  const std::size_t block = layout.matrix_blocks ? kk : kc;
  const std::size_t payload = 8 * centre + (layout.diagonal ? 8 * kk : 0) +
                              (layout.residual ? 8 * kc : 0) + count * (2 + 8 * block);
  r.need(payload, "payload");
  if (r.left() != payload) {
    r.fail(std::to_string(r.left() - payload) + " trailing bytes");
  }
  m.center = doubles(centre);
  if (layout.diagonal) m.diagonal = doubles(kk);
  if (layout.residual) m.residual = doubles(kc);
  for (std::size_t b = 0; b < count; ++b) {
    const int robot = r.u16("block robot");
    m.blocks.emplace_back(robot, doubles(block));
  }
  CheckCoarse(m);
  return m;
}

namespace {

// Messages from one robot to another: both ids in range, and two robots.
void CheckRobotPair(int sender, int receiver, const std::string& what) {
  if (sender < 0 || sender > kMaxMessageRobot || receiver < 0 || receiver > kMaxMessageRobot) {
    throw InvalidInputError(what + ": robot ids must be in [0, 65535]");
  }
  if (sender == receiver) {
    throw InvalidInputError(what + ": sender and receiver are the same robot " +
                            std::to_string(sender));
  }
}

void CheckWeights(const WeightMessage& m) {
  auto bad = [](const std::string& what) {
    throw InvalidInputError("DGS weight message: " + what);
  };
  CheckRobotPair(m.sender, m.receiver, "DGS weight message");
  for (std::size_t i = 0; i < m.weights.size(); ++i) {
    const double w = m.weights[i];
    if (!(w >= 0.0 && w <= 1.0)) {
      bad("weight " + std::to_string(i) + " is not a number in [0, 1]");
    }
  }
  if (m.weights.size() > 0xFFFFFFFFu) bad("too many weights");
}

}  // namespace

std::vector<std::uint8_t> EncodeWeightMessage(const WeightMessage& m) {
  CheckWeights(m);
  WireWriter w(kWeightHeaderBytes + 8 * m.weights.size());
  w.u8(kWeightMagic);
  w.u8(kMessageVersion);
  w.u16(static_cast<std::uint16_t>(m.sender));
  w.u16(static_cast<std::uint16_t>(m.receiver));
  w.u16(0);
  w.u32(m.round);
  w.u32(static_cast<std::uint32_t>(m.weights.size()));
  for (double v : m.weights) w.f64(v);
  return w.take();
}

WeightMessage DecodeWeightMessage(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "DGS weight message");
  ReadMagicAndVersion(r, kWeightMagic, "a weight message");
  WeightMessage m;
  m.sender = r.u16("sender");
  m.receiver = r.u16("receiver");
  if (r.u16("reserved") != 0) r.fail("reserved field not 0");
  m.round = r.u32("round");
  const std::uint32_t count = r.u32("count");
  if (r.left() / 8 < count || r.left() != 8 * static_cast<std::size_t>(count)) {
    r.fail(std::to_string(count) + " weights need " +
           std::to_string(8 * static_cast<std::size_t>(count)) + " bytes, " +
           std::to_string(r.left()) + " follow");
  }
  m.weights.resize(count);
  for (double& w : m.weights) w = r.f64("weight");
  CheckWeights(m);
  return m;
}

namespace {

void CheckCovariance(const CovarianceMessage& m) {
  auto bad = [](const std::string& what) {
    throw InvalidInputError("DGS covariance message: " + what);
  };
  CheckRobotPair(m.sender, m.receiver, "DGS covariance message");
  const Eigen::Index n = m.covariance.rows();
  if (m.covariance.cols() != n) bad("the covariance is not square");
  if (n % 6 != 0 || n > static_cast<Eigen::Index>(kMaxCovarianceDimension)) {
    bad("dimension " + std::to_string(n) + " is not a multiple of 6 up to " +
        std::to_string(kMaxCovarianceDimension));
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!(m.covariance(i, i) >= 0.0)) {
      bad("diagonal entry " + std::to_string(i) + " is negative or not a number");
    }
    for (Eigen::Index j = i; j < n; ++j) {
      if (!std::isfinite(m.covariance(i, j))) {
        bad("entry (" + std::to_string(i) + ", " + std::to_string(j) + ") is not finite");
      }
    }
  }
}

}  // namespace

std::vector<std::uint8_t> EncodeCovarianceMessage(const CovarianceMessage& m) {
  CheckCovariance(m);
  const std::size_t n = static_cast<std::size_t>(m.covariance.rows());
  WireWriter w(kCovarianceHeaderBytes + 8 * (n * (n + 1) / 2));
  w.u8(kCovarianceMagic);
  w.u8(kMessageVersion);
  w.u16(static_cast<std::uint16_t>(m.sender));
  w.u16(static_cast<std::uint16_t>(m.receiver));
  w.u16(0);
  w.u32(static_cast<std::uint32_t>(n));
  w.u32(0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i; j < n; ++j) {
      w.f64(m.covariance(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
    }
  }
  return w.take();
}

CovarianceMessage DecodeCovarianceMessage(const std::vector<std::uint8_t>& bytes) {
  ByteReader r(bytes, "DGS covariance message");
  auto bad = [&r](const std::string& what) { r.fail(what); };
  ReadMagicAndVersion(r, kCovarianceMagic, "a covariance message");
  CovarianceMessage m;
  m.sender = r.u16("sender");
  m.receiver = r.u16("receiver");
  if (r.u16("reserved") != 0) bad("reserved field not 0");
  const std::uint32_t n = r.u32("dimension");
  if (r.u32("reserved") != 0) bad("reserved field not 0");
  if (n % 6 != 0 || n > kMaxCovarianceDimension) {
    bad("dimension " + std::to_string(n) + " is not a multiple of 6 up to " +
        std::to_string(kMaxCovarianceDimension));
  }
  const std::size_t count = static_cast<std::size_t>(n) * (n + 1) / 2;
  if (r.left() != 8 * count) {
    bad("dimension " + std::to_string(n) + " needs " + std::to_string(8 * count) + " bytes, " +
        std::to_string(r.left()) + " follow");
  }
  m.covariance.resize(n, n);
  for (std::uint32_t i = 0; i < n; ++i) {
    for (std::uint32_t j = i; j < n; ++j) {
      m.covariance(i, j) = m.covariance(j, i) = r.f64("entry");
    }
  }
  CheckCovariance(m);
  return m;
}

}  // namespace moslam
