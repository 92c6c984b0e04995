#include "moslam/transport/in_process_transport.h"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

namespace {

// History slot of a packet: status, objects and coarse shares per sender; per (sender, receiver):
// estimates (slot = receiver), shared objects (slot = kSharedTopic - 3 receiver), weights
// (slot = kSharedTopic - 3 receiver - 1) and covariances (slot = kSharedTopic - 3 receiver - 2).
constexpr int kStatusTopic = -1;
constexpr int kObjectsTopic = -2;
constexpr int kCoarseTopic = -3;
constexpr int kSharedTopic = -4;
// The robot a history slot is addressed to, or -1 (every robot).
int SlotReceiver(int topic) {
  if (topic >= 0) return topic;
  if (topic <= kSharedTopic) return (kSharedTopic - topic) / 3;
  return -1;
}
int SharedSlot(int receiver) { return kSharedTopic - 3 * receiver; }
int WeightsSlot(int receiver) { return kSharedTopic - 3 * receiver - 1; }
int CovarianceSlot(int receiver) { return kSharedTopic - 3 * receiver - 2; }

struct Delivery {
  int to = 0;
  Received received;
};

}  // namespace

struct InProcessNetwork::State {
  struct Endpoint {
    std::deque<Received> inbox;
  };
  std::mutex mutex;
  std::condition_variable arrived;
  std::map<int, Endpoint> endpoints;                         // connected robots
  std::map<std::pair<int, int>, std::deque<Received>> history;  // (sender, topic) -> last packets
  std::set<std::pair<int, int>> down;                        // links (min, max) that are cut
  std::map<std::pair<int, int>, std::deque<Delivery>> held;  // packets waiting on a cut link

  static std::pair<int, int> link(int a, int b) { return {std::min(a, b), std::max(a, b)}; }
  bool linkUp(int a, int b) const { return down.count(link(a, b)) == 0; }

  // Under the lock.
  void deliver(int to, Received r) {
    if (!linkUp(r.sender, to)) {
      held[link(r.sender, to)].push_back({to, std::move(r)});
      return;
    }
    const auto it = endpoints.find(to);
    if (it == endpoints.end()) return;
    it->second.inbox.push_back(std::move(r));
    arrived.notify_all();
  }
  void remember(int sender, int topic, const Received& r) {
    auto& h = history[{sender, topic}];
    h.push_back(r);
    while (h.size() > static_cast<std::size_t>(kTransportHistoryDepth)) h.pop_front();
  }
};

namespace {

class InProcessTransport final : public Transport {
 public:
  InProcessTransport(std::shared_ptr<InProcessNetwork::State> state, int robot,
                     TransportOptions options)
      : state_(std::move(state)), robot_(robot), options_(std::move(options)) {
    if (!options_.log) options_.log = StderrLog(robot_);
  }
  ~InProcessTransport() override {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->endpoints.erase(robot_);
    // Packets held for the robot on cut links are dropped with it (DDS forgets a reader that
    // leaves); the history stays for a restart.
    for (auto& [link, queue] : state_->held) {
      queue.erase(std::remove_if(queue.begin(), queue.end(),
                                 [&](const Delivery& d) { return d.to == robot_; }),
                  queue.end());
    }
  }

  int self() const override { return robot_; }

  void send(const EstimatesPacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, packet.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    transmit(packet, packet.receiver, packet.receiver);
  }
  void send(const SharedObjectsPacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, packet.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    transmit(packet, SharedSlot(packet.receiver), packet.receiver);
  }
  void send(const WeightsPacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, packet.message.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    transmit(packet, WeightsSlot(packet.message.receiver), packet.message.receiver);
  }
  void send(const CovariancePacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, packet.message.receiver, {});
    if (!why.empty()) throw InvalidInputError("cannot send: " + why);
    transmit(packet, CovarianceSlot(packet.message.receiver), packet.message.receiver);
  }
  void publish(const StatusPacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    transmit(packet, kStatusTopic, -1);
  }
  void publish(const ObjectListPacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    transmit(packet, kObjectsTopic, -1);
  }
  void publish(const CoarsePacket& packet) override {
    const std::string why = CheckPacket(packet, robot_, -1, {});
    if (!why.empty()) throw InvalidInputError("cannot publish: " + why);
    transmit(packet, kCoarseTopic, -1);
  }

  std::vector<Received> poll(std::chrono::milliseconds timeout) override {
    std::deque<Received> raw;
    {
      std::unique_lock<std::mutex> lock(state_->mutex);
      auto& inbox = state_->endpoints.at(robot_).inbox;
      state_->arrived.wait_for(lock, timeout, [&]() { return !inbox.empty(); });
      raw.swap(inbox);
    }
    std::vector<Received> out;
    for (Received& r : raw) {
      const std::string why = CheckPacket(r.packet, r.sender, robot_, known_);
      if (!why.empty()) {
        ++stats_.rejected;
        options_.log("rejected: " + why);
        continue;
      }
      ++stats_.received_samples;
      stats_.received_bytes += BinarySize(r.packet);
      out.push_back(std::move(r));
    }
    return out;
  }

  std::set<int> alive() const override {
    std::lock_guard<std::mutex> lock(state_->mutex);
    std::set<int> out;
    for (const auto& [robot, endpoint] : state_->endpoints) {
      if (robot != robot_ && state_->linkUp(robot, robot_)) out.insert(robot);
    }
    return out;
  }

  void setKnownRobots(const std::set<int>& robots) override { known_ = robots; }
  TransportStats stats() const override { return stats_; }

 private:
  // `to` < 0: every other connected robot.
  void transmit(const Packet& packet, int topic, int to) {
    const std::int64_t bytes = BinarySize(packet);
    std::lock_guard<std::mutex> lock(state_->mutex);
    ++stats_.sent_samples;
    stats_.sent_bytes += bytes;
    if (std::holds_alternative<EstimatesPacket>(packet)) {
      ++stats_.estimates_sent;
      stats_.estimates_bytes += bytes;
    } else if (std::holds_alternative<StatusPacket>(packet)) {
      ++stats_.status_sent;
      stats_.status_bytes += bytes;
    } else if (std::holds_alternative<CoarsePacket>(packet)) {
      ++stats_.coarse_sent;
      stats_.coarse_bytes += bytes;
    } else if (std::holds_alternative<WeightsPacket>(packet)) {
      ++stats_.weights_sent;
      stats_.weights_bytes += bytes;
    } else if (std::holds_alternative<CovariancePacket>(packet)) {
      ++stats_.covariances_sent;
      stats_.covariances_bytes += bytes;
    } else {
      ++stats_.objects_sent;
      stats_.objects_bytes += bytes;
    }
    Received r{robot_, packet};
    state_->remember(robot_, topic, r);
    if (to >= 0) {
      state_->deliver(to, std::move(r));
      return;
    }
    std::vector<int> targets;
    for (const auto& [robot, endpoint] : state_->endpoints) {
      if (robot != robot_) targets.push_back(robot);
    }
    for (int t : targets) state_->deliver(t, r);
  }

  std::shared_ptr<InProcessNetwork::State> state_;
  int robot_;
  TransportOptions options_;
  std::set<int> known_;
  TransportStats stats_;
};

}  // namespace

InProcessNetwork::InProcessNetwork() : state_(std::make_shared<State>()) {}
InProcessNetwork::~InProcessNetwork() = default;

std::unique_ptr<Transport> InProcessNetwork::connect(int robot, TransportOptions options) {
  if (robot < 0 || robot > kMaxTransportRobot) {
    throw InvalidInputError("in-process transport: robot id " + std::to_string(robot) +
                            " out of range [0, 65535]");
  }
  std::lock_guard<std::mutex> lock(state_->mutex);
  if (state_->endpoints.count(robot)) {
    throw InvalidInputError("in-process transport: robot " + std::to_string(robot) +
                            " is already connected");
  }
  state_->endpoints[robot];
  // Late joiner: each sender's recent status and object lists, and the estimates sent to it.
  for (const auto& [slot, packets] : state_->history) {
    const auto [sender, topic] = slot;
    if (sender == robot) continue;
    const int receiver = SlotReceiver(topic);
    if (receiver >= 0 && receiver != robot) continue;
    for (const Received& r : packets) state_->deliver(robot, r);
  }
  return std::make_unique<InProcessTransport>(state_, robot, std::move(options));
}

void InProcessNetwork::setLink(int a, int b, bool up) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const auto key = State::link(a, b);
  if (!up) {
    state_->down.insert(key);
    return;
  }
  state_->down.erase(key);
  std::deque<Delivery> waiting;
  waiting.swap(state_->held[key]);
  for (Delivery& d : waiting) state_->deliver(d.to, std::move(d.received));
}

void InProcessNetwork::inject(int sender, int to, Packet packet) {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const auto it = state_->endpoints.find(to);
  if (it == state_->endpoints.end()) return;
  it->second.inbox.push_back({sender, std::move(packet)});
  state_->arrived.notify_all();
}

}  // namespace moslam
