// Messages the DGS robots exchange, and their compact binary serialization (the bytes a network
// layer sends). A message carries, from one sender robot, the current estimates of some of the
// sender's own variables in one stage and iteration:
//
//   header (16 bytes, little-endian):
//     u8  magic 0xD6 | u8 version 1 | u8 stage (dgs_types.h) | u8 flags (bit 0: initialised)
//     u16 sender robot | u16 reserved (0) | u32 iteration | u32 entry count
//   entries, keys strictly increasing (graph/key.h order within one robot: poses, then objects):
//     varint (index << 1 | kind)  -- LEB128, at most 9 bytes (index < 2^56)
//     StageDimension(stage) IEEE-754 doubles, 8 bytes each, little-endian
//
// Every key belongs to the sender (robots only send their own variables), so the robot is not
// repeated per entry. `initialised` tells the receiver the sender has solved in this stage
// (flagged initialisation, DGS.md). DecodeMessage rejects, with InvalidInputError naming the
// cause: truncated input, a bad magic/version/stage/flags/reserved field, an entry count the
// payload cannot hold, a malformed varint, keys not strictly increasing, a non-finite value and
// trailing bytes.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "moslam/distributed/dgs_types.h"
#include "moslam/geometry/se3.h"
#include "moslam/graph/key.h"

namespace moslam {

struct Message {
  DgsStage stage = DgsStage::kRotation;
  std::uint32_t iteration = 0;  // the sender's iteration count in this stage (0: before solving)
  int sender = 0;
  bool initialised = false;
  std::vector<Key> keys;        // the sender's variables, strictly increasing
  std::vector<double> values;   // keys.size() * StageDimension(stage), key by key

  // The StageDimension(stage) numbers of entry i.
  const double* entry(std::size_t i) const;
  // A pose as an entry, (Log R, t), and back: the map estimates of the robust solve's separator
  // check and readmission. Throw InvalidInputError unless the stage's dimension is 6.
  void appendPose(const Key& key, const SE3& pose);
  SE3 pose(std::size_t i) const;
};

inline constexpr std::uint8_t kMessageMagic = 0xD6;
inline constexpr std::uint8_t kMessageVersion = 1;
inline constexpr std::size_t kMessageHeaderBytes = 16;
inline constexpr int kMaxMessageRobot = 65535;

// Throws InvalidInputError when the message cannot be encoded: a key of another robot, keys not
// strictly increasing, values.size() not keys.size() * dimension, non-finite values, sender
// outside [0, 65535], an index >= 2^56.
std::vector<std::uint8_t> EncodeMessage(const Message& message);
Message DecodeMessage(const std::vector<std::uint8_t>& bytes);

// Control messages of the refinement stage: the scalars a coordinator robot gathers and the
// decisions it broadcasts (dgs_driver.h). Fixed size, 32 bytes, little-endian:
//
//   u8 magic 0xD7 | u8 version 1 | u8 kind | u8 flags | u16 sender | u16 reserved (0)
//   u32 round (Gauss-Newton step, 0: before the first) | u32 sweep (within the step)
//   f64 value[0] | f64 value[1]
//
//   kReport     robot -> coordinator: two scalars (after a sweep: its change and ||delta_r||;
//               conjugate gradients: its part of a dot product)
//   kBroadcast  coordinator -> robot: flags bit 0 = stop the linear solve; value[0]: a
//               coefficient (conjugate gradients: alpha or beta)
//   kCostReport robot -> coordinator: value[0] = its share of the cost
//   kStepDecision coordinator -> robot: flags bit 0 = accept the step, bit 1 = refinement
//               finished, bit 2 = halve the step and report the cost there (bit 2 alone);
//               value = (global cost: at the halved step's candidate for bit 2, damping lambda of
//               the next step); sweep: the halvings before this decision
//
// DecodeControlMessage rejects with InvalidInputError: a wrong size, bad magic/version/kind,
// flag bits the kind does not define, a non-zero reserved field, non-finite values.
enum class ControlKind : std::uint8_t {
  kReport = 1,
  kBroadcast = 2,
  kCostReport = 3,
  kStepDecision = 4,
};

struct ControlMessage {
  ControlKind kind = ControlKind::kCostReport;
  int sender = 0;
  std::uint32_t round = 0;
  std::uint32_t sweep = 0;
  std::uint8_t flags = 0;
  double value[2] = {0.0, 0.0};
};

inline constexpr std::uint8_t kControlMagic = 0xD7;
inline constexpr std::size_t kControlMessageBytes = 32;
inline constexpr std::uint8_t kStopLinearSolve = 1;  // kBroadcast
inline constexpr std::uint8_t kAcceptStep = 1;       // kStepDecision
inline constexpr std::uint8_t kRefineFinished = 2;   // kStepDecision
inline constexpr std::uint8_t kHalveStep = 4;        // kStepDecision

// Throws InvalidInputError on the same conditions DecodeControlMessage rejects.
std::vector<std::uint8_t> EncodeControlMessage(const ControlMessage& message);
ControlMessage DecodeControlMessage(const std::vector<std::uint8_t>& bytes);

// Coarse messages: the second level of the two-level DGS (dgs_driver.h,
// DgsOptions::coarse_correction) and of the refinement's preconditioner
// (DgsOptions::Refinement::coarse_preconditioner). Each robot sends its rows of a small coarse
// system to a coordinator robot, which solves it and sends each robot the coarse unknowns of
// itself and of its neighbouring robots. Little-endian:
//
//   header (16 bytes): u8 magic 0xD8 | u8 version 1 | u8 stage | u8 kind | u16 sender |
//                      u16 block count | u32 iteration | u8 k | u8 ncols | u8 center size |
//                      u8 reserved (0)
//   kShare     (rotation, pose) center size doubles (stage 2: the robot's coarse centre c_r, 3),
//              k*k doubles (P_r^T H_rr P_r), k*ncols doubles (P_r^T (g - H x)_r), then per block:
//              u16 robot s, k*k doubles (P_r^T H_rs P_s, in the sender's basis)
//   kSolution  (any stage) per block: u16 robot, k*ncols doubles (that robot's coarse unknowns y,
//              in the receiver's basis)
//   kMatrix    (pose, refinement: conjugate gradients) as kShare without the residual: the coarse
//              matrix of a linear solve, sent once per solve
//   kResidual  (pose, refinement) k*ncols doubles (P_r^T r_r), no blocks: one per preconditioning
// Matrices column-major; block robots strictly increasing.
//
// The refinement's coarse space by pieces (DgsOptions::Refinement::coarse_piece_poses): a rigid
// motion per piece of a robot instead of one per robot (refinement only, k = 6, ncols = 1, the
// header's block count 0; pieces by id, `CoarsePieceBlock`):
//   kPieceMatrix    center size 3 (the robot's reference point c_r, about which every block is
//                   computed), u32 m, m x (u32 piece, 3 doubles: the piece's centre), u32 b,
//                   b x (u32 row piece, u16 robot s, u32 piece q, 36 doubles: P_p^T H P_q)
//   kPieceResidual  u32 m, m x (u32 piece, 6 doubles: P_p^T r)
//   kPieceSolution  u32 b, b x (u16 robot, u32 piece, 6 doubles: its y, about the receiver's c_r)
// Pieces strictly increasing, blocks strictly increasing by (row piece, robot, piece) and their
// row pieces among the message's pieces.
//
// DecodeCoarseMessage rejects with InvalidInputError: truncated input, bad magic/version/stage/
// kind or a kind of another stage, k outside [1, kMaxCoarseK] or ncols outside [1, 16], a center
// size other than 0 or 3 (0 in a solution or a residual), blocks in a residual, a non-zero
// reserved field, robots not increasing, a non-finite value, trailing bytes; for the piece kinds
// also k other than 6, ncols other than 1, header blocks, more than kMaxCoarsePieces pieces or
// kMaxCoarsePieceBlocks blocks, pieces or blocks out of order, a row piece the message lacks.
enum class CoarseKind : std::uint8_t {
  kShare = 1,
  kSolution = 2,
  kMatrix = 3,
  kResidual = 4,
  kPieceMatrix = 5,
  kPieceResidual = 6,
  kPieceSolution = 7
};

inline constexpr int kMaxCoarseK = 16;
inline constexpr std::uint32_t kMaxCoarsePieces = 1u << 16;
inline constexpr std::uint32_t kMaxCoarsePieceBlocks = 1u << 20;

// A piece of a robot in a piece message: its id and its values (the centre, 3, in kPieceMatrix;
// P_p^T r, 6, in kPieceResidual).
struct CoarsePiece {
  std::uint32_t id = 0;
  std::vector<double> values;
};

// A block of a piece message: kPieceMatrix, the coupling of the sender's piece `row_piece` to
// piece `piece` of robot `robot` (6 x 6, the sender itself included); kPieceSolution, the coarse
// unknowns of piece `piece` of robot `robot` (6; row_piece 0).
struct CoarsePieceBlock {
  std::uint32_t row_piece = 0;
  int robot = 0;
  std::uint32_t piece = 0;
  std::vector<double> values;
};

struct CoarseMessage {
  CoarseKind kind = CoarseKind::kShare;
  DgsStage stage = DgsStage::kRotation;
  int sender = 0;
  std::uint32_t iteration = 0;
  int k = 3, ncols = 3;
  std::vector<double> center;                                // kShare, kMatrix: 0 or 3
  std::vector<double> diagonal, residual;                    // k*k (kShare, kMatrix), k*ncols
                                                             // (kShare, kResidual)
  std::vector<std::pair<int, std::vector<double>>> blocks;   // k*k (kShare, kMatrix); k*ncols
                                                             // (kSolution)
  std::vector<CoarsePiece> pieces;                           // kPieceMatrix, kPieceResidual
  std::vector<CoarsePieceBlock> piece_blocks;                // kPieceMatrix, kPieceSolution
};

inline constexpr std::uint8_t kCoarseMagic = 0xD8;

// An empty piece message of `kind` (kPieceMatrix, kPieceResidual or kPieceSolution): the
// refinement's stage, k = 6, ncols = 1.
inline CoarseMessage PieceMessage(CoarseKind kind, int sender, std::uint32_t iteration) {
  CoarseMessage m;
  m.kind = kind;
  m.stage = DgsStage::kRefine;
  m.sender = sender;
  m.iteration = iteration;
  m.k = 6;
  m.ncols = 1;
  return m;
}

// Throws InvalidInputError on the conditions DecodeCoarseMessage rejects (and wrong sizes).
std::vector<std::uint8_t> EncodeCoarseMessage(const CoarseMessage& message);
CoarseMessage DecodeCoarseMessage(const std::vector<std::uint8_t>& bytes);

// Weight messages of the robust solve (robust_dgs.h): between two GNC rounds, the robot that owns
// the robust separators between itself and another robot (the lower id) sends it their weights,
// in the order both robots hold those factors (the graph's). Little-endian:
//
//   u8 magic 0xD9 | u8 version 1 | u16 sender | u16 receiver | u16 reserved (0) |
//   u32 round (the GNC round, 1-based) | u32 count | count x f64 weight
//
// DecodeWeightMessage rejects with InvalidInputError: truncated input, a bad magic/version, a
// non-zero reserved field, a sender equal to the receiver, a count the payload does not hold
// exactly, a weight that is not a number in [0, 1].
struct WeightMessage {
  int sender = 0;
  int receiver = 0;
  std::uint32_t round = 0;
  std::vector<double> weights;
};

inline constexpr std::uint8_t kWeightMagic = 0xD9;
inline constexpr std::size_t kWeightHeaderBytes = 16;

// Throws InvalidInputError on the conditions DecodeWeightMessage rejects (robots outside
// [0, 65535] too).
std::vector<std::uint8_t> EncodeWeightMessage(const WeightMessage& message);
WeightMessage DecodeWeightMessage(const std::vector<std::uint8_t>& bytes);

// Covariance messages of the separator check (separator_consistency.h): beside the local
// estimates of its separator variables (a DGS message), a robot sends the other robot of the pair
// their joint covariance in its own map (solver/marginals.h), n = 6 x the number of variables, in
// the order of that DGS message's keys; the upper triangle, row by row. Little-endian:
//
//   u8 magic 0xDA | u8 version 1 | u16 sender | u16 receiver | u16 reserved (0) |
//   u32 n (a multiple of 6, at most kMaxCovarianceDimension) | u32 reserved (0) |
//   n (n + 1) / 2 x f64
//
// DecodeCovarianceMessage rejects with InvalidInputError: truncated input or trailing bytes, a
// bad magic/version, non-zero reserved fields, a sender equal to the receiver, n not a multiple
// of 6 or too large, a non-finite entry, a negative diagonal entry.
struct CovarianceMessage {
  int sender = 0;
  int receiver = 0;
  Eigen::MatrixXd covariance;  // n x n, symmetric (the encoder sends the upper triangle)
};

inline constexpr std::uint8_t kCovarianceMagic = 0xDA;
inline constexpr std::size_t kCovarianceHeaderBytes = 16;
inline constexpr std::uint32_t kMaxCovarianceDimension = 6 * 4096;

// Throws InvalidInputError on the conditions DecodeCovarianceMessage rejects (and a matrix that
// is not square).
std::vector<std::uint8_t> EncodeCovarianceMessage(const CovarianceMessage& message);
CovarianceMessage DecodeCovarianceMessage(const std::vector<std::uint8_t>& bytes);

}  // namespace moslam
