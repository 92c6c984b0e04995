#include "moslam/transport/dds_wire.h"

#include <dds/ddsi/ddsi_cdrstream.h>
#include <fmt/core.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {

std::int64_t CdrSize(const dds_topic_descriptor_t& type, const void* sample) {
  dds_ostream_t os;
  dds_ostream_init(&os, 0, kXcdr1);
  dds_stream_write(&os, static_cast<const char*>(sample), type.m_ops);
  const std::int64_t size = os.m_index + kEncapsulationHeader;
  dds_ostream_fini(&os);
  return size;
}

SE3 PoseFromWire(const double* position, const double* q, const std::string& what) {
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!std::isfinite(norm) || std::abs(norm - 1.0) > 1e-6) {
    throw InvalidInputError(
        fmt::format("{} orientation is not a unit quaternion (norm {})", what, norm));
  }
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(position[k])) throw InvalidInputError(what + " position not finite");
  }
  return SE3(SO3::FromQuaternion(q[3], q[0], q[1], q[2]),
             Vector3(position[0], position[1], position[2]));
}

void PoseToWire(const SE3& pose, double* position, double* orientation) {
  const Eigen::Quaterniond q(pose.rotation().matrix());
  orientation[0] = q.x();
  orientation[1] = q.y();
  orientation[2] = q.z();
  orientation[3] = q.w();
  for (int k = 0; k < 3; ++k) position[k] = pose.translation()(k);
}

std::uint64_t WireKey(const Key& k) { return k.index << 1 | static_cast<std::uint64_t>(k.kind); }

EstimatesPacket FromSample(const EstimatesSample& s) {
  EstimatesPacket p;
  p.receiver = s.receiver;
  p.solve = s.solve;
  p.round = s.round;
  p.message.stage = static_cast<DgsStage>(s.stage);
  p.message.iteration = s.iteration;
  p.message.sender = s.sender;
  p.message.initialised = s.initialised;
  p.message.keys.reserve(s.keys._length);
  for (std::uint32_t i = 0; i < s.keys._length; ++i) {
    const std::uint64_t w = s.keys._buffer[i];
    p.message.keys.push_back(
        {s.sender, (w & 1u) ? VariableKind::kObject : VariableKind::kPose, w >> 1});
  }
  p.message.values.assign(s.values._buffer, s.values._buffer + s.values._length);
  return p;
}

StatusPacket FromSample(const StatusSample& s) {
  StatusPacket p;
  p.robot = s.robot;
  p.solve = s.solve;
  p.incarnation = s.incarnation;
  p.state = static_cast<RobotState>(s.state);
  p.stage = s.stage;
  p.round = s.round;
  p.iteration = s.iteration;
  p.sent = s.sent;
  p.initialised = s.initialised;
  p.done = s.done;
  p.change = s.change;
  p.error_bound = s.error_bound;
  p.coarse_ready = s.coarse_ready;
  p.coarse = s.coarse;
  p.weights = s.weights;
  p.covariance = s.covariance;
  p.value[0] = s.values[0];
  p.value[1] = s.values[1];
  p.neighbours.assign(s.neighbours._buffer, s.neighbours._buffer + s.neighbours._length);
  for (std::uint32_t i = 0; i < s.team._length; ++i) {
    const TeamPairSample& w = s.team._buffer[i];
    TeamPairEntry t;
    t.mine = w.mine;
    t.other_robot = w.other_robot;
    t.other = w.other;
    t.mine_is_alpha = w.mine_is_alpha;
    t.held = w.held;
    t.step = w.step;
    t.pose = PoseFromWire(w.position, w.orientation, fmt::format("team pair {}", i));
    p.team.push_back(t);
  }
  return p;
}

CoarsePacket FromSample(const CoarseSample& s) {
  CoarsePacket p;
  p.solve = s.solve;
  p.round = s.round;
  CoarseMessage& m = p.message;
  m.sender = s.sender;
  m.stage = static_cast<DgsStage>(s.stage);
  m.kind = static_cast<CoarseKind>(s.kind);
  m.iteration = s.iteration;
  m.k = s.k;
  m.ncols = s.ncols;
  m.center = Doubles(s.center);
  m.diagonal = Doubles(s.diagonal);
  m.residual = Doubles(s.residual);
  const std::uint32_t n = s.block_robots._length;
  if (n > 0) {
    if (s.blocks._length % n != 0) {
      throw InvalidInputError(fmt::format("{} coupling values for {} blocks", s.blocks._length, n));
    }
    const std::uint32_t size = s.blocks._length / n;
    for (std::uint32_t i = 0; i < n; ++i) {
      const double* b = s.blocks._buffer + static_cast<std::size_t>(i) * size;
      m.blocks.emplace_back(s.block_robots._buffer[i], std::vector<double>(b, b + size));
    }
  } else if (s.blocks._length != 0) {
    throw InvalidInputError("coupling values without blocks");
  }
  // By pieces: each piece's values and each piece block's of one size, as the kind says.
  const std::uint32_t pieces = s.piece_ids._length;
  if (pieces > 0) {
    if (s.piece_values._length % pieces != 0) {
      throw InvalidInputError(
          fmt::format("{} piece values for {} pieces", s.piece_values._length, pieces));
    }
    const std::uint32_t size = s.piece_values._length / pieces;
    for (std::uint32_t i = 0; i < pieces; ++i) {
      const double* v = s.piece_values._buffer + static_cast<std::size_t>(i) * size;
      m.pieces.push_back({s.piece_ids._buffer[i], std::vector<double>(v, v + size)});
    }
  } else if (s.piece_values._length != 0) {
    throw InvalidInputError("piece values without pieces");
  }
  const std::uint32_t piece_blocks = s.piece_block_robots._length;
  if (s.block_row_pieces._length != piece_blocks || s.block_pieces._length != piece_blocks) {
    throw InvalidInputError(fmt::format("piece blocks of {} robots, {} row pieces and {} pieces",
                                        piece_blocks, s.block_row_pieces._length,
                                        s.block_pieces._length));
  }
  if (piece_blocks > 0) {
    if (s.piece_block_values._length % piece_blocks != 0) {
      throw InvalidInputError(fmt::format("{} piece block values for {} blocks",
                                          s.piece_block_values._length, piece_blocks));
    }
    const std::uint32_t size = s.piece_block_values._length / piece_blocks;
    for (std::uint32_t i = 0; i < piece_blocks; ++i) {
      const double* v = s.piece_block_values._buffer + static_cast<std::size_t>(i) * size;
      m.piece_blocks.push_back({s.block_row_pieces._buffer[i], s.piece_block_robots._buffer[i],
                                s.block_pieces._buffer[i], std::vector<double>(v, v + size)});
    }
  } else if (s.piece_block_values._length != 0) {
    throw InvalidInputError("piece block values without blocks");
  }
  return p;
}

WeightsPacket FromSample(const WeightsSample& s) {
  WeightsPacket p;
  p.solve = s.solve;
  p.round = s.round;
  p.message.sender = s.sender;
  p.message.receiver = s.receiver;
  p.message.round = s.gnc_round;
  p.message.weights = Doubles(s.weights);
  return p;
}

// Throws InvalidInputError when the triangle does not hold n (n + 1) / 2 entries.
CovariancePacket FromSample(const CovarianceSample& s) {
  CovariancePacket p;
  p.solve = s.solve;
  p.round = s.round;
  p.message.sender = s.sender;
  p.message.receiver = s.receiver;
  const std::uint64_t n = s.dimension;
  if (n > kMaxTransportCovarianceDimension || s.upper._length != n * (n + 1) / 2) {
    throw InvalidInputError("covariance of dimension " + std::to_string(n) + " with " +
                            std::to_string(s.upper._length) + " entries");
  }
  const auto dim = static_cast<Eigen::Index>(n);
  p.message.covariance.resize(dim, dim);
  std::size_t k = 0;
  for (Eigen::Index i = 0; i < dim; ++i) {
    for (Eigen::Index j = i; j < dim; ++j) {
      p.message.covariance(i, j) = p.message.covariance(j, i) = s.upper._buffer[k++];
    }
  }
  return p;
}

ObjectListPacket FromSample(const ObjectListSample& s) {
  ObjectListPacket p;
  p.robot = s.robot;
  p.revision = s.revision;
  p.step = s.step;
  for (std::uint32_t i = 0; i < s.objects._length; ++i) {
    const ObjectPoseSample& o = s.objects._buffer[i];
    ObjectObservation ob;
    ob.id = o.id;
    ob.label.assign(o.label, strnlen(o.label, sizeof o.label));
    ob.pose = PoseFromWire(o.position, o.orientation, fmt::format("object {}", o.id));
    p.objects.push_back(std::move(ob));
  }
  return p;
}

SharedObjectsPacket FromSample(const SharedSample& s) {
  SharedObjectsPacket p;
  p.sender = s.sender;
  p.receiver = s.receiver;
  p.step = s.step;
  for (std::uint32_t i = 0; i < s.pairs._length; ++i) {
    p.pairs.emplace_back(s.pairs._buffer[i].alpha, s.pairs._buffer[i].beta);
  }
  for (std::uint32_t i = 0; i < s.removed._length; ++i) {
    p.removed.emplace_back(s.removed._buffer[i].alpha, s.removed._buffer[i].beta);
  }
  return p;
}

}  // namespace moslam::transport_detail
