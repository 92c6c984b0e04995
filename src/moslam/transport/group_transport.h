// The robots of one group solve (online mapping, online/group_solve.h) seen as robots 0..k-1 of
// one solve, over a robot's transport: what a DgsNode of the group problem (keys re-labelled
// robots[i] -> i) needs to run unchanged between processes whose ids are `robots`.
//
// Outgoing DGS packets are stamped with the solve and mapped to the real ids (robot fields,
// neighbour lists, variable keys, coarse block robots, weights' sender and receiver). Incoming DGS packets of the solve from
// robots of the group are mapped back; everything else (rendezvous packets, DGS packets of other
// solves or from other robots) is handed untouched to `elsewhere`, the owner's inbox, so a robot
// that has moved on to its next rendezvous loses nothing it sent meanwhile.
#pragma once

#include <cstdint>
#include <functional>
#include <set>
#include <vector>

#include "moslam/transport/transport.h"

namespace moslam {

class GroupTransport final : public Transport {
 public:
  // `robots`: increasing real ids, inner.self() among them; `pending`: packets received before
  // (real ids), routed as if polled now. Throws InvalidInputError otherwise.
  GroupTransport(Transport& inner, std::vector<int> robots, std::uint32_t solve,
                 std::function<void(Received)> elsewhere, std::vector<Received> pending = {});

  int self() const override { return self_; }
  void send(const EstimatesPacket& packet) override;
  // Rendezvous packets are not part of a solve: InvalidInputError.
  void send(const SharedObjectsPacket& packet) override;
  void send(const WeightsPacket& packet) override;
  void send(const CovariancePacket& packet) override;
  void publish(const StatusPacket& packet) override;
  void publish(const ObjectListPacket& packet) override;
  void publish(const CoarsePacket& packet) override;
  std::vector<Received> poll(std::chrono::milliseconds timeout) override;
  std::set<int> alive() const override;
  // Group ids; empty: every robot of the group.
  void setKnownRobots(const std::set<int>& robots) override;
  TransportStats stats() const override { return inner_.stats(); }

  // Packets of the solve that could not be mapped (a neighbour or block robot outside the
  // group): dropped.
  std::int64_t rejected() const { return rejected_; }

 private:
  int real(int local) const;
  int local(int real) const;  // -1 outside the group
  // Sends a packet addressed by its message's sender and receiver (weights, covariances) with
  // the team's ids and this solve.
  template <typename Packet>
  void sendAddressed(Packet p);
  enum class Route { kMapped, kElsewhere, kRejected };
  // Maps `r` in place when it is a packet of this solve.
  Route route(Received& r);

  Transport& inner_;
  std::vector<int> robots_;
  std::uint32_t solve_;
  std::function<void(Received)> elsewhere_;
  std::vector<Received> pending_;
  std::set<int> known_;
  int self_ = 0;
  std::int64_t rejected_ = 0;
};

}  // namespace moslam
