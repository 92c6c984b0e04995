// Tests of robot sessions (robot_session_test.cc, online_session_test.cc): who takes part when,
// to pick the robot a fault test kills and the partner that finds it gone.
#pragma once

#include <algorithm>
#include <map>
#include <vector>

#include "moslam/online/online_team.h"
#include "moslam/sim/sensing.h"

namespace moslam {

// Robot -> the steps of its rendezvous events, in order.
inline std::map<int, std::vector<int>> EventStepsOf(const SimulationData& data) {
  std::map<int, std::vector<int>> steps_of;
  for (const RendezvousEvent& e : data.rendezvous) {
    for (int r : {e.alpha, e.beta}) steps_of[r].push_back(e.step);
  }
  return steps_of;
}

// Robot -> the steps of its group solves in an online run, in order.
inline std::map<int, std::vector<int>> SolveStepsOf(const OnlineRun& run) {
  std::map<int, std::vector<int>> steps_of;
  for (const GroupSolveRecord& s : run.solves) {
    for (int r : s.robots) steps_of[r].push_back(s.step);
  }
  return steps_of;
}

// The robot with the most steps (the lowest of a tie); -1 when there is none.
inline int Busiest(const std::map<int, std::vector<int>>& steps_of) {
  const auto it = std::max_element(steps_of.begin(), steps_of.end(), [](const auto& a,
                                   const auto& b) { return a.second.size() < b.second.size(); });
  return it == steps_of.end() ? -1 : it->first;
}

// The partner of `robot`'s first rendezvous after `step` (the first to wait for it when it died
// then); -1 when it has none.
inline int FirstPartnerAfter(const SimulationData& data, int robot, int step) {
  for (const RendezvousEvent& e : data.rendezvous) {
    if (e.step > step && (e.alpha == robot || e.beta == robot)) {
      return e.alpha == robot ? e.beta : e.alpha;
    }
  }
  return -1;
}

}  // namespace moslam
