// One robot's side of the robust program's separator check (C1-C4 of robust_program.h) over the
// team channel: its map's estimates and covariances to its lower neighbours, the largest
// consistent set of each pair it checks (it checks the pairs with its higher neighbours), the
// flood of the lowest robot linked through confirmed pairs, and the final verdicts. Internal to
// the robust program (robust_program.cc); tested through it (robust_program_test.cc).
#pragma once

#include <cstddef>
#include <map>
#include <set>
#include <vector>

#include "moslam/distributed/program_link.h"
#include "moslam/distributed/robust_program.h"

namespace moslam {

struct SeparatorCheckVerdict {
  std::vector<bool> kept;              // per factor of the subgraph: false if left out
  std::map<std::size_t, int> support;  // per separator it checked: the check's support
  std::set<std::size_t> runner_up;     // the separators it checked in their pair's runner-up set
  double rejected_by_team = 0.0;       // separators the check left out, over the team
  // The separators to higher robots it left out (RobustProgramResult::check_rejected), and of
  // those, the ones of pairs too small to confirm themselves kept for GNC (check_deferred).
  int rejected = 0;
  int deferred = 0;
};

// `pairs`: per neighbour, the indices of the checked separators with it (every neighbour has an
// entry); `consistency` with its threshold resolved. Every robot of the team calls it at the same
// step of the program.
SeparatorCheckVerdict RunSeparatorCheck(const RobustRobotProblem& problem,
                                        const std::map<int, std::vector<std::size_t>>& pairs,
                                        const SeparatorConsistencyOptions& consistency,
                                        const GncOptions& gnc, ProgramLink& link);

}  // namespace moslam
