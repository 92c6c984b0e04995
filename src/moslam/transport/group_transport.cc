#include "moslam/transport/group_transport.h"

#include <algorithm>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

GroupTransport::GroupTransport(Transport& inner, std::vector<int> robots, std::uint32_t solve,
                               std::function<void(Received)> elsewhere,
                               std::vector<Received> pending)
    : inner_(inner),
      robots_(std::move(robots)),
      solve_(solve),
      elsewhere_(std::move(elsewhere)),
      pending_(std::move(pending)) {
  if (robots_.empty() || std::adjacent_find(robots_.begin(), robots_.end(),
                                            std::greater_equal<int>()) != robots_.end()) {
    throw InvalidInputError("GroupTransport: the group's robots must be distinct and increasing");
  }
  self_ = local(inner_.self());
  if (self_ < 0) {
    throw InvalidInputError("GroupTransport: robot " + std::to_string(inner_.self()) +
                            " is not in the group");
  }
  if (!elsewhere_) throw InvalidInputError("GroupTransport: no inbox for the other packets");
}

int GroupTransport::real(int local) const {
  if (local < 0 || local >= static_cast<int>(robots_.size())) {
    throw InvalidInputError("GroupTransport: robot " + std::to_string(local) +
                            " of the solve is not in the group of " +
                            std::to_string(robots_.size()));
  }
  return robots_[static_cast<std::size_t>(local)];
}

int GroupTransport::local(int real) const {
  const auto it = std::lower_bound(robots_.begin(), robots_.end(), real);
  return it != robots_.end() && *it == real ? static_cast<int>(it - robots_.begin()) : -1;
}

void GroupTransport::send(const EstimatesPacket& packet) {
  EstimatesPacket p = packet;
  p.solve = solve_;
  p.receiver = real(p.receiver);
  p.message.sender = real(p.message.sender);
  for (Key& k : p.message.keys) k.robot = real(k.robot);
  inner_.send(p);
}

template <typename Packet>
void GroupTransport::sendAddressed(Packet p) {
  p.solve = solve_;
  p.message.sender = real(p.message.sender);
  p.message.receiver = real(p.message.receiver);
  inner_.send(p);
}

void GroupTransport::send(const WeightsPacket& packet) { sendAddressed(packet); }

void GroupTransport::send(const CovariancePacket& packet) { sendAddressed(packet); }

void GroupTransport::send(const SharedObjectsPacket&) {
  throw InvalidInputError("GroupTransport: shared objects are not part of a group solve");
}

void GroupTransport::publish(const ObjectListPacket&) {
  throw InvalidInputError("GroupTransport: object lists are not part of a group solve");
}

void GroupTransport::publish(const StatusPacket& packet) {
  StatusPacket p = packet;
  p.solve = solve_;
  p.robot = real(p.robot);
  for (int& n : p.neighbours) n = real(n);
  inner_.publish(p);
}

void GroupTransport::publish(const CoarsePacket& packet) {
  CoarsePacket p = packet;
  p.solve = solve_;
  p.message.sender = real(p.message.sender);
  for (auto& [r, block] : p.message.blocks) r = real(r);
  inner_.publish(p);
}

GroupTransport::Route GroupTransport::route(Received& r) {
  const auto of_solve = [&](std::uint32_t solve) {
    const int sender = local(r.sender);
    return solve == solve_ && sender >= 0 && (known_.empty() || known_.count(sender) > 0);
  };
  const auto mapped = [&](int real_id, int& out) {
    out = local(real_id);
    return out >= 0;
  };
  bool ok = true;
  if (auto* e = std::get_if<EstimatesPacket>(&r.packet)) {
    if (!of_solve(e->solve)) return Route::kElsewhere;
    ok = mapped(e->receiver, e->receiver) && mapped(e->message.sender, e->message.sender);
    for (Key& k : e->message.keys) ok = ok && mapped(k.robot, k.robot);
  } else if (auto* s = std::get_if<StatusPacket>(&r.packet)) {
    if (!of_solve(s->solve)) return Route::kElsewhere;
    ok = mapped(s->robot, s->robot);
    for (int& n : s->neighbours) ok = ok && mapped(n, n);
  } else if (auto* c = std::get_if<CoarsePacket>(&r.packet)) {
    if (!of_solve(c->solve)) return Route::kElsewhere;
    ok = mapped(c->message.sender, c->message.sender);
    for (auto& [robot, block] : c->message.blocks) ok = ok && mapped(robot, robot);
  } else if (auto* w = std::get_if<WeightsPacket>(&r.packet)) {
    if (!of_solve(w->solve)) return Route::kElsewhere;
    ok = mapped(w->message.sender, w->message.sender) &&
         mapped(w->message.receiver, w->message.receiver);
  } else if (auto* v = std::get_if<CovariancePacket>(&r.packet)) {
    if (!of_solve(v->solve)) return Route::kElsewhere;
    ok = mapped(v->message.sender, v->message.sender) &&
         mapped(v->message.receiver, v->message.receiver);
  } else {
    return Route::kElsewhere;  // rendezvous packets
  }
  if (!ok) {
    ++rejected_;
    return Route::kRejected;
  }
  r.sender = local(r.sender);
  return Route::kMapped;
}

std::vector<Received> GroupTransport::poll(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::vector<Received> in = std::move(pending_);
  pending_.clear();
  bool polled = false;
  while (true) {
    std::vector<Received> out;
    for (Received& r : in) {
      Received original = r;
      switch (route(r)) {
        case Route::kMapped:
          out.push_back(std::move(r));
          break;
        case Route::kElsewhere:
          elsewhere_(std::move(original));
          break;
        case Route::kRejected:
          break;
      }
    }
    if (!out.empty()) return out;
    const auto now = std::chrono::steady_clock::now();
    if (polled && now >= deadline) return out;
    in = inner_.poll(std::chrono::duration_cast<std::chrono::milliseconds>(
        std::max(deadline - now, std::chrono::steady_clock::duration::zero())));
    polled = true;
    if (in.empty()) return out;
  }
}

std::set<int> GroupTransport::alive() const {
  std::set<int> out;
  for (int r : inner_.alive()) {
    const int l = local(r);
    if (l >= 0) out.insert(l);
  }
  return out;
}

void GroupTransport::setKnownRobots(const std::set<int>& robots) {
  for (int r : robots) (void)real(r);
  known_ = robots;
}

}  // namespace moslam
