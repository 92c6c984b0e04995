// Which robots a robot session still counts on, and whether the team still counts on it: the
// rules of robot_session.h (Leaving for good) in one place, over the robot's Transport.
//
//   - A robot waited for (at a rendezvous, for a joining status) that is not alive for
//     leave_timeout has left for good, seen alive before or never (one that died before this
//     robot's transport heard from it cannot be told from one that never started).
//   - Every departure found is journaled (Options::journal) and listed in this robot's presence
//     status (a StatusPacket of kPresenceSolve: its liveliness before any solve; `neighbours`:
//     the robots it found gone), which it sends again at every departure and in answer to the
//     presence status of a robot it found gone (once per news of that robot: two robots gone for
//     each other do not answer each other forever).
//   - A robot that reads its own id in another's list has been found gone by the team (it is back
//     after leave_timeout): it leaves the team (journaled as its own departure), every other
//     robot is gone for it, and its presence status says so (state kFailed); a robot whose
//     presence status says so is gone at once for whoever waits for it.
//   - A group that forms applies every member's list (ApplyGoneLists): gone for one member, gone
//     for all of them, so that all form the same group.
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "moslam/transport/transport.h"

namespace moslam {

class TeamMembership {
 public:
  using Clock = std::chrono::steady_clock;
  struct Options {
    std::chrono::milliseconds leave_timeout{15000};
    // Every departure found: (robot, step); robot == self when this robot left the team.
    std::function<void(int robot, int step)> journal;
    std::function<void(const std::string&)> log;  // default: nothing
  };

  // Throws InvalidInputError when `self` is not one of `num_robots` or the transport is another
  // robot's.
  TeamMembership(int self, int num_robots, Transport& transport, Options options);

  // A departure read back from the journal (robot == self: it had left the team); nothing sent.
  void restore(int robot, int step);
  // Its presence status, as it stands.
  void publishPresence();
  // Every received packet: its sender was alive; presence statuses are read (and answered).
  void onPacket(const Received& packet);
  // The robots alive now (remembered as seen alive).
  std::set<int> noteAlive();

  bool hasLeft(int robot, int step) const;
  bool out() const { return out_; }  // the team found this robot gone: it continues alone
  int outStep() const { return out_step_; }  // the step it left the team at (-1: it did not)
  // While `robot` is waited for at `step`: whether it has left for good, by the rules above.
  // `not_alive_since` keeps, per robot waited for, when it was first seen not alive.
  bool foundLeft(int robot, int step, std::map<int, Clock::time_point>& not_alive_since,
                 Clock::time_point now = Clock::now());
  // `robot` is gone for good from `step` on: journaled, logged with `why`, listed.
  void markLeft(int robot, int step, const std::string& why);
  // The members of a group forming at `step` (their presence statuses precede their joining
  // statuses): the robots any of them lists are gone for this robot too; when one lists this
  // robot, it leaves the team.
  void applyGoneLists(const std::vector<int>& members, int step);

 private:
  void leaveTheTeam(int step);
  void foundGoneBy(int by, int step);

  int self_;
  int num_robots_;
  Transport& transport_;
  Options options_;
  std::map<int, int> left_;               // robots found gone for good -> the step
  std::map<int, StatusPacket> presence_;  // the latest presence status of each robot
  std::set<int> seen_alive_;
  bool out_ = false;
  int out_step_ = -1;
};

}  // namespace moslam
