#include "moslam/distributed/messages.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {

Message MakeMessage(DgsStage stage, int sender, int n) {
  Message m;
  m.stage = stage;
  m.iteration = 4000000007u;
  m.sender = sender;
  m.initialised = true;
  const int dim = StageDimension(stage);
  for (int i = 0; i < n; ++i) {
    m.keys.push_back(Key::Pose(sender, static_cast<std::uint64_t>(i) * 1000003u));
    for (int d = 0; d < dim; ++d) m.values.push_back(std::sin(1.0 + i * dim + d) * 1e3 / (d + 1));
  }
  m.keys.push_back(Key::Object(sender, kMaxKeyIndex));
  for (int d = 0; d < dim; ++d) m.values.push_back(d == 0 ? -0.0 : d * 1e-310);  // -0, denormals
  return m;
}

void ExpectEqual(const Message& a, const Message& b) {
  EXPECT_EQ(a.stage, b.stage);
  EXPECT_EQ(a.iteration, b.iteration);
  EXPECT_EQ(a.sender, b.sender);
  EXPECT_EQ(a.initialised, b.initialised);
  EXPECT_EQ(a.keys, b.keys);
  ASSERT_EQ(a.values.size(), b.values.size());
  for (std::size_t i = 0; i < a.values.size(); ++i) {
    // Bit-exact, including the sign of zero and denormals.
    EXPECT_EQ(std::memcmp(&a.values[i], &b.values[i], sizeof(double)), 0) << i;
  }
}

TEST(Messages, RoundTripEveryStage) {
  for (DgsStage stage : {DgsStage::kRotation, DgsStage::kPose, DgsStage::kRefine}) {
    const Message m = MakeMessage(stage, 65535, 7);
    const std::vector<std::uint8_t> bytes = EncodeMessage(m);
    ExpectEqual(m, DecodeMessage(bytes));
  }
}

TEST(Messages, RoundTripEmptyAndUninitialised) {
  Message m;
  m.stage = DgsStage::kPose;
  m.sender = 3;
  m.iteration = 0;
  m.initialised = false;
  const std::vector<std::uint8_t> bytes = EncodeMessage(m);
  EXPECT_EQ(bytes.size(), kMessageHeaderBytes);
  ExpectEqual(m, DecodeMessage(bytes));
}

TEST(Messages, SizeIsHeaderPlusCompactEntries) {
  Message m;
  m.stage = DgsStage::kRotation;
  m.sender = 2;
  m.keys = {Key::Pose(2, 5), Key::Pose(2, 63), Key::Pose(2, 64), Key::Object(2, 1)};
  m.values.assign(4 * 9, 0.5);
  // Varints of (index << 1 | kind): 10 -> 1 byte, 126 -> 1, 128 -> 2, 3 -> 1.
  EXPECT_EQ(EncodeMessage(m).size(), kMessageHeaderBytes + 5 + 4 * 9 * 8);
}

TEST(Messages, HeaderIsLittleEndian) {
  Message m;
  m.stage = DgsStage::kPose;
  m.sender = 0x0102;
  m.iteration = 0x0A0B0C0D;
  const std::vector<std::uint8_t> b = EncodeMessage(m);
  EXPECT_EQ(b[0], kMessageMagic);
  EXPECT_EQ(b[1], kMessageVersion);
  EXPECT_EQ(b[2], 2);
  EXPECT_EQ(b[3], 0);
  EXPECT_EQ(b[4], 0x02);
  EXPECT_EQ(b[5], 0x01);
  EXPECT_EQ(b[8], 0x0D);
  EXPECT_EQ(b[11], 0x0A);
}

TEST(Messages, RejectsEveryTruncation) {
  const std::vector<std::uint8_t> bytes = EncodeMessage(MakeMessage(DgsStage::kPose, 1, 3));
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(n));
    EXPECT_THROW(DecodeMessage(cut), InvalidInputError) << n;
  }
}

TEST(Messages, RejectsTrailingBytes) {
  std::vector<std::uint8_t> bytes = EncodeMessage(MakeMessage(DgsStage::kPose, 1, 3));
  bytes.push_back(0);
  EXPECT_THROW(DecodeMessage(bytes), InvalidInputError);
}

TEST(Messages, RejectsBadHeaderFields) {
  const std::vector<std::uint8_t> good = EncodeMessage(MakeMessage(DgsStage::kRotation, 1, 2));
  ASSERT_NO_THROW(DecodeMessage(good));
  const std::vector<std::pair<std::size_t, std::uint8_t>> corruptions = {
      {0, 0x00},  // magic
      {1, 2},     // version
      {2, 0},     // stage
      {2, 4},     // stage
      {3, 2},     // unknown flag bit
      {6, 1},     // reserved
  };
  for (const auto& [offset, value] : corruptions) {
    std::vector<std::uint8_t> bad = good;
    bad[offset] = value;
    EXPECT_THROW(DecodeMessage(bad), InvalidInputError) << offset;
  }
}

TEST(Messages, RejectsOversizedCount) {
  std::vector<std::uint8_t> bytes = EncodeMessage(MakeMessage(DgsStage::kPose, 1, 2));
  // Count field at offset 12: claim 2^32 - 1 entries.
  for (int b = 12; b < 16; ++b) bytes[static_cast<std::size_t>(b)] = 0xFF;
  EXPECT_THROW(DecodeMessage(bytes), InvalidInputError);
  // One more entry than the payload holds.
  std::vector<std::uint8_t> plus_one = EncodeMessage(MakeMessage(DgsStage::kPose, 1, 2));
  plus_one[12] = static_cast<std::uint8_t>(plus_one[12] + 1);
  EXPECT_THROW(DecodeMessage(plus_one), InvalidInputError);
}

TEST(Messages, RejectsInconsistentEntries) {
  Message m;
  m.stage = DgsStage::kPose;
  m.sender = 1;
  m.keys = {Key::Pose(1, 3), Key::Pose(1, 4)};
  m.values.assign(12, 1.0);
  const std::vector<std::uint8_t> good = EncodeMessage(m);
  const std::size_t first_key = kMessageHeaderBytes;
  const std::size_t second_key = kMessageHeaderBytes + 1 + 6 * 8;
  ASSERT_EQ(good[first_key], 6);
  ASSERT_EQ(good[second_key], 8);

  std::vector<std::uint8_t> duplicate = good;  // same key twice
  duplicate[second_key] = 6;
  EXPECT_THROW(DecodeMessage(duplicate), InvalidInputError);

  std::vector<std::uint8_t> decreasing = good;
  decreasing[second_key] = 4;
  EXPECT_THROW(DecodeMessage(decreasing), InvalidInputError);

  std::vector<std::uint8_t> nan = good;  // first value -> NaN
  const double q = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t bits;
  std::memcpy(&bits, &q, sizeof bits);
  for (int b = 0; b < 8; ++b) {
    nan[first_key + 1 + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(bits >> (8 * b));
  }
  EXPECT_THROW(DecodeMessage(nan), InvalidInputError);
}

TEST(Messages, RejectsMalformedVarints) {
  Message m;
  m.stage = DgsStage::kPose;
  m.sender = 1;
  const std::vector<std::uint8_t> header = EncodeMessage(m);
  auto with_key_bytes = [&](const std::vector<std::uint8_t>& key) {
    std::vector<std::uint8_t> b = header;
    b[12] = 1;  // one entry
    b.insert(b.end(), key.begin(), key.end());
    b.insert(b.end(), 48, 0);  // six zero doubles
    return b;
  };
  ASSERT_NO_THROW(DecodeMessage(with_key_bytes({0x05})));
  // Ten continuation bytes: longer than any 57-bit key.
  EXPECT_THROW(DecodeMessage(with_key_bytes(std::vector<std::uint8_t>(10, 0x80))),
               InvalidInputError);
  // Non-canonical (a redundant zero group).
  EXPECT_THROW(DecodeMessage(with_key_bytes({0x85, 0x00})), InvalidInputError);
  // Index 2^56 (packed 2^57, bit 57 = bit 1 of the 9th group): a valid varint, index too big.
  EXPECT_THROW(
      DecodeMessage(with_key_bytes({0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x02})),
      InvalidInputError);
}

TEST(Messages, EncodeRejectsInconsistentMessages) {
  Message m = MakeMessage(DgsStage::kRotation, 1, 2);
  Message foreign = m;
  foreign.keys[0].robot = 2;
  EXPECT_THROW(EncodeMessage(foreign), InvalidInputError);
  Message short_values = m;
  short_values.values.pop_back();
  EXPECT_THROW(EncodeMessage(short_values), InvalidInputError);
  Message unordered = m;
  std::swap(unordered.keys[0], unordered.keys[1]);
  EXPECT_THROW(EncodeMessage(unordered), InvalidInputError);
  Message inf = m;
  inf.values[3] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(EncodeMessage(inf), InvalidInputError);
  Message big_sender = m;
  big_sender.sender = 70000;
  for (Key& k : big_sender.keys) k.robot = 70000;
  EXPECT_THROW(EncodeMessage(big_sender), InvalidInputError);
}

// Control messages of the refinement: fixed 32 bytes, bit-exact round trip, strict decoding.
TEST(ControlMessages, RoundTripAndLayout) {
  ControlMessage m;
  m.kind = ControlKind::kStepDecision;
  m.sender = 0x0102;
  m.round = 7;
  m.sweep = 0x0A0B0C0D;
  m.flags = kAcceptStep | kRefineFinished;
  m.value[0] = 1234.5678;
  m.value[1] = -0.0;
  const std::vector<std::uint8_t> b = EncodeControlMessage(m);
  ASSERT_EQ(b.size(), kControlMessageBytes);
  EXPECT_EQ(b[0], kControlMagic);
  EXPECT_EQ(b[1], kMessageVersion);
  EXPECT_EQ(b[2], 4);
  EXPECT_EQ(b[3], 3);
  EXPECT_EQ(b[4], 0x02);
  EXPECT_EQ(b[5], 0x01);
  EXPECT_EQ(b[12], 0x0D);
  const ControlMessage d = DecodeControlMessage(b);
  EXPECT_EQ(d.kind, m.kind);
  EXPECT_EQ(d.sender, m.sender);
  EXPECT_EQ(d.round, m.round);
  EXPECT_EQ(d.sweep, m.sweep);
  EXPECT_EQ(d.flags, m.flags);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(std::memcmp(&d.value[i], &m.value[i], sizeof(double)), 0);
  // A data message is not a control message and vice versa.
  EXPECT_THROW(DecodeMessage(b), InvalidInputError);
  EXPECT_THROW(DecodeControlMessage(EncodeMessage(MakeMessage(DgsStage::kRefine, 1, 1))),
               InvalidInputError);
}

TEST(ControlMessages, RejectsMalformedInput) {
  ControlMessage m;
  m.kind = ControlKind::kReport;
  m.sender = 3;
  m.value[0] = -2.5;  // a robot's part of a dot product may be negative
  const std::vector<std::uint8_t> good = EncodeControlMessage(m);
  ASSERT_NO_THROW(DecodeControlMessage(good));
  for (std::size_t n = 0; n < good.size(); ++n) {
    const std::vector<std::uint8_t> cut(good.begin(), good.begin() + static_cast<long>(n));
    EXPECT_THROW(DecodeControlMessage(cut), InvalidInputError) << n;
  }
  std::vector<std::uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_THROW(DecodeControlMessage(longer), InvalidInputError);
  const std::vector<std::pair<std::size_t, std::uint8_t>> corruptions = {
      {0, 0xD6},  // magic
      {1, 2},     // version
      {2, 0},     // kind
      {2, 5},     // kind
      {3, 1},     // a flag a report does not define
      {6, 1},     // reserved
      {23, 0x7F}, // value[0] becomes NaN (exponent all ones, mantissa set)
  };
  for (const auto& [offset, value] : corruptions) {
    std::vector<std::uint8_t> bad = good;
    bad[offset] = value;
    if (offset == 23) bad[22] = 0xF8;
    EXPECT_THROW(DecodeControlMessage(bad), InvalidInputError) << offset;
  }
  ControlMessage inf = m;
  inf.value[1] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(EncodeControlMessage(inf), InvalidInputError);
  ControlMessage flags = m;
  flags.kind = ControlKind::kBroadcast;
  flags.flags = 2;
  EXPECT_THROW(EncodeControlMessage(flags), InvalidInputError);
  ControlMessage sender = m;
  sender.sender = 65536;
  EXPECT_THROW(EncodeControlMessage(sender), InvalidInputError);
  // A step decision halves the step (bit 2) alone: never with accepting or finishing it.
  ControlMessage halve = m;
  halve.kind = ControlKind::kStepDecision;
  halve.flags = kHalveStep;
  halve.sweep = 2;  // the halvings before it
  EXPECT_EQ(DecodeControlMessage(EncodeControlMessage(halve)).flags, kHalveStep);
  for (std::uint8_t with : {kAcceptStep, kRefineFinished}) {
    ControlMessage both = halve;
    both.flags = static_cast<std::uint8_t>(kHalveStep | with);
    EXPECT_THROW(EncodeControlMessage(both), InvalidInputError) << int(with);
    std::vector<std::uint8_t> bytes = EncodeControlMessage(halve);
    bytes[3] = both.flags;
    EXPECT_THROW(DecodeControlMessage(bytes), InvalidInputError) << int(with);
  }
  ControlMessage undefined = halve;
  undefined.flags = 8;
  EXPECT_THROW(EncodeControlMessage(undefined), InvalidInputError);
}

CoarseMessage ExampleShare() {
  CoarseMessage m;
  m.kind = CoarseKind::kShare;
  m.stage = DgsStage::kPose;
  m.sender = 3;
  m.iteration = 7;
  m.k = 6;
  m.ncols = 1;
  for (int i = 0; i < 36; ++i) m.diagonal.push_back(0.5 * i - 3.0);
  for (int i = 0; i < 6; ++i) m.residual.push_back(-1e-3 * i);
  m.center = {10.0, -2.0, 0.5};
  m.blocks.emplace_back(1, std::vector<double>(36, 2.5));
  m.blocks.emplace_back(4, std::vector<double>(36, -1.25));
  return m;
}

TEST(CoarseMessages, RoundTripAndSize) {
  const CoarseMessage m = ExampleShare();
  const std::vector<std::uint8_t> bytes = EncodeCoarseMessage(m);
  // Header, centre, diagonal and residual, two blocks of (robot id + 36 doubles).
  EXPECT_EQ(bytes.size(), 16u + 8u * (3 + 36 + 6) + 2u * (2 + 8 * 36));
  EXPECT_EQ(bytes[0], kCoarseMagic);
  const CoarseMessage d = DecodeCoarseMessage(bytes);
  EXPECT_EQ(d.kind, m.kind);
  EXPECT_EQ(d.stage, m.stage);
  EXPECT_EQ(d.sender, m.sender);
  EXPECT_EQ(d.iteration, m.iteration);
  EXPECT_EQ(d.k, m.k);
  EXPECT_EQ(d.ncols, m.ncols);
  EXPECT_EQ(d.center, m.center);
  EXPECT_EQ(d.diagonal, m.diagonal);
  EXPECT_EQ(d.residual, m.residual);
  EXPECT_EQ(d.blocks, m.blocks);

  CoarseMessage y;
  y.kind = CoarseKind::kSolution;
  y.stage = DgsStage::kRotation;
  y.k = 3;
  y.ncols = 3;
  y.blocks.emplace_back(0, std::vector<double>(9, 0.125));
  const CoarseMessage yd = DecodeCoarseMessage(EncodeCoarseMessage(y));
  EXPECT_EQ(yd.blocks, y.blocks);
  EXPECT_TRUE(yd.diagonal.empty());
}

TEST(CoarseMessages, RejectsMalformedInput) {
  const std::vector<std::uint8_t> good = EncodeCoarseMessage(ExampleShare());
  auto rejects = [](std::vector<std::uint8_t> bytes, const char* why) {
    SCOPED_TRACE(why);
    EXPECT_THROW(DecodeCoarseMessage(bytes), InvalidInputError);
  };
  rejects({good.begin(), good.begin() + 10}, "truncated header");
  rejects({good.begin(), good.end() - 1}, "truncated payload");
  std::vector<std::uint8_t> b = good;
  b.push_back(0);
  rejects(b, "trailing byte");
  b = good;
  b[0] = 0xD6;
  rejects(b, "magic of a value message");
  b = good;
  b[2] = 7;
  rejects(b, "unknown stage");
  b = good;
  b[3] = 9;
  rejects(b, "kind");
  b = good;
  b[12] = 0;
  rejects(b, "k = 0");
  b = good;
  b[14] = 2;
  rejects(b, "center size 2");
  b = good;
  b[15] = 1;
  rejects(b, "reserved");
  b = good;
  const double nan = std::nan("");
  std::memcpy(&b[16], &nan, 8);
  rejects(b, "non-finite value");

  CoarseMessage m = ExampleShare();
  std::swap(m.blocks[0], m.blocks[1]);
  EXPECT_THROW(EncodeCoarseMessage(m), InvalidInputError);  // robots not increasing
  m = ExampleShare();
  m.residual.pop_back();
  EXPECT_THROW(EncodeCoarseMessage(m), InvalidInputError);  // wrong size
  m = ExampleShare();
  m.kind = CoarseKind::kSolution;
  EXPECT_THROW(EncodeCoarseMessage(m), InvalidInputError);  // a solution has no diagonal
}

// The preconditioner of conjugate gradients sends its coarse matrix once per solve (kMatrix: a
// share without residual) and a residual per preconditioning (kResidual); neither belongs to the
// rotation stage, and a share does not belong to the refinement.
TEST(CoarseMessages, RefinementMatrixAndResidual) {
  CoarseMessage matrix = ExampleShare();
  matrix.kind = CoarseKind::kMatrix;
  matrix.stage = DgsStage::kRefine;
  matrix.residual.clear();
  const std::vector<std::uint8_t> bytes = EncodeCoarseMessage(matrix);
  EXPECT_EQ(bytes.size(), 16u + 8u * (3 + 36) + 2u * (2 + 8 * 36));
  const CoarseMessage md = DecodeCoarseMessage(bytes);
  EXPECT_EQ(md.kind, CoarseKind::kMatrix);
  EXPECT_EQ(md.diagonal, matrix.diagonal);
  EXPECT_EQ(md.blocks, matrix.blocks);
  EXPECT_TRUE(md.residual.empty());

  CoarseMessage residual;
  residual.kind = CoarseKind::kResidual;
  residual.stage = DgsStage::kRefine;
  residual.sender = 3;
  residual.k = 6;
  residual.ncols = 1;
  residual.residual = {1, 2, 3, 4, 5, 6};
  const std::vector<std::uint8_t> rb = EncodeCoarseMessage(residual);
  EXPECT_EQ(rb.size(), 16u + 8u * 6);
  EXPECT_EQ(DecodeCoarseMessage(rb).residual, residual.residual);

  auto rejects = [](std::vector<std::uint8_t> b, const char* why) {
    SCOPED_TRACE(why);
    EXPECT_THROW(DecodeCoarseMessage(b), InvalidInputError);
  };
  std::vector<std::uint8_t> b = bytes;
  b[2] = static_cast<std::uint8_t>(DgsStage::kRotation);
  rejects(b, "a matrix in the rotation stage");
  b = EncodeCoarseMessage(ExampleShare());
  b[2] = static_cast<std::uint8_t>(DgsStage::kRefine);
  rejects(b, "a share in the refinement");
  b = rb;
  b[14] = 3;
  rejects(b, "a residual with a centre");
  b = rb;
  b[6] = 1;  // one block announced
  rejects(b, "a residual with blocks");
  b = rb;
  b[12] = kMaxCoarseK + 1;
  rejects(b, "k too large");
  residual.blocks.emplace_back(0, std::vector<double>(6, 0.0));
  EXPECT_THROW(EncodeCoarseMessage(residual), InvalidInputError);
}

// The refinement's coarse space by pieces: a matrix with the robot's reference, its pieces'
// centres and blocks between pieces (its own and a neighbour's), a residual per piece, a solution
// per piece; each decoded as it was sent, and the layout's rules enforced both ways.
CoarseMessage ExamplePieceMatrix() {
  CoarseMessage m;
  m.kind = CoarseKind::kPieceMatrix;
  m.stage = DgsStage::kRefine;
  m.sender = 2;
  m.iteration = 9;
  m.k = 6;
  m.ncols = 1;
  m.center = {1.0, 2.0, 3.0};
  m.pieces = {{4, {0.5, 0.25, 0.0}}, {kMaxCoarsePieces, {-1.0, 2.0, 8.0}}};
  auto values = [](double v) { return std::vector<double>(36, v); };
  m.piece_blocks = {{4, 2, 4, values(1.0)},
                    {4, 2, kMaxCoarsePieces, values(-0.5)},
                    {4, 3, 5, values(0.25)},
                    {kMaxCoarsePieces, 1, 0, values(2.0)}};
  return m;
}

TEST(CoarseMessages, PiecesRoundTripAndRules) {
  const CoarseMessage m = ExamplePieceMatrix();
  const std::vector<std::uint8_t> bytes = EncodeCoarseMessage(m);
  EXPECT_EQ(bytes.size(), 16u + 8u * 3 + 4u + 2u * (4 + 8 * 3) + 4u + 4u * (10 + 8 * 36));
  const CoarseMessage d = DecodeCoarseMessage(bytes);
  EXPECT_EQ(d.kind, CoarseKind::kPieceMatrix);
  EXPECT_EQ(d.center, m.center);
  ASSERT_EQ(d.pieces.size(), 2u);
  EXPECT_EQ(d.pieces[1].id, kMaxCoarsePieces);
  EXPECT_EQ(d.pieces[1].values, m.pieces[1].values);
  ASSERT_EQ(d.piece_blocks.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(d.piece_blocks[i].row_piece, m.piece_blocks[i].row_piece);
    EXPECT_EQ(d.piece_blocks[i].robot, m.piece_blocks[i].robot);
    EXPECT_EQ(d.piece_blocks[i].piece, m.piece_blocks[i].piece);
    EXPECT_EQ(d.piece_blocks[i].values, m.piece_blocks[i].values);
  }

  CoarseMessage residual;
  residual.kind = CoarseKind::kPieceResidual;
  residual.stage = DgsStage::kRefine;
  residual.sender = 2;
  residual.k = 6;
  residual.ncols = 1;
  residual.pieces = {{0, {1, 2, 3, 4, 5, 6}}, {7, {6, 5, 4, 3, 2, 1}}};
  const std::vector<std::uint8_t> rb = EncodeCoarseMessage(residual);
  EXPECT_EQ(rb.size(), 16u + 4u + 2u * (4 + 8 * 6));
  EXPECT_EQ(DecodeCoarseMessage(rb).pieces[1].values, residual.pieces[1].values);

  CoarseMessage solution = residual;
  solution.kind = CoarseKind::kPieceSolution;
  solution.pieces.clear();
  solution.piece_blocks = {{0, 1, 3, {1, 2, 3, 4, 5, 6}}, {0, 2, 0, {0, 0, 0, 0, 0, 1}}};
  const std::vector<std::uint8_t> sb = EncodeCoarseMessage(solution);
  EXPECT_EQ(sb.size(), 16u + 4u + 2u * (6 + 8 * 6));
  const CoarseMessage sd = DecodeCoarseMessage(sb);
  ASSERT_EQ(sd.piece_blocks.size(), 2u);
  EXPECT_EQ(sd.piece_blocks[0].robot, 1);
  EXPECT_EQ(sd.piece_blocks[0].piece, 3u);
  EXPECT_EQ(sd.piece_blocks[1].values, solution.piece_blocks[1].values);

  auto refused = [](const CoarseMessage& bad, const char* why) {
    SCOPED_TRACE(why);
    EXPECT_THROW(EncodeCoarseMessage(bad), InvalidInputError);
  };
  CoarseMessage bad = m;
  std::swap(bad.piece_blocks[0], bad.piece_blocks[1]);
  refused(bad, "blocks out of order");
  bad = m;
  bad.piece_blocks[3].row_piece = 5;
  refused(bad, "a row piece the message lacks");
  bad = m;
  std::swap(bad.pieces[0], bad.pieces[1]);
  refused(bad, "pieces out of order");
  bad = m;
  bad.stage = DgsStage::kPose;
  refused(bad, "pieces in the pose stage");
  bad = m;
  bad.center.clear();
  refused(bad, "a piece matrix without its reference");
  bad = m;
  bad.piece_blocks[0].values[7] = std::nan("");
  refused(bad, "a non-finite block");
  bad = m;
  bad.diagonal.assign(36, 0.0);
  refused(bad, "a robot diagonal in a piece matrix");
  bad = residual;
  bad.piece_blocks = solution.piece_blocks;
  refused(bad, "blocks in a residual");
  bad = ExampleShare();
  bad.pieces = residual.pieces;
  refused(bad, "pieces in a share of robots");

  auto rejects = [](std::vector<std::uint8_t> b, const char* why) {
    SCOPED_TRACE(why);
    EXPECT_THROW(DecodeCoarseMessage(b), InvalidInputError);
  };
  for (std::size_t n = 0; n < bytes.size(); n += 7) {
    rejects(std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + n), "truncated");
  }
  std::vector<std::uint8_t> b = bytes;
  b.push_back(0);
  rejects(b, "a trailing byte");
  b = rb;
  b[6] = 1;  // a robot block announced in the header
  rejects(b, "header blocks");
  b = rb;
  b[16] = 0xFF;  // piece count low byte: far more pieces than the bytes hold
  rejects(b, "a piece count the payload does not hold");
  b = sb;
  b[19] = 0xFF;  // piece block count's high byte: beyond kMaxCoarsePieceBlocks
  rejects(b, "too many piece blocks");
  b = bytes;
  b[13] = 2;  // ncols
  rejects(b, "ncols other than 1");
}

// What each encoder refuses and each decoder rejects, with the message naming it: a pose read
// from or written to a rotation-stage message, a control message of no kind, a coarse message
// with k = 0 or with robot blocks in a piece message, a piece matrix without its centre on the
// wire and a piece count past the limit.
TEST(CoarseMessages, RefusalsNameWhatIsWrong) {
  Message rotation = MakeMessage(DgsStage::kRotation, 1, 1);
  EXPECT_TRUE(test::ThrowsNaming([&] { rotation.appendPose(Key::Pose(1, 9), SE3()); },
                                 "a pose entry needs a stage of dimension 6, not 9"));
  EXPECT_TRUE(test::ThrowsNaming([&] { rotation.pose(0); }, "dimension 6, not 9"));

  ControlMessage control;
  control.kind = static_cast<ControlKind>(0);
  EXPECT_TRUE(test::ThrowsNaming([&] { EncodeControlMessage(control); }, "unknown kind 0"));

  CoarseMessage share = ExampleShare();
  share.k = 0;
  EXPECT_TRUE(test::ThrowsNaming([&] { EncodeCoarseMessage(share); }, "k must be in [1, "));
  CoarseMessage piece = ExamplePieceMatrix();
  piece.blocks.emplace_back(1, std::vector<double>(36, 0.0));
  EXPECT_TRUE(test::ThrowsNaming([&] { EncodeCoarseMessage(piece); }, "no robot blocks"));

  const std::vector<std::uint8_t> bytes = EncodeCoarseMessage(ExamplePieceMatrix());
  ASSERT_EQ(bytes[14], 3);  // the centre's size, then its 3 doubles, then the piece count
  std::vector<std::uint8_t> no_centre = bytes;  // the centre's size 0 and its doubles cut
  no_centre[14] = 0;
  no_centre.erase(no_centre.begin() + 16, no_centre.begin() + 16 + 24);
  EXPECT_TRUE(test::ThrowsNaming([&] { DecodeCoarseMessage(no_centre); },
                                 "center size 0 (3 in a piece matrix, else 0)"));
  std::vector<std::uint8_t> many = bytes;
  const std::uint32_t count = kMaxCoarsePieces + 1;
  for (int i = 0; i < 4; ++i) many[40 + i] = static_cast<std::uint8_t>(count >> (8 * i));
  EXPECT_TRUE(test::ThrowsNaming([&] { DecodeCoarseMessage(many); },
                                 "more than " + std::to_string(kMaxCoarsePieces) + " pieces"));
}

}  // namespace
}  // namespace moslam
