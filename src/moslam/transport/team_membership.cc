#include "moslam/transport/team_membership.h"

#include <fmt/core.h>

#include <algorithm>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

TeamMembership::TeamMembership(int self, int num_robots, Transport& transport, Options options)
    : self_(self), num_robots_(num_robots), transport_(transport), options_(std::move(options)) {
  if (self_ < 0 || self_ >= num_robots_) {
    throw InvalidInputError(fmt::format("team membership: robot {} of a team of {}", self_,
                                        num_robots_));
  }
  if (transport_.self() != self_) {
    throw InvalidInputError(fmt::format("team membership: robot {} given the transport of robot {}",
                                        self_, transport_.self()));
  }
  if (options_.leave_timeout.count() <= 0) {
    throw InvalidInputError("team membership: leave_timeout must be positive");
  }
  if (!options_.journal) options_.journal = [](int, int) {};
  if (!options_.log) options_.log = [](const std::string&) {};
}

void TeamMembership::restore(int robot, int step) {
  if (robot < 0 || robot >= num_robots_) {
    throw InvalidInputError(fmt::format("team membership: a departure of robot {}, not of the team "
                                        "of {}",
                                        robot, num_robots_));
  }
  if (robot == self_) {
    leaveTheTeam(step);
  } else {
    left_.emplace(robot, step);
  }
}

void TeamMembership::publishPresence() {
  StatusPacket presence;
  presence.robot = self_;
  presence.solve = kPresenceSolve;
  if (out_) {
    presence.state = RobotState::kFailed;
  } else {
    for (const auto& [r, step] : left_) presence.neighbours.push_back(r);
  }
  transport_.publish(presence);
}

void TeamMembership::onPacket(const Received& r) {
  // A packet proves its sender was alive, even one that is gone by the time this robot looks at
  // the liveliness (its presence status is there for that).
  seen_alive_.insert(r.sender);
  const auto* st = std::get_if<StatusPacket>(&r.packet);
  if (!st || st->solve != kPresenceSolve || r.sender == self_) return;
  const auto known = presence_.find(r.sender);
  const bool news = known == presence_.end() || known->second.neighbours != st->neighbours ||
                    known->second.state != st->state;
  presence_[r.sender] = *st;
  // A robot found gone that is back: it learns from this robot's presence, sent again, that the
  // team went on without it.
  if (news && st->state != RobotState::kFailed && left_.count(r.sender) > 0) publishPresence();
}

std::set<int> TeamMembership::noteAlive() {
  std::set<int> alive = transport_.alive();
  seen_alive_.insert(alive.begin(), alive.end());
  return alive;
}

bool TeamMembership::hasLeft(int robot, int step) const {
  const auto it = left_.find(robot);
  return it != left_.end() && it->second <= step;
}

bool TeamMembership::foundLeft(int robot, int step,
                               std::map<int, Clock::time_point>& not_alive_since,
                               Clock::time_point now) {
  if (hasLeft(robot, step)) return true;
  if (const auto p = presence_.find(robot); p != presence_.end()) {
    if (p->second.state == RobotState::kFailed) {  // it left the team
      markLeft(robot, step, fmt::format("it left the team, at step {}", step));
      return true;
    }
    if (std::binary_search(p->second.neighbours.begin(), p->second.neighbours.end(), self_)) {
      foundGoneBy(robot, step);
      return true;
    }
  }
  if (noteAlive().count(robot)) {
    not_alive_since.erase(robot);
    return false;
  }
  const auto since = not_alive_since.emplace(robot, now).first->second;
  if (now - since < options_.leave_timeout) return false;
  markLeft(robot, step,
           fmt::format("{} for {} ms at step {}",
                       seen_alive_.count(robot) ? "not alive" : "never heard from, not alive",
                       options_.leave_timeout.count(), step));
  return true;
}

void TeamMembership::markLeft(int robot, int step, const std::string& why) {
  left_[robot] = step;
  options_.journal(robot, step);
  options_.log(fmt::format("robot {} left for good ({}): its rendezvous are skipped and the solves "
                           "go on without it",
                           robot, why));
  publishPresence();
}

void TeamMembership::applyGoneLists(const std::vector<int>& members, int step) {
  for (int m : members) {
    const auto p = presence_.find(m);
    if (m == self_ || p == presence_.end()) continue;
    if (p->second.state == RobotState::kFailed) {
      if (!hasLeft(m, step)) markLeft(m, step, fmt::format("it left the team, at step {}", step));
      continue;
    }
    for (int r : p->second.neighbours) {
      if (r == self_) {
        foundGoneBy(m, step);
        return;
      }
      if (r < num_robots_ && !hasLeft(r, step)) {
        markLeft(r, step, fmt::format("robot {} found it gone, at step {}", m, step));
      }
    }
  }
}

void TeamMembership::foundGoneBy(int by, int step) {
  if (out_) return;
  options_.log(fmt::format("robot {} found this robot gone: it continues alone from step {} (no "
                           "more rendezvous or solves)",
                           by, step));
  options_.journal(self_, step);
  leaveTheTeam(step);
  publishPresence();
}

void TeamMembership::leaveTheTeam(int step) {
  out_ = true;
  out_step_ = step;
  for (int r = 0; r < num_robots_; ++r) {
    if (r != self_) left_.emplace(r, step);
  }
}

}  // namespace moslam
