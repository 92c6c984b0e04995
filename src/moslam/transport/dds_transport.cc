#include "moslam/transport/dds_transport.h"

#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>
#include <map>
#include <mutex>

#include "moslam/common/errors.h"
#include "moslam/transport/dds_entities.h"
#include "moslam/transport/dds_wire.h"

namespace moslam {

void DdsTransportOptions::validate() const {
  if (domain < 0 || domain > 232) {
    throw InvalidInputError("DDS transport: domain id must be in [0, 232], got " +
                            std::to_string(domain));
  }
  if (liveliness_lease.count() <= 0) {
    throw InvalidInputError("DDS transport: the liveliness lease must be positive");
  }
}

std::string StatusTopicName() { return "rt/moslam/status"; }
std::string CoarseTopicName() { return "rt/moslam/dgs_coarse"; }
std::string ObjectsTopicName() { return "rt/moslam/objects"; }
std::string EstimatesTopicName(int robot) {
  return "rt/moslam/robot" + std::to_string(robot) + "/dgs_estimates";
}
std::string WeightsTopicName(int robot) {
  return "rt/moslam/robot" + std::to_string(robot) + "/dgs_weights";
}
std::string CovarianceTopicName(int robot) {
  return "rt/moslam/robot" + std::to_string(robot) + "/dgs_covariance";
}
std::string SharedObjectsTopicName(int robot) {
  return "rt/moslam/robot" + std::to_string(robot) + "/shared_objects";
}

int DiscoveryPort(int domain, int index) { return 7400 + 250 * domain + 10 + 2 * index; }

namespace {

// Letters, digits and the punctuation of interface names and IPv4/IPv6 addresses.
bool NameOrAddress(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == ':' || ch == '-' ||
           ch == '_' || ch == '%' || ch == '[' || ch == ']';
  });
}

}  // namespace

void CycloneConfig::validate() const {
  if (interfaces.empty()) throw InvalidInputError("CycloneConfig.interfaces is empty");
  for (std::size_t i = 0; i < interfaces.size(); ++i) {
    if (!NameOrAddress(interfaces[i])) {
      throw InvalidInputError(fmt::format(
          "CycloneConfig.interfaces[{}] '{}' is not an interface name or address", i,
          interfaces[i]));
    }
  }
  for (std::size_t i = 0; i < peers.size(); ++i) {
    const std::string& p = peers[i];
    const std::size_t colon = p.rfind(':');
    int port = 0;
    bool ok = colon != std::string::npos && NameOrAddress(p.substr(0, colon));
    if (ok) {
      const char* first = p.data() + colon + 1;
      const char* last = p.data() + p.size();
      const auto [end, error] = std::from_chars(first, last, port);
      ok = first != last && error == std::errc() && end == last && port >= 1 && port <= 65535;
    }
    if (!ok) {
      throw InvalidInputError(fmt::format(
          "CycloneConfig.peers[{}] '{}' is not \"address:port\" (port in [1, 65535])", i, p));
    }
  }
  if (max_participant_index < 0) {
    throw InvalidInputError("CycloneConfig.max_participant_index must be >= 0");
  }
  if (spdp_interval.count() <= 0) {
    throw InvalidInputError("CycloneConfig.spdp_interval must be positive");
  }
  if (lease.count() <= 0) throw InvalidInputError("CycloneConfig.lease must be positive");
}

std::string CycloneConfigXml(const CycloneConfig& c) {
  c.validate();
  std::string xml = "<CycloneDDS><Domain id=\"any\"><General><Interfaces>";
  for (const std::string& i : c.interfaces) xml += "<NetworkInterface name=\"" + i + "\"/>";
  xml += "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>";
  xml += "<ParticipantIndex>auto</ParticipantIndex>";
  xml += fmt::format("<MaxAutoParticipantIndex>{}</MaxAutoParticipantIndex>",
                     c.max_participant_index);
  xml += fmt::format("<SPDPInterval>{}ms</SPDPInterval>", c.spdp_interval.count());
  xml += fmt::format("<LeaseDuration>{}ms</LeaseDuration>", c.lease.count());
  xml += "<Peers>";
  for (const std::string& p : c.peers) xml += "<Peer address=\"" + p + "\"/>";
  xml += "</Peers></Discovery></Domain></CycloneDDS>";
  return xml;
}

std::string LoopbackConfigXml(int domain, int participants, int spare) {
  CycloneConfig c;
  c.max_participant_index = participants + spare - 1;
  for (int i = 0; i < participants + spare; ++i) {
    c.peers.push_back(fmt::format("127.0.0.1:{}", DiscoveryPort(domain, i)));
  }
  return CycloneConfigXml(c);
}

using namespace transport_detail;  // the samples and their conversions (dds_wire.h)

class DdsTransport::Impl {
 public:
  Impl(int robot, const DdsTransportOptions& options)
      : robot_(robot),
        options_(options),
        participant_(options.domain),
        writer_qos_(dds::Qos::Reliable(kTransportHistoryDepth, options.liveliness_lease)),
        reader_qos_(dds::Qos::ReliableKeepAll(options.liveliness_lease)),
        status_topic_(participant_, moslam_msg_dds__Status__desc, StatusTopicName(), writer_qos_),
        coarse_topic_(participant_, moslam_msg_dds__DgsCoarse__desc, CoarseTopicName(),
                      writer_qos_),
        objects_topic_(participant_, moslam_msg_dds__ObjectList__desc, ObjectsTopicName(),
                       writer_qos_),
        inbox_topic_(participant_, moslam_msg_dds__DgsEstimates__desc, EstimatesTopicName(robot),
                     writer_qos_),
        shared_topic_(participant_, moslam_msg_dds__SharedObjects__desc,
                      SharedObjectsTopicName(robot), writer_qos_),
        weights_topic_(participant_, moslam_msg_dds__DgsWeights__desc, WeightsTopicName(robot),
                       writer_qos_),
        covariance_topic_(participant_, moslam_msg_dds__DgsCovariance__desc,
                          CovarianceTopicName(robot), writer_qos_),
        status_writer_(participant_, status_topic_, writer_qos_),
        coarse_writer_(participant_, coarse_topic_, writer_qos_),
        objects_writer_(participant_, objects_topic_, writer_qos_),
        status_reader_(participant_, status_topic_, reader_qos_),
        coarse_reader_(participant_, coarse_topic_, reader_qos_),
        objects_reader_(participant_, objects_topic_, reader_qos_),
        inbox_reader_(participant_, inbox_topic_, reader_qos_),
        shared_reader_(participant_, shared_topic_, reader_qos_),
        weights_reader_(participant_, weights_topic_, reader_qos_),
        covariance_reader_(participant_, covariance_topic_, reader_qos_),
        waitset_(participant_) {
    if (!options_.transport.log) options_.transport.log = StderrLog(robot_);
    waitset_.attach(status_reader_);
    waitset_.attach(coarse_reader_);
    waitset_.attach(objects_reader_);
    waitset_.attach(inbox_reader_);
    waitset_.attach(shared_reader_);
    waitset_.attach(weights_reader_);
    waitset_.attach(covariance_reader_);
  }

  void send(const EstimatesPacket& p) {
    const std::string why = CheckPacket(p, robot_, p.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    std::vector<std::uint64_t> keys;
    keys.reserve(p.message.keys.size());
    for (const Key& k : p.message.keys) keys.push_back(WireKey(k));
    EstimatesSample s{};
    s.sender = static_cast<std::uint16_t>(robot_);
    s.receiver = static_cast<std::uint16_t>(p.receiver);
    s.solve = p.solve;
    s.stage = static_cast<std::uint8_t>(p.message.stage);
    s.round = p.round;
    s.iteration = p.message.iteration;
    s.initialised = p.message.initialised;
    Lend(keys, s.keys);
    s.values = {static_cast<std::uint32_t>(p.message.values.size()),
                static_cast<std::uint32_t>(p.message.values.size()),
                const_cast<double*>(p.message.values.data()), false};
    std::lock_guard<std::mutex> lock(mutex_);
    outbox(estimate_writers_, moslam_msg_dds__DgsEstimates__desc, EstimatesTopicName(p.receiver),
           p.receiver)
        .write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__DgsEstimates__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.estimates_sent;
    stats_.estimates_bytes += bytes;
  }

  void send(const SharedObjectsPacket& p) {
    const std::string why = CheckPacket(p, robot_, p.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    const auto samples = [](const std::vector<std::pair<std::uint64_t, std::uint64_t>>& list) {
      std::vector<PairSample> out(list.size());
      for (std::size_t i = 0; i < list.size(); ++i) {
        out[i].alpha = list[i].first;
        out[i].beta = list[i].second;
      }
      return out;
    };
    const std::vector<PairSample> pairs = samples(p.pairs), removed = samples(p.removed);
    SharedSample s{};
    s.sender = static_cast<std::uint16_t>(robot_);
    s.receiver = static_cast<std::uint16_t>(p.receiver);
    s.step = p.step;
    Lend(pairs, s.pairs);
    Lend(removed, s.removed);
    std::lock_guard<std::mutex> lock(mutex_);
    outbox(shared_writers_, moslam_msg_dds__SharedObjects__desc, SharedObjectsTopicName(p.receiver),
           p.receiver)
        .write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__SharedObjects__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.objects_sent;
    stats_.objects_bytes += bytes;
  }

  void send(const WeightsPacket& p) {
    const std::string why = CheckPacket(p, robot_, p.message.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    WeightsSample s{};
    s.sender = static_cast<std::uint16_t>(robot_);
    s.receiver = static_cast<std::uint16_t>(p.message.receiver);
    s.solve = p.solve;
    s.round = p.round;
    s.gnc_round = p.message.round;
    Lend(p.message.weights, s.weights);
    std::lock_guard<std::mutex> lock(mutex_);
    outbox(weight_writers_, moslam_msg_dds__DgsWeights__desc,
           WeightsTopicName(p.message.receiver), p.message.receiver)
        .write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__DgsWeights__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.weights_sent;
    stats_.weights_bytes += bytes;
  }

  void send(const CovariancePacket& p) {
    const std::string why = CheckPacket(p, robot_, p.message.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    const Eigen::MatrixXd& c = p.message.covariance;
    std::vector<double> upper;
    upper.reserve(static_cast<std::size_t>(c.rows() * (c.rows() + 1) / 2));
    for (Eigen::Index i = 0; i < c.rows(); ++i) {
      for (Eigen::Index j = i; j < c.rows(); ++j) upper.push_back(c(i, j));
    }
    CovarianceSample s{};
    s.sender = static_cast<std::uint16_t>(robot_);
    s.receiver = static_cast<std::uint16_t>(p.message.receiver);
    s.solve = p.solve;
    s.round = p.round;
    s.dimension = static_cast<std::uint32_t>(c.rows());
    Lend(upper, s.upper);
    std::lock_guard<std::mutex> lock(mutex_);
    outbox(covariance_writers_, moslam_msg_dds__DgsCovariance__desc,
           CovarianceTopicName(p.message.receiver), p.message.receiver)
        .write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__DgsCovariance__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.covariances_sent;
    stats_.covariances_bytes += bytes;
  }

  void publish(const StatusPacket& p) {
    const std::string why = CheckPacket(p, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    std::vector<std::uint16_t> neighbours(p.neighbours.begin(), p.neighbours.end());
    StatusSample s{};
    s.robot = static_cast<std::uint16_t>(robot_);
    s.solve = p.solve;
    s.incarnation = p.incarnation;
    s.state = static_cast<std::uint8_t>(p.state);
    s.stage = p.stage;
    s.round = p.round;
    s.iteration = p.iteration;
    s.sent = p.sent;
    s.initialised = p.initialised;
    s.done = p.done;
    s.change = p.change;
    s.error_bound = p.error_bound;
    s.coarse_ready = p.coarse_ready;
    s.coarse = p.coarse;
    s.weights = p.weights;
    s.covariance = p.covariance;
    s.values[0] = p.value[0];
    s.values[1] = p.value[1];
    Lend(neighbours, s.neighbours);
    std::vector<TeamPairSample> team(p.team.size());
    for (std::size_t i = 0; i < p.team.size(); ++i) {
      const TeamPairEntry& t = p.team[i];
      TeamPairSample& w = team[i];
      w.mine = t.mine;
      w.other = t.other;
      w.other_robot = static_cast<std::uint16_t>(t.other_robot);
      w.mine_is_alpha = t.mine_is_alpha;
      w.held = t.held;
      w.step = t.step;
      PoseToWire(t.pose, w.position, w.orientation);
    }
    Lend(team, s.team);
    std::lock_guard<std::mutex> lock(mutex_);
    status_writer_.write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__Status__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.status_sent;
    stats_.status_bytes += bytes;
  }

  void publish(const CoarsePacket& p) {
    const std::string why = CheckPacket(p, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    const CoarseMessage& m = p.message;
    std::vector<std::uint16_t> robots;
    std::vector<double> blocks;
    for (const auto& [r, block] : m.blocks) {
      robots.push_back(static_cast<std::uint16_t>(r));
      blocks.insert(blocks.end(), block.begin(), block.end());
    }
    std::vector<std::uint32_t> piece_ids, row_pieces, block_pieces;
    std::vector<std::uint16_t> piece_robots;
    std::vector<double> piece_values, piece_blocks;
    for (const CoarsePiece& piece : m.pieces) {
      piece_ids.push_back(piece.id);
      piece_values.insert(piece_values.end(), piece.values.begin(), piece.values.end());
    }
    for (const CoarsePieceBlock& b : m.piece_blocks) {
      row_pieces.push_back(b.row_piece);
      piece_robots.push_back(static_cast<std::uint16_t>(b.robot));
      block_pieces.push_back(b.piece);
      piece_blocks.insert(piece_blocks.end(), b.values.begin(), b.values.end());
    }
    CoarseSample s{};
    s.sender = static_cast<std::uint16_t>(robot_);
    s.solve = p.solve;
    s.round = p.round;
    s.stage = static_cast<std::uint8_t>(m.stage);
    s.kind = static_cast<std::uint8_t>(m.kind);
    s.iteration = m.iteration;
    s.k = static_cast<std::uint8_t>(m.k);
    s.ncols = static_cast<std::uint8_t>(m.ncols);
    Lend(m.center, s.center);
    Lend(m.diagonal, s.diagonal);
    Lend(m.residual, s.residual);
    Lend(robots, s.block_robots);
    Lend(blocks, s.blocks);
    Lend(piece_ids, s.piece_ids);
    Lend(piece_values, s.piece_values);
    Lend(row_pieces, s.block_row_pieces);
    Lend(piece_robots, s.piece_block_robots);
    Lend(block_pieces, s.block_pieces);
    Lend(piece_blocks, s.piece_block_values);
    std::lock_guard<std::mutex> lock(mutex_);
    coarse_writer_.write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__DgsCoarse__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.coarse_sent;
    stats_.coarse_bytes += bytes;
  }

  void publish(const ObjectListPacket& p) {
    const std::string why = CheckPacket(p, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    std::vector<ObjectPoseSample> objects(p.objects.size());
    for (std::size_t i = 0; i < p.objects.size(); ++i) {
      const ObjectObservation& o = p.objects[i];
      ObjectPoseSample& s = objects[i];
      s.id = o.id;
      std::memset(s.label, 0, sizeof s.label);
      std::memcpy(s.label, o.label.data(), o.label.size());
      PoseToWire(o.pose, s.position, s.orientation);
    }
    ObjectListSample s{};
    s.robot = static_cast<std::uint16_t>(robot_);
    s.revision = p.revision;
    s.step = p.step;
    Lend(objects, s.objects);
    std::lock_guard<std::mutex> lock(mutex_);
    objects_writer_.write(&s);
    const std::int64_t bytes = CdrSize(moslam_msg_dds__ObjectList__desc, &s);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    ++stats_.objects_sent;
    stats_.objects_bytes += bytes;
  }

  std::vector<Received> poll(std::chrono::milliseconds timeout) {
    std::lock_guard<std::mutex> lock(poll_mutex_);
    std::vector<Received> out;
    drain(out);
    if (out.empty() && waitset_.wait(timeout)) drain(out);
    return out;
  }

  std::set<int> alive() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::set<int> out;
    for (const auto& [robot, is_alive] : alive_) {
      if (is_alive && robot != robot_) out.insert(robot);
    }
    return out;
  }

  void setKnownRobots(const std::set<int>& robots) {
    std::lock_guard<std::mutex> lock(mutex_);
    known_ = robots;
  }

  TransportStats stats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
  }

  int robot() const { return robot_; }

 private:
  struct Outbox {
    std::unique_ptr<dds::Topic> topic;
    std::unique_ptr<dds::Writer> writer;
  };

  // The writer to robot `receiver`'s inbox topic `name`, created on first use (under mutex_).
  dds::Writer& outbox(std::map<int, Outbox>& writers, const dds_topic_descriptor_t& type,
                      const std::string& name, int receiver) {
    auto it = writers.find(receiver);
    if (it == writers.end()) {
      auto topic = std::make_unique<dds::Topic>(participant_, type, name, writer_qos_);
      auto writer = std::make_unique<dds::Writer>(participant_, *topic, writer_qos_);
      it = writers.emplace(receiver, Outbox{std::move(topic), std::move(writer)}).first;
    }
    return *it->second.writer;
  }

  // Validates and appends; rejected samples are counted and logged.
  void accept(std::vector<Received>& out, int sender, Packet packet, std::int64_t bytes) {
    std::set<int> known;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      known = known_;
    }
    const std::string why = CheckPacket(packet, sender, robot_, known);
    if (!why.empty()) {
      reject(why);
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.received_samples;
    stats_.received_bytes += bytes;
    out.push_back({sender, std::move(packet)});
  }

  void reject(const std::string& why) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++stats_.rejected;
    }
    options_.transport.log("rejected: " + why);
  }

  void drain(std::vector<Received>& out) {
    takeAll<EstimatesSample, &EstimatesSample::sender>(
        inbox_reader_, moslam_msg_dds__DgsEstimates__desc, "DGS estimates", out);
    status_reader_.take(kMaxTake, [&](const void* data, const dds_sample_info_t& info) {
      const auto& s = *static_cast<const StatusSample*>(data);
      noteLiveliness(s.robot, info);  // the key: valid in invalid samples too
      if (info.valid_data) acceptSample(out, s.robot, s, moslam_msg_dds__Status__desc, "status");
    });
    takeAll<CoarseSample, &CoarseSample::sender>(coarse_reader_, moslam_msg_dds__DgsCoarse__desc,
                                                 "coarse share", out);
    takeAll<ObjectListSample, &ObjectListSample::robot>(
        objects_reader_, moslam_msg_dds__ObjectList__desc, "object list", out);
    takeAll<SharedSample, &SharedSample::sender>(
        shared_reader_, moslam_msg_dds__SharedObjects__desc, "shared objects", out);
    takeAll<WeightsSample, &WeightsSample::sender>(
        weights_reader_, moslam_msg_dds__DgsWeights__desc, "weights", out);
    takeAll<CovarianceSample, &CovarianceSample::sender>(
        covariance_reader_, moslam_msg_dds__DgsCovariance__desc, "covariance", out);
  }

  static constexpr int kMaxTake = 1 << 20;  // samples taken from a reader at once

  // Every valid sample `reader` holds, converted (acceptSample); `Sender` is the field naming the
  // robot that wrote it.
  template <class Sample, auto Sender>
  void takeAll(dds::Reader& reader, const dds_topic_descriptor_t& type, const char* what,
               std::vector<Received>& out) {
    reader.take(kMaxTake, [&](const void* data, const dds_sample_info_t& info) {
      if (!info.valid_data) return;
      const auto& s = *static_cast<const Sample*>(data);
      acceptSample(out, s.*Sender, s, type, what);
    });
  }

  // One sample from robot `sender` converted to a packet and accepted, or rejected with what it
  // was and why (a conversion or packet check that failed).
  template <class Sample>
  void acceptSample(std::vector<Received>& out, int sender, const Sample& s,
                    const dds_topic_descriptor_t& type, const char* what) {
    try {
      accept(out, sender, FromSample(s), CdrSize(type, &s));
    } catch (const std::exception& e) {
      reject(fmt::format("{} from robot {}: {}", what, sender, e.what()));
    }
  }

  // A status instance's liveliness: robot `robot` (another one, of the team when it is known) is
  // back when its instance is alive with data, gone when the instance is disposed or has no
  // writer; logged when that changes (and not at a robot's first appearance).
  void noteLiveliness(int robot, const dds_sample_info_t& info) {
    const bool instance_alive = info.instance_state == DDS_IST_ALIVE;
    std::lock_guard<std::mutex> lock(mutex_);
    if (robot == robot_ || (!known_.empty() && known_.count(robot) == 0)) return;
    const auto it = alive_.find(robot);
    const bool was = it != alive_.end() && it->second;
    if (was != instance_alive && (instance_alive ? info.valid_data : true)) {
      alive_[robot] = instance_alive;
      if (it != alive_.end() || !instance_alive) {
        options_.transport.log(
            fmt::format("robot {} {}", robot, instance_alive ? "is back" : "is gone"));
      }
    }
  }

  int robot_;
  DdsTransportOptions options_;
  // Parents first: members are destroyed in reverse order.
  dds::Participant participant_;
  dds::Qos writer_qos_, reader_qos_;
  dds::Topic status_topic_, coarse_topic_, objects_topic_, inbox_topic_, shared_topic_,
      weights_topic_, covariance_topic_;
  dds::Writer status_writer_, coarse_writer_, objects_writer_;
  dds::Reader status_reader_, coarse_reader_, objects_reader_, inbox_reader_, shared_reader_,
      weights_reader_, covariance_reader_;
  dds::WaitSet waitset_;
  std::map<int, Outbox> estimate_writers_, shared_writers_, weight_writers_, covariance_writers_;

  mutable std::mutex mutex_;  // stats, known, alive, writers
  std::mutex poll_mutex_;
  std::set<int> known_;
  std::map<int, bool> alive_;
  TransportStats stats_;
};

DdsTransport::DdsTransport(int robot, const DdsTransportOptions& options) {
  options.validate();
  if (robot < 0 || robot > kMaxTransportRobot) {
    throw InvalidInputError("DDS transport: robot id " + std::to_string(robot) +
                            " out of range [0, 65535]");
  }
  impl_ = std::make_unique<Impl>(robot, options);
}

DdsTransport::~DdsTransport() = default;

int DdsTransport::self() const { return impl_->robot(); }
void DdsTransport::send(const EstimatesPacket& packet) { impl_->send(packet); }
void DdsTransport::send(const SharedObjectsPacket& packet) { impl_->send(packet); }
void DdsTransport::send(const WeightsPacket& packet) { impl_->send(packet); }
void DdsTransport::send(const CovariancePacket& packet) { impl_->send(packet); }
void DdsTransport::publish(const StatusPacket& packet) { impl_->publish(packet); }
void DdsTransport::publish(const ObjectListPacket& packet) { impl_->publish(packet); }
void DdsTransport::publish(const CoarsePacket& packet) { impl_->publish(packet); }
std::vector<Received> DdsTransport::poll(std::chrono::milliseconds timeout) {
  return impl_->poll(timeout);
}
std::set<int> DdsTransport::alive() const { return impl_->alive(); }
void DdsTransport::setKnownRobots(const std::set<int>& robots) { impl_->setKnownRobots(robots); }
TransportStats DdsTransport::stats() const { return impl_->stats(); }

}  // namespace moslam
