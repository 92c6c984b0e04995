#include "moslam/transport/group_formation.h"

#include <fmt/core.h>

#include <variant>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {

void GrowClosure(std::set<int>& group, const std::map<int, std::vector<int>>& neighbours,
                 const std::set<int>* range) {
  for (bool grew = true; grew;) {
    grew = false;
    for (int r : std::vector<int>(group.begin(), group.end())) {
      const auto it = neighbours.find(r);
      if (it == neighbours.end()) continue;
      for (int n : it->second) {
        grew = ((!range || range->count(n)) && group.insert(n).second) || grew;
      }
    }
  }
}

JoiningStatuses ReadJoiningStatuses(const std::vector<Received>& packets, std::uint32_t solve,
                                    const std::set<int>& range) {
  JoiningStatuses out;
  for (const Received& r : packets) {
    const auto* st = std::get_if<StatusPacket>(&r.packet);
    if (st && st->solve == solve && range.count(r.sender)) {
      out.neighbours.try_emplace(r.sender, st->neighbours);
      out.team.try_emplace(r.sender, st->team);
    }
  }
  return out;
}

std::vector<TeamPair> GroupHeldPairs(const std::vector<int>& members,
                                     const std::map<int, std::vector<TeamPairEntry>>& team) {
  const std::set<int> in_group(members.begin(), members.end());
  std::vector<TeamPair> held;
  for (int r : members) {
    const auto it = team.find(r);
    if (it == team.end()) {
      throw InvalidInputError(fmt::format("group of a solve: no joining status of member {}", r));
    }
    for (const TeamPairEntry& e : it->second) {
      if (in_group.count(e.other_robot)) continue;  // solved together, not held
      held.push_back({Key::Object(r, e.mine), Key::Object(e.other_robot, e.other), e.mine_is_alpha,
                      e.held, HeldEstimate{e.pose, static_cast<int>(e.step)}});
    }
  }
  return held;
}

}  // namespace moslam::transport_detail
