#include "moslam/transport/session_inbox.h"

#include <variant>

namespace moslam::transport_detail {

std::uint32_t SolveOf(const Received& r) {
  if (const auto* e = std::get_if<EstimatesPacket>(&r.packet)) return e->solve;
  if (const auto* s = std::get_if<StatusPacket>(&r.packet)) return s->solve;
  if (const auto* c = std::get_if<CoarsePacket>(&r.packet)) return c->solve;
  if (const auto* w = std::get_if<WeightsPacket>(&r.packet)) return w->solve;
  if (const auto* v = std::get_if<CovariancePacket>(&r.packet)) return v->solve;
  return 0;
}

void SessionInbox::add(Received r) {
  if (auto* list = std::get_if<ObjectListPacket>(&r.packet)) {
    lists_[{r.sender, list->step}].push_back(std::move(*list));
  } else if (auto* answer = std::get_if<SharedObjectsPacket>(&r.packet)) {
    answers_[{r.sender, answer->step}].push_back(std::move(*answer));
  } else if (const auto* st = std::get_if<StatusPacket>(&r.packet);
             !st || st->solve != kPresenceSolve) {  // presence: the membership's alone
    pending_.push_back(std::move(r));
  }
}

void SessionInbox::dropListsUpTo(std::uint32_t step) {
  for (auto it = lists_.begin(); it != lists_.end();) {
    it = it->first.second <= step ? lists_.erase(it) : std::next(it);
  }
}

std::vector<Received> SessionInbox::takePending() {
  std::vector<Received> all = std::move(pending_);
  pending_.clear();
  return all;
}

std::vector<Received> SessionInbox::takePending(std::uint32_t solve) {
  std::vector<Received> mine, rest;
  for (Received& r : pending_) (SolveOf(r) == solve ? mine : rest).push_back(std::move(r));
  pending_ = std::move(rest);
  return mine;
}

}  // namespace moslam::transport_detail
