// How the robots of a solve form its group from their joining statuses (robot_session.h: the
// online group solves, and the closure of the batch solve). Each robot publishes a StatusPacket
// of the solve listing its partners (`neighbours`) and its pairs with other robots (`team`); the
// group is the closure of those lists within the robots in range, and every member forms the same
// group from the same statuses. The closure rule is the DgsNode's too (dgs_node.h, a team that
// forms without a given team). Internal to the transport module.
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <vector>

#include "moslam/online/group_solve.h"
#include "moslam/transport/transport.h"

namespace moslam::transport_detail {

// `group` grown by the neighbour lists of its members that were heard (`neighbours`: each
// robot's list), until nothing changes; with `range`, only by robots in it.
void GrowClosure(std::set<int>& group, const std::map<int, std::vector<int>>& neighbours,
                 const std::set<int>* range = nullptr);

struct JoiningStatuses {
  std::map<int, std::vector<int>> neighbours;      // each sender's partners
  std::map<int, std::vector<TeamPairEntry>> team;  // each sender's pairs with other robots
};
// The joining statuses of `solve` among `packets` from the robots in `range`: a sender's first
// status of the solve (packets in arrival order), the one it joined with; its later ones are its
// DgsNode's, whose neighbours are those of the group that formed (without the robots that left).
JoiningStatuses ReadJoiningStatuses(const std::vector<Received>& packets, std::uint32_t solve,
                                    const std::set<int>& range);

// The pairs of the group's `members` with robots outside it, from the members' statuses
// (`team`, each member's own included), member by member in the order given: the held factors of
// its solve. The pairs among members are solved together, not held. Throws InvalidInputError when
// a member has no status.
std::vector<TeamPair> GroupHeldPairs(const std::vector<int>& members,
                                     const std::map<int, std::vector<TeamPairEntry>>& team);

}  // namespace moslam::transport_detail
