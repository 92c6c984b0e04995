// Transport between threads of one process, for unit tests of the protocol (dgs_node.h) without
// a middleware. It keeps the contract of transport.h: reliable in-order delivery per sender, the
// last kTransportHistoryDepth packets per sender and topic delivered to a robot that connects
// late (as DDS transient-local durability), validation of every received packet.
//
//   InProcessNetwork net;
//   auto t0 = net.connect(0), t1 = net.connect(1);   // thread-safe; one endpoint per robot
//   net.setLink(0, 1, false);   // a cut: packets wait, the robots stop seeing each other alive
//   net.setLink(0, 1, true);    // restored: the waiting packets are delivered, in order
//
// Destroying an endpoint disconnects its robot (it leaves: not alive for the others); the same
// robot may connect again (a restart) and then receives the history. Bytes counted: BinarySize().
#pragma once

#include <memory>

#include "moslam/transport/transport.h"

namespace moslam {

class InProcessNetwork {
 public:
  InProcessNetwork();
  ~InProcessNetwork();
  InProcessNetwork(const InProcessNetwork&) = delete;
  InProcessNetwork& operator=(const InProcessNetwork&) = delete;

  // Throws InvalidInputError when `robot` is out of range or already connected. The endpoint
  // may outlive the network (it then neither sends nor receives).
  std::unique_ptr<Transport> connect(int robot, TransportOptions options = {});
  // Link state between robots a and b (up by default).
  void setLink(int a, int b, bool up);
  // Delivers `packet` to robot `to` as if `sender` had sent it, without any check (tests of the
  // receiver's validation). Dropped when `to` is not connected.
  void inject(int sender, int to, Packet packet);

  struct State;

 private:
  std::shared_ptr<State> state_;
};

}  // namespace moslam
