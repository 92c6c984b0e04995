// How robot processes talk: the packets of the multi-robot protocol and the Transport interface
// that moves them (dds_transport.h: Cyclone DDS between processes and machines;
// in_process_transport.h: threads of one process, for unit tests).
//
// Packets (one DDS topic each, idl/*.idl, ROS 2 naming moslam/msg/<Name>):
//   EstimatesPacket  DGS estimates for ONE receiver in one stage and protocol round
//                    (topic rt/moslam/robot<R>/dgs_estimates: the receiver's inbox);
//   StatusPacket     a robot's progress, to every robot (rt/moslam/status), after every protocol
//                    step: what it reports to the team (robot_program.h, TeamReport);
//   CoarsePacket     a robot's rows of a coarse system (two-level DGS, the refinement's
//                    preconditioner), to every robot (rt/moslam/dgs_coarse): each robot solves it;
//   WeightsPacket    the robust solve's weights of the factors a robot owns, for ONE neighbour
//                    (rt/moslam/robot<R>/dgs_weights: the receiver's inbox; robust_program.h);
//   CovariancePacket the separator check's map covariance of a robot's separator variables, for
//                    ONE neighbour (rt/moslam/robot<R>/dgs_covariance: the receiver's inbox;
//                    robust_program.h);
//   ObjectListPacket the objects a robot shares at a rendezvous, label + pose each
//                    (rt/moslam/objects: every robot in range);
//   SharedObjectsPacket the answer to an object list: the pairs of shared objects found by the
//                    robot that matched it (rt/moslam/robot<R>/shared_objects: the inbox of R,
//                    the robot that sent the list).
//
// Delivery contract, met by both transports: reliable and in order per sender; a robot that
// joins late (or restarts) still receives each sender's recent history (the last
// kTransportHistoryDepth packets per sender and topic), so a restarted robot catches up; alive()
// tells which robots currently assert liveliness.
//
// Every received packet is validated before poll() returns it (CheckPacket below): a sample from
// a robot outside setKnownRobots(), addressed to another robot, or with malformed content (bad
// stage, keys not the sender's or not increasing, wrong value count, NaN/Inf, ...) is rejected:
// counted in stats().rejected and reported through TransportOptions::log, never returned and
// never thrown at the caller.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "moslam/distributed/messages.h"
#include "moslam/geometry/se3.h"

namespace moslam {

inline constexpr int kTransportHistoryDepth = 16;
// Robot ids travel as 16-bit fields.
inline constexpr int kMaxTransportRobot = 65535;
inline constexpr std::size_t kMaxObjectLabel = 64;
inline constexpr std::size_t kMaxObjects = 4096;
inline constexpr std::size_t kMaxNeighbours = 1024;
inline constexpr std::size_t kMaxWeights = 65536;  // per WeightsPacket
// Per CovariancePacket: the dimension (6 per separator variable of a robot pair).
inline constexpr std::uint32_t kMaxTransportCovarianceDimension = 6 * 256;

// The distributed solve a DGS packet (estimates, status, coarse share) belongs to: 0 for the
// batch solve after the mission; with online mapping, 1 + the time step of the rendezvous whose
// group solves (a robot takes part in at most one solve per step).
//
// kPresenceSolve: a status of no solve, which an online robot publishes when it starts so that
// its liveliness is asserted before its first solve (its partners tell a robot that has left for
// good from one that is slow: robot_session.h). Every solve ignores it.
inline constexpr std::uint32_t kPresenceSolve = 0xFFFFFFFFu;
struct EstimatesPacket {
  int receiver = 0;
  std::uint32_t solve = 0;
  std::uint32_t round = 0;  // protocol round of message.stage (0: before any solve)
  Message message;          // sender, stage, iteration, initialised, keys, values
};

// A robot's protocol state (Status_.state on the wire).
enum class RobotState : std::uint8_t {
  kJoining = 0,
  kRotation = 1,
  kPose = 2,
  kRefine = 3,
  kDone = 4,
  kFailed = 5,
};

// Online mapping: a shared pair of the sender's landmark with a landmark of a robot outside the
// group solve it joins, and the sender's copy of that landmark (online/group_solve.h, TeamPair).
struct TeamPairEntry {
  std::uint64_t mine = 0;   // the sender's object index (< 2^56)
  int other_robot = 0;      // not the sender
  std::uint64_t other = 0;  // object index of other_robot (< 2^56)
  bool mine_is_alpha = false;
  bool held = false;        // the sender holds a copy of the other landmark:
  std::uint32_t step = 0;   // from the group solve of this time step,
  SE3 pose;                 // in the sender's own frame
};

// The order of team pairs in a status: by (mine, other_robot, other).
bool TeamPairBefore(const TeamPairEntry& a, const TeamPairEntry& b);

struct StatusPacket {
  int robot = 0;
  std::uint32_t solve = 0;
  std::uint32_t incarnation = 0;  // process starts of this robot minus one
  RobotState state = RobotState::kJoining;
  std::uint8_t stage = 0;         // DgsStage of `round`, 0 while joining
  std::uint32_t round = 0;        // last completed round of the stage
  std::uint32_t iteration = 0;    // solves in the stage
  bool sent = false;              // it sent estimates to its neighbours in this round
  bool initialised = false;       // it has solved in this stage
  bool done = false;              // its result is final and saved
  double change = std::numeric_limits<double>::infinity();  // RobotAgent::lastChange()
  double error_bound = std::numeric_limits<double>::infinity();  // RobotAgent::errorBound()
  bool coarse_ready = false;      // it can take part in a coarse correction
  bool coarse = false;            // a CoarsePacket of this round comes with the status
  bool weights = false;           // a WeightsPacket of this round to every neighbour comes with it
  bool covariance = false;        // a CovariancePacket of this round to every neighbour comes too
  double value[2] = {0.0, 0.0};   // its inputs to the round's team-wide sums and maxima
  std::vector<int> neighbours;    // robots its separators reach, increasing
  // Only when it joins an online group solve: its team pairs, increasing by (mine, other_robot,
  // other), at most kMaxObjects.
  std::vector<TeamPairEntry> team;
};

// A robot's coarse share of one protocol round, to every robot.
struct CoarsePacket {
  std::uint32_t solve = 0;
  std::uint32_t round = 0;
  CoarseMessage message;  // sender, stage, kind (share, matrix or residual; of pieces too), blocks
};

// A robot's weights for one neighbour in one protocol round of the robust solve.
struct WeightsPacket {
  std::uint32_t solve = 0;
  std::uint32_t round = 0;
  WeightMessage message;  // sender, receiver, GNC round, weights (each in [0, 1])
};

// A robot's map covariance for one neighbour in one protocol round of the separator check.
struct CovariancePacket {
  std::uint32_t solve = 0;
  std::uint32_t round = 0;
  CovarianceMessage message;  // sender, receiver, the joint covariance (n x n, n = 6 k)
};

struct ObjectObservation {
  std::uint64_t id = 0;  // object index (Key::Object(robot, id)), < 2^56
  std::string label;     // 1..kMaxObjectLabel characters
  SE3 pose;              // in the sending robot's world frame
};

struct ObjectListPacket {
  int robot = 0;
  std::uint32_t revision = 0;  // increases with every list the robot publishes
  std::uint32_t step = 0;      // time step (pose index) of the map: the rendezvous it is for
  std::vector<ObjectObservation> objects;
};

// Beta's answer to alpha's object list of `step`: (alpha object id, beta object id) per new
// shared object, and per pair shared before that the consistency check across rendezvous drops
// (unknown initial poses: slam/rendezvous.h); each id at most once per list.
struct SharedObjectsPacket {
  int sender = 0;    // beta, who matched
  int receiver = 0;  // alpha, who sent the list
  std::uint32_t step = 0;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> pairs;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> removed;
};

using Packet = std::variant<EstimatesPacket, StatusPacket, ObjectListPacket, SharedObjectsPacket,
                            CoarsePacket, WeightsPacket, CovariancePacket>;

struct Received {
  int sender = 0;
  Packet packet;
};

// Counters of one transport endpoint. Bytes are the serialized payloads (CDR for DDS, the binary
// Message encoding for DGS estimates in-process), without middleware or IP headers.
struct TransportStats {
  std::int64_t sent_samples = 0;
  std::int64_t sent_bytes = 0;
  std::int64_t received_samples = 0;  // accepted
  std::int64_t received_bytes = 0;
  std::int64_t rejected = 0;          // invalid or from an unknown robot
  std::int64_t estimates_sent = 0;    // DGS estimates among sent_samples, and their bytes
  std::int64_t estimates_bytes = 0;
  std::int64_t status_sent = 0;
  std::int64_t status_bytes = 0;
  std::int64_t coarse_sent = 0;       // coarse shares (two-level DGS, refinement)
  std::int64_t coarse_bytes = 0;
  std::int64_t weights_sent = 0;      // robust solve's weights
  std::int64_t weights_bytes = 0;
  std::int64_t covariances_sent = 0;  // the separator check's map covariances
  std::int64_t covariances_bytes = 0;
  std::int64_t objects_sent = 0;      // object lists and shared-object answers (rendezvous)
  std::int64_t objects_bytes = 0;
};

// Field by field: what was counted between two readings of the same transport (later - earlier).
TransportStats operator-(const TransportStats& later, const TransportStats& earlier);

struct TransportOptions {
  // Where rejections and connection events are reported; default: one line on stderr.
  std::function<void(const std::string&)> log;
};

class Transport {
 public:
  virtual ~Transport() = default;

  virtual int self() const = 0;
  // Reliable send to packet.receiver. Throws InvalidInputError on a packet CheckPacket rejects
  // (the caller's bug: sender must be self()).
  virtual void send(const EstimatesPacket& packet) = 0;
  virtual void send(const SharedObjectsPacket& packet) = 0;
  virtual void send(const WeightsPacket& packet) = 0;
  virtual void send(const CovariancePacket& packet) = 0;
  // To every robot. Throws InvalidInputError as send().
  virtual void publish(const StatusPacket& packet) = 0;
  virtual void publish(const ObjectListPacket& packet) = 0;
  virtual void publish(const CoarsePacket& packet) = 0;
  // The valid packets that arrived since the last call; when none has, waits up to `timeout`
  // for one. Never throws on received content.
  virtual std::vector<Received> poll(std::chrono::milliseconds timeout) = 0;
  // Other robots whose liveliness is asserted now (they have published a status and not left).
  virtual std::set<int> alive() const = 0;
  // From now on accept only packets from these robots (empty: any robot id).
  virtual void setKnownRobots(const std::set<int>& robots) = 0;
  virtual TransportStats stats() const = 0;
};

// Empty when `packet`, received by robot `self` from `sender`, is valid; else the reason.
// `known`: accepted senders (empty: any). Estimates must be addressed to `self`; their content is
// what EncodeMessage accepts (no variable at all included: the robust program's check steps send
// every neighbour a message, empty where it has nothing for it). Status: state and stage in range,
// change >= 0 (+inf allowed), error bound >= 0 (+inf allowed), values finite, neighbours distinct,
// increasing, without the robot itself; team pairs at most kMaxObjects, increasing, ids < 2^56,
// other robot not the sender, finite poses. Coarse: the sender's own share, what
// EncodeCoarseMessage accepts, kind share, matrix or residual (of robots or of pieces). Weights:
// addressed to `self`, what EncodeWeightMessage accepts (each weight in [0, 1]), at most
// kMaxWeights. Covariance: addressed to `self`, what EncodeCovarianceMessage accepts (finite,
// non-negative diagonal), dimension at most kMaxTransportCovarianceDimension. Objects: finite
// poses, unit quaternions (checked before conversion, tolerance 1e-6), labels of 1..64 printable
// characters, distinct ids < 2^56, at most kMaxObjects. Shared objects: addressed to `self`, at
// most kMaxObjects pairs, ids < 2^56, no id twice on either side.
std::string CheckPacket(const Packet& packet, int sender, int self, const std::set<int>& known);

// Bytes of the binary encoding of a packet (messages.h for estimates; a comparable fixed-size
// layout for the others), the in-process transport's byte count.
std::int64_t BinarySize(const Packet& packet);

// The default log: "moslam transport [robot R]: <text>" on stderr.
std::function<void(const std::string&)> StderrLog(int robot);

}  // namespace moslam
