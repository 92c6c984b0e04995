// One robot's side of the robust program's re-tests of the separator check's rejects (step 5 of
// robust_program.h; RunRobustDgs's, robust_dgs.h): one by one against the joint estimate
// (RobustProgramOptions::retest_left_out), then the robot pairs' groups (retest_groups). Internal
// to the robust program (robust_program.cc); tested through it (robust_program_test.cc, and the
// robot processes' in apps/team_test.cc).
#pragma once

#include <cstdint>

#include "moslam/distributed/robust_robot.h"
#include "moslam/distributed/separator_check_program.h"

namespace moslam {

// After the inliers' solve was kept, with `inlier_cost` its F over the team: R1, the higher
// robot of each pair sends the lower its estimates of its variables, held by inliers, in the
// robust separators the check left out and still rejected; R2, the lower robot's candidates (the
// check's support, both ends held) by r^T Omega r, then subgraph order, and its groups (with
// retest_groups: per neighbour of higher id, increasing, the separators left out of the pair's
// runner-up set with both ends held); then per candidate, team-wide in increasing r^T Omega r
// (ties: the lower robot), a trial, and per group with GroupMinimum or more members still
// rejected, team-wide in increasing (robot, neighbour), a trial of all of them. Every robot of the
// team calls it at the same step, with the same `round` (the weight messages' first round).
// Counts into robot.result(): retests, retest_readmitted, group_retests, group_readmitted.
void RunRetests(RobustRobot& robot, const SeparatorCheckVerdict& check, double inlier_cost,
                std::uint32_t round);

}  // namespace moslam
