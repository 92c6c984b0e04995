#include "moslam/transport/transport.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <tuple>

#include "moslam/common/errors.h"
#include "moslam/graph/key.h"

namespace moslam {
namespace {

std::string CheckEstimates(const EstimatesPacket& p, int sender, int self) {
  if (p.receiver != self) {
    return fmt::format("DGS estimates addressed to robot {}, not to this robot", p.receiver);
  }
  if (p.message.sender != sender) {
    return fmt::format("DGS estimates claim sender {} but came from robot {}", p.message.sender,
                       sender);
  }
  const auto stage = static_cast<int>(p.message.stage);
  if (stage < 1 || stage > 3) return fmt::format("DGS estimates with unknown stage {}", stage);
  try {
    (void)EncodeMessage(p.message);  // checks keys (owner, order, range), counts, finiteness
  } catch (const InvalidInputError& e) {
    return std::string("malformed DGS estimates: ") + e.what();
  }
  return {};
}

}  // namespace

TransportStats operator-(const TransportStats& later, const TransportStats& earlier) {
  static_assert(sizeof(TransportStats) == 17 * sizeof(std::int64_t),
                "TransportStats has a new counter: subtract it here");
  TransportStats d;
  d.sent_samples = later.sent_samples - earlier.sent_samples;
  d.sent_bytes = later.sent_bytes - earlier.sent_bytes;
  d.received_samples = later.received_samples - earlier.received_samples;
  d.received_bytes = later.received_bytes - earlier.received_bytes;
  d.rejected = later.rejected - earlier.rejected;
  d.estimates_sent = later.estimates_sent - earlier.estimates_sent;
  d.estimates_bytes = later.estimates_bytes - earlier.estimates_bytes;
  d.status_sent = later.status_sent - earlier.status_sent;
  d.status_bytes = later.status_bytes - earlier.status_bytes;
  d.coarse_sent = later.coarse_sent - earlier.coarse_sent;
  d.coarse_bytes = later.coarse_bytes - earlier.coarse_bytes;
  d.weights_sent = later.weights_sent - earlier.weights_sent;
  d.weights_bytes = later.weights_bytes - earlier.weights_bytes;
  d.covariances_sent = later.covariances_sent - earlier.covariances_sent;
  d.covariances_bytes = later.covariances_bytes - earlier.covariances_bytes;
  d.objects_sent = later.objects_sent - earlier.objects_sent;
  d.objects_bytes = later.objects_bytes - earlier.objects_bytes;
  return d;
}

bool TeamPairBefore(const TeamPairEntry& a, const TeamPairEntry& b) {
  return std::make_tuple(a.mine, a.other_robot, a.other) <
         std::make_tuple(b.mine, b.other_robot, b.other);
}

namespace {

std::string CheckStatus(const StatusPacket& p, int sender) {
  if (p.robot != sender) {
    return fmt::format("status claims robot {} but came from robot {}", p.robot, sender);
  }
  if (static_cast<int>(p.state) > static_cast<int>(RobotState::kFailed)) {
    return fmt::format("status with unknown state {}", static_cast<int>(p.state));
  }
  if (p.stage > 3) return fmt::format("status with unknown stage {}", p.stage);
  if (std::isnan(p.change) || p.change < 0.0) {
    return fmt::format("status with invalid change {}", p.change);
  }
  if (std::isnan(p.error_bound) || p.error_bound < 0.0) {
    return fmt::format("status with invalid error bound {}", p.error_bound);
  }
  if (!std::isfinite(p.value[0]) || !std::isfinite(p.value[1])) {
    return "status with non-finite values";
  }
  if (p.neighbours.size() > kMaxNeighbours) return "status with too many neighbours";
  for (std::size_t i = 0; i < p.neighbours.size(); ++i) {
    const int n = p.neighbours[i];
    if (n < 0 || n > kMaxTransportRobot || n == p.robot ||
        (i > 0 && n <= p.neighbours[i - 1])) {
      return fmt::format("status with invalid neighbour list (entry {}: {})", i, n);
    }
  }
  if (p.team.size() > kMaxObjects) return "status with too many team pairs";
  for (std::size_t i = 0; i < p.team.size(); ++i) {
    const TeamPairEntry& t = p.team[i];
    if (t.mine > kMaxKeyIndex || t.other > kMaxKeyIndex || t.other_robot < 0 ||
        t.other_robot > kMaxTransportRobot || t.other_robot == p.robot ||
        (i > 0 && !TeamPairBefore(p.team[i - 1], t))) {
      return fmt::format("status with an invalid team pair (entry {}: {} - robot {} object {})",
                         i, t.mine, t.other_robot, t.other);
    }
    if (!t.pose.rotation().matrix().allFinite() || !t.pose.translation().allFinite()) {
      return fmt::format("status with a non-finite team pair pose (entry {})", i);
    }
  }
  return {};
}

std::string CheckObjects(const ObjectListPacket& p, int sender) {
  if (p.robot != sender) {
    return fmt::format("object list claims robot {} but came from robot {}", p.robot, sender);
  }
  if (p.objects.size() > kMaxObjects) return "object list with too many objects";
  std::set<std::uint64_t> ids;
  for (const ObjectObservation& o : p.objects) {
    if (o.id > kMaxKeyIndex) return fmt::format("object id {} out of range", o.id);
    if (!ids.insert(o.id).second) return fmt::format("object id {} listed twice", o.id);
    if (o.label.empty() || o.label.size() > kMaxObjectLabel) {
      return fmt::format("object {} with a label of {} characters", o.id, o.label.size());
    }
    for (char c : o.label) {
      if (c < 0x20 || c > 0x7e) return fmt::format("object {} label not printable", o.id);
    }
    if (!o.pose.rotation().matrix().allFinite() || !o.pose.translation().allFinite()) {
      return fmt::format("object {} with a non-finite pose", o.id);
    }
  }
  return {};
}

std::string CheckShared(const SharedObjectsPacket& p, int sender, int self) {
  if (p.sender != sender) {
    return fmt::format("shared objects claim sender {} but came from robot {}", p.sender, sender);
  }
  if (p.receiver != self) {
    return fmt::format("shared objects addressed to robot {}, not to this robot", p.receiver);
  }
  for (const auto* list : {&p.pairs, &p.removed}) {
    const char* what = list == &p.pairs ? "shared object pair" : "removed shared object pair";
    if (list->size() > kMaxObjects) return fmt::format("too many of: {}", what);
    std::set<std::uint64_t> alpha, beta;
    for (const auto& [a, b] : *list) {
      if (a > kMaxKeyIndex || b > kMaxKeyIndex) {
        return fmt::format("{} ({}, {}) out of range", what, a, b);
      }
      if (!alpha.insert(a).second || !beta.insert(b).second) {
        return fmt::format("{} ({}, {}) uses an object twice", what, a, b);
      }
    }
  }
  return {};
}

std::string CheckCoarse(const CoarsePacket& p, int sender) {
  if (p.message.sender != sender) {
    return fmt::format("coarse share claims sender {} but came from robot {}", p.message.sender,
                       sender);
  }
  if (p.message.kind == CoarseKind::kSolution || p.message.kind == CoarseKind::kPieceSolution) {
    return "a coarse solution is not a share";
  }
  try {
    (void)EncodeCoarseMessage(p.message);  // stage, kind, sizes, finiteness, block robots
  } catch (const InvalidInputError& e) {
    return std::string("malformed coarse share: ") + e.what();
  }
  return {};
}

std::string CheckWeights(const WeightsPacket& p, int sender, int self) {
  if (p.message.sender != sender) {
    return fmt::format("weights claim sender {} but came from robot {}", p.message.sender, sender);
  }
  if (p.message.receiver != self) {
    return fmt::format("weights addressed to robot {}, not to this robot", p.message.receiver);
  }
  if (p.message.weights.size() > kMaxWeights) return "weights: too many";
  try {
    (void)EncodeWeightMessage(p.message);  // every weight a number in [0, 1]
  } catch (const InvalidInputError& e) {
    return std::string("malformed weights: ") + e.what();
  }
  return {};
}

std::string CheckCovariance(const CovariancePacket& p, int sender, int self) {
  if (p.message.sender != sender) {
    return fmt::format("covariance claims sender {} but came from robot {}", p.message.sender,
                       sender);
  }
  if (p.message.receiver != self) {
    return fmt::format("covariance addressed to robot {}, not to this robot", p.message.receiver);
  }
  if (p.message.covariance.rows() > kMaxTransportCovarianceDimension) {
    return "covariance: dimension too large";
  }
  try {
    (void)EncodeCovarianceMessage(p.message);  // square, 6 k, finite, non-negative diagonal
  } catch (const InvalidInputError& e) {
    return std::string("malformed covariance: ") + e.what();
  }
  return {};
}

}  // namespace

std::string CheckPacket(const Packet& packet, int sender, int self, const std::set<int>& known) {
  if (sender < 0 || sender > kMaxTransportRobot) {
    return fmt::format("sample from invalid robot id {}", sender);
  }
  if (sender == self) return fmt::format("sample claims this robot's own id {}", sender);
  if (!known.empty() && known.count(sender) == 0) {
    return fmt::format("sample from unknown robot {}", sender);
  }
  if (const auto* e = std::get_if<EstimatesPacket>(&packet)) return CheckEstimates(*e, sender, self);
  if (const auto* s = std::get_if<StatusPacket>(&packet)) return CheckStatus(*s, sender);
  if (const auto* h = std::get_if<SharedObjectsPacket>(&packet)) {
    return CheckShared(*h, sender, self);
  }
  if (const auto* c = std::get_if<CoarsePacket>(&packet)) return CheckCoarse(*c, sender);
  if (const auto* w = std::get_if<WeightsPacket>(&packet)) return CheckWeights(*w, sender, self);
  if (const auto* v = std::get_if<CovariancePacket>(&packet)) {
    return CheckCovariance(*v, sender, self);
  }
  return CheckObjects(std::get<ObjectListPacket>(packet), sender);
}

std::int64_t BinarySize(const Packet& packet) {
  if (const auto* e = std::get_if<EstimatesPacket>(&packet)) {
    // The binary Message plus receiver (u16), solve and round (u32).
    return static_cast<std::int64_t>(EncodeMessage(e->message).size()) + 10;
  }
  if (const auto* s = std::get_if<StatusPacket>(&packet)) {
    // robot u16, solve and incarnation u32, state/stage/flags 3 x u8, round/iteration u32,
    // change and error bound f64, two f64 values, neighbour count u16 + u16 each, team pair
    // count u16 + per pair two u64 ids, robot u16, two flags, step u32, 7 f64.
    return 2 + 4 + 4 + 3 + 8 + 4 * 8 + 2 + 2 * static_cast<std::int64_t>(s->neighbours.size()) +
           2 + (8 + 8 + 2 + 2 + 4 + 7 * 8) * static_cast<std::int64_t>(s->team.size());
  }
  if (const auto* c = std::get_if<CoarsePacket>(&packet)) {
    return static_cast<std::int64_t>(EncodeCoarseMessage(c->message).size()) + 8;  // + solve, round
  }
  if (const auto* w = std::get_if<WeightsPacket>(&packet)) {
    return static_cast<std::int64_t>(EncodeWeightMessage(w->message).size()) + 8;  // + solve, round
  }
  if (const auto* v = std::get_if<CovariancePacket>(&packet)) {
    return static_cast<std::int64_t>(EncodeCovarianceMessage(v->message).size()) + 8;
  }
  if (const auto* h = std::get_if<SharedObjectsPacket>(&packet)) {
    // sender, receiver u16, step u32, two counts u32, two u64 ids per pair.
    return 2 + 2 + 4 + 4 + 4 + 16 * static_cast<std::int64_t>(h->pairs.size() + h->removed.size());
  }
  const auto& o = std::get<ObjectListPacket>(packet);
  std::int64_t bytes = 2 + 4 + 4 + 4;  // robot, revision, step, count
  for (const ObjectObservation& ob : o.objects) {
    bytes += 8 + 1 + static_cast<std::int64_t>(ob.label.size()) + 7 * 8;
  }
  return bytes;
}

std::function<void(const std::string&)> StderrLog(int robot) {
  return [robot](const std::string& text) {
    fmt::print(stderr, "moslam transport [robot {}]: {}\n", robot, text);
    std::fflush(stderr);
  };
}

}  // namespace moslam
