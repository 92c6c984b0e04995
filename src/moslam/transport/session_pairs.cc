#include "moslam/transport/session_pairs.h"

#include <fmt/core.h>

#include <algorithm>
#include <set>

#include "moslam/common/errors.h"
#include "moslam/online/online_team.h"

namespace moslam::transport_detail {

std::vector<SharedObject> SessionPairs::apply(const SharedObjectsMessage& answer, int step) {
  std::vector<SharedObject> shared = shared_, aside = set_aside_;
  for (const SharedObject& s : RemovedObjectsOf(answer)) {
    if (!EraseShared(shared, s)) {  // only a journal of another run gets here
      throw InvalidInputError(
          fmt::format("robot {}: the rendezvous of step {} removes a pair "
                      "never shared (journal of another run?)",
                      robot_, step));
    }
    EraseShared(aside, s);  // gone, so no longer set aside either
  }
  const std::vector<SharedObject> added = SharedObjectsOf(answer);
  shared.insert(shared.end(), added.begin(), added.end());
  shared_ = std::move(shared);
  set_aside_ = std::move(aside);
  return added;
}

std::string SessionPairs::checkAnswer(const SharedObjectsPacket& answer,
                                      std::size_t own_landmarks, bool known_initial_poses) const {
  const int beta = answer.sender;
  std::set<std::uint64_t> mine_taken, theirs_taken;
  std::set<std::pair<std::uint64_t, std::uint64_t>> before;  // (this robot's, beta's)
  for (const SharedObject& s : shared_) {
    for (const auto& [own, other] : {std::make_pair(s.alpha_object, s.beta_object),
                                     std::make_pair(s.beta_object, s.alpha_object)}) {
      if (own.robot == robot_ && other.robot == beta) {
        mine_taken.insert(own.index);
        theirs_taken.insert(other.index);
        before.emplace(own.index, other.index);
      }
    }
  }
  for (const auto& [a, b] : answer.pairs) {
    if (a >= own_landmarks) {
      return fmt::format("names object {} of this robot, which has {}", a, own_landmarks);
    }
    if (b > 0xFFFFFFFFu) return fmt::format("object id {} exceeds 32 bits", b);
    if (before.count({a, b}) ||
        (known_initial_poses && (mine_taken.count(a) || theirs_taken.count(b)))) {
      return fmt::format("pair ({}, {}) uses an object already shared between the two", a, b);
    }
  }
  for (const auto& [a, b] : answer.removed) {
    if (!before.count({a, b})) {
      return fmt::format("removes pair ({}, {}), which the two do not share", a, b);
    }
  }
  return {};
}

std::vector<SharedObject> SessionPairs::accepted() const {
  return AcceptedPairs(shared_, set_aside_);
}

std::vector<std::pair<Key, Key>> SessionPairs::setAsideKeys() const {
  std::vector<std::pair<Key, Key>> out;
  for (const SharedObject& s : set_aside_) out.emplace_back(s.alpha_object, s.beta_object);
  return out;
}

void SessionPairs::setAside(const std::vector<std::pair<Key, Key>>& keys, int step) {
  std::vector<SharedObject> aside;
  for (const auto& [alpha, beta] : keys) {
    const auto it = std::find_if(shared_.begin(), shared_.end(), [&](const SharedObject& s) {
      return s.alpha_object == alpha && s.beta_object == beta;
    });
    if (it == shared_.end()) {
      throw InvalidInputError(
          fmt::format("robot {}: the solve of step {} sets aside a pair it "
                      "does not share (journal of another run?)",
                      robot_, step));
    }
    aside.push_back(*it);
  }
  set_aside_ = std::move(aside);
}

}  // namespace moslam::transport_detail
