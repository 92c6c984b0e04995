// Tests: a robot process that dies at a chosen status it publishes. Wraps a robot's transport;
// when `dies_at` is true for a status about to be published, the status is not sent, `die` is
// called (it throws what the test catches as the process's death) and from then on nothing
// leaves the robot (a dead process publishes no failure status either).
#pragma once

#include <functional>
#include <memory>
#include <set>
#include <utility>
#include <vector>

#include "moslam/transport/transport.h"

namespace moslam {

class DyingTransport final : public Transport {
 public:
  DyingTransport(std::unique_ptr<Transport> inner, std::function<bool(const StatusPacket&)> dies_at,
                 std::function<void()> die)
      : inner_(std::move(inner)), dies_at_(std::move(dies_at)), die_(std::move(die)) {}

  int self() const override { return inner_->self(); }
  void send(const EstimatesPacket& p) override { if (!dead_) inner_->send(p); }
  void send(const SharedObjectsPacket& p) override { if (!dead_) inner_->send(p); }
  void send(const WeightsPacket& p) override { if (!dead_) inner_->send(p); }
  void send(const CovariancePacket& p) override { if (!dead_) inner_->send(p); }
  void publish(const StatusPacket& p) override {
    if (dead_) return;
    if (dies_at_(p)) {
      dead_ = true;
      die_();
    }
    inner_->publish(p);
  }
  void publish(const ObjectListPacket& p) override { if (!dead_) inner_->publish(p); }
  void publish(const CoarsePacket& p) override { if (!dead_) inner_->publish(p); }
  std::vector<Received> poll(std::chrono::milliseconds timeout) override {
    return inner_->poll(timeout);
  }
  std::set<int> alive() const override { return inner_->alive(); }
  void setKnownRobots(const std::set<int>& robots) override { inner_->setKnownRobots(robots); }
  TransportStats stats() const override { return inner_->stats(); }

 private:
  std::unique_ptr<Transport> inner_;
  std::function<bool(const StatusPacket&)> dies_at_;
  std::function<void()> die_;
  bool dead_ = false;
};

}  // namespace moslam
