// The fingerprint of a robot session's run (robot_session.h), kept in the header of its journal
// (session_journal.h): everything the answers, groups and online solves it journals depend on,
// so that a restarted session refuses the journal of another run instead of mixing two. That is
// the robot's data (measurements, initial poses when known, the events), its SLAM and rendezvous
// configuration and, online, the solver and the robust solve's options. Not in it: what only
// decides how long to wait (timeouts), where to write, and how to report. Internal to the
// transport module.
#pragma once

#include <cstdint>

#include "moslam/transport/robot_session.h"

namespace moslam::transport_detail {

std::uint64_t SessionFingerprint(const RobotScenarioData& data, const RobotSessionOptions& options);

}  // namespace moslam::transport_detail
