// A robot session's shared pairs (robot_session.h): every object pair it shares with another
// robot, in the order its rendezvous added them (as RunMultiRobotObjectSlam keeps the team's),
// and, online with robust group solves, those its last solve that judged them set aside
// (online_team.h). Each robot knows its own pairs only. Internal to the transport module.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "moslam/graph/key.h"
#include "moslam/slam/rendezvous.h"
#include "moslam/transport/transport.h"

namespace moslam::transport_detail {

class SessionPairs {
 public:
  explicit SessionPairs(int robot) : robot_(robot) {}

  // What the rendezvous of `step` changed, as `answer` says it: the removed pairs leave first
  // (and are no longer set aside), the new ones are appended. Returns the pairs added. Throws
  // InvalidInputError, naming the step, when a removed pair was never shared (a journal of
  // another run); the pairs are then unchanged.
  std::vector<SharedObject> apply(const SharedObjectsMessage& answer, int step);

  // Why beta's answer to this robot's (alpha's) object list cannot be applied, or empty when it
  // can: a new pair naming a landmark this robot does not have (it has `own_landmarks`) or an id
  // beyond 32 bits, or repeating a pair shared with beta (with known initial poses: using an
  // object already shared between the two, as AnswerObjectMap excludes them); a removed pair
  // that the two do not share. Anything received from the network is checked before apply().
  std::string checkAnswer(const SharedObjectsPacket& answer, std::size_t own_landmarks,
                          bool known_initial_poses) const;

  const std::vector<SharedObject>& shared() const { return shared_; }
  const std::vector<SharedObject>& setAside() const { return set_aside_; }
  // The shared pairs not set aside (AcceptedPairs).
  std::vector<SharedObject> accepted() const;

  // The pairs set aside, as (alpha landmark, beta landmark), in the order they were set aside.
  std::vector<std::pair<Key, Key>> setAsideKeys() const;
  // A solve's verdict (computed now or journaled at `step`): exactly these pairs are set aside.
  // Throws InvalidInputError, naming the step, when one is not shared (a journal of another run);
  // the pairs set aside are then unchanged.
  void setAside(const std::vector<std::pair<Key, Key>>& keys, int step);

 private:
  int robot_;
  std::vector<SharedObject> shared_;
  std::vector<SharedObject> set_aside_;
};

}  // namespace moslam::transport_detail
