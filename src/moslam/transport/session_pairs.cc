#include "moslam/transport/session_pairs.h"

#include <fmt/core.h>

#include <algorithm>

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
