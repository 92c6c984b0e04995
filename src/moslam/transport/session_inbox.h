// What a robot session (robot_session.h) has received and not used yet: the object lists and the
// shared-objects answers of rendezvous, by sender and step in arrival order (a restarted sender's
// duplicates are identical), and every other packet of its solves (DGS packets, joining
// statuses) in arrival order. Presence statuses are the membership's alone (team_membership.h)
// and are not kept. Internal to the transport module.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <utility>
#include <vector>

#include "moslam/transport/transport.h"

namespace moslam::transport_detail {

// The solve a packet belongs to (0 for a rendezvous packet).
std::uint32_t SolveOf(const Received& r);

class SessionInbox {
 public:
  void add(Received r);

  // Received lists of `sender` for `step` and answers from `sender` for `step`, oldest first.
  std::deque<ObjectListPacket>& lists(int sender, std::uint32_t step) {
    return lists_[{sender, step}];
  }
  std::deque<SharedObjectsPacket>& answers(int sender, std::uint32_t step) {
    return answers_[{sender, step}];
  }
  // Lists of `step` or earlier are no longer needed.
  void dropListsUpTo(std::uint32_t step);

  // The packets of the solves, in arrival order.
  const std::vector<Received>& pending() const { return pending_; }
  // All of them, taken out (a DgsNode's first poll).
  std::vector<Received> takePending();
  // Those of `solve`, taken out (its GroupTransport's first poll).
  std::vector<Received> takePending(std::uint32_t solve);
  // Drops those of the solves `before` says come before `solve`.
  template <typename Before>
  void dropPendingBefore(std::uint32_t solve, Before before) {
    std::vector<Received> kept;
    for (Received& r : pending_) {
      if (!before(SolveOf(r), solve)) kept.push_back(std::move(r));
    }
    pending_ = std::move(kept);
  }

 private:
  std::map<std::pair<int, std::uint32_t>, std::deque<ObjectListPacket>> lists_;
  std::map<std::pair<int, std::uint32_t>, std::deque<SharedObjectsPacket>> answers_;
  std::vector<Received> pending_;
};

}  // namespace moslam::transport_detail
