// The Transport of transport.h on Cyclone DDS (C API, wrapped in dds_entities.h), one
// participant per robot process. Topics (ROS 2 naming, types from idl/*.idl):
//   rt/moslam/status                    moslam/msg/Status       keyed by robot, every robot
//   rt/moslam/dgs_coarse                moslam/msg/DgsCoarse    every robot (coarse shares)
//   rt/moslam/objects                   moslam/msg/ObjectList   every robot
//   rt/moslam/robot<R>/dgs_estimates    moslam/msg/DgsEstimates robot R's inbox: only R reads it,
//                                                               so estimates go only to R
//   rt/moslam/robot<R>/shared_objects   moslam/msg/SharedObjects robot R's inbox (rendezvous
//                                                               answers to R's object lists)
//   rt/moslam/robot<R>/dgs_weights      moslam/msg/DgsWeights   robot R's inbox (the robust
//                                                               solve's weights)
//   rt/moslam/robot<R>/dgs_covariance   moslam/msg/DgsCovariance robot R's inbox (the
//                                                               separator check's covariances)
// QoS everywhere: reliable, transient-local (writers keep their last kTransportHistoryDepth
// samples and replay them to readers that join late: a restarted robot catches up), readers
// keep all, automatic liveliness with a lease (liveliness_lease). Liveliness is observed on the
// status topic: a robot whose writer is gone (process ended, lease expired after a crash or a
// long cut) has its status instance no longer alive, and leaves alive().
//
// DgsEstimates carries typed fields rather than the binary Message bytes: any DDS or ROS 2 tool
// can decode it, Cyclone validates the framing (sequence lengths, bounds) before the sample
// reaches us. The cost: a key is 8 bytes instead of a 1-9 byte varint and the header is 36
// bytes instead of 16: +18% payload on blocks_world/4robots (274,048 vs 232,704 bytes, README).
//
// The DDS configuration comes from CYCLONEDDS_URI, unless the process created the domain with
// an explicit configuration first (dds::Domain). LoopbackConfigXml() gives the loopback-only,
// unicast, multicast-free configuration of `moslam team` and the tests.
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "moslam/transport/transport.h"

namespace moslam {

struct DdsTransportOptions {
  int domain = 0;  // DDS domain id, 0..232
  std::chrono::milliseconds liveliness_lease{3000};
  TransportOptions transport;
  // Throws InvalidInputError on a domain outside [0, 232] or a non-positive lease.
  void validate() const;
};

class DdsTransport final : public Transport {
 public:
  // Creates the participant, topics, readers and writers. Throws dds::DdsError (a moslam::Error)
  // when Cyclone refuses (bad configuration, no usable interface), InvalidInputError on bad
  // options or robot id.
  DdsTransport(int robot, const DdsTransportOptions& options);
  ~DdsTransport() override;

  int self() const override;
  void send(const EstimatesPacket& packet) override;
  void send(const SharedObjectsPacket& packet) override;
  void send(const WeightsPacket& packet) override;
  void send(const CovariancePacket& packet) override;
  void publish(const StatusPacket& packet) override;
  void publish(const ObjectListPacket& packet) override;
  void publish(const CoarsePacket& packet) override;
  std::vector<Received> poll(std::chrono::milliseconds timeout) override;
  std::set<int> alive() const override;
  void setKnownRobots(const std::set<int>& robots) override;
  TransportStats stats() const override;

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Topic names.
std::string StatusTopicName();
std::string ObjectsTopicName();
std::string EstimatesTopicName(int robot);
std::string SharedObjectsTopicName(int robot);
std::string WeightsTopicName(int robot);
std::string CovarianceTopicName(int robot);

// The unicast discovery port of participant index `index` on `domain` (Cyclone's default port
// mapping: 7400 + 250 domain + 10 + 2 index).
int DiscoveryPort(int domain, int index);

struct CycloneConfig {
  std::vector<std::string> interfaces{"lo"};  // names or addresses, at least one
  std::vector<std::string> peers;  // "address:port" (IPv6: "[address]:port")
  int max_participant_index = 9;
  std::chrono::milliseconds spdp_interval{1000};  // discovery announcements
  std::chrono::milliseconds lease{5000};          // participant lease
  // Throws InvalidInputError naming the first bad field: no interface, an interface or peer
  // address with characters no name or address has (they go into XML as they are), a peer
  // without a port in [1, 65535], a negative participant index, intervals that are not positive.
  void validate() const;
};
// The configuration as Cyclone DDS reads it (validated first).
std::string CycloneConfigXml(const CycloneConfig& config);

// Loopback only, no multicast, participant indices 0..participants-1 (plus `spare` more for
// restarts and test participants), every one of them a unicast peer on 127.0.0.1.
std::string LoopbackConfigXml(int domain, int participants, int spare = 2);

}  // namespace moslam
