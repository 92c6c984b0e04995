#include "moslam/transport/session_channel.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/transport/in_process_transport.h"

namespace moslam::transport_detail {
namespace {

TEST(SessionChannel, AnAttemptIsItsSolvesLaterAttemptAndPresenceIsOfNoSolve) {
  EXPECT_EQ(AttemptSolve(12, 0), 12u);
  EXPECT_NE(AttemptSolve(12, 1), AttemptSolve(13, 0));
  EXPECT_TRUE(SolveBefore(12, 13));
  EXPECT_TRUE(SolveBefore(AttemptSolve(12, 1), 13));  // an earlier step, whatever its attempt
  EXPECT_TRUE(SolveBefore(12, AttemptSolve(12, 1)));  // an earlier attempt of the same step
  EXPECT_FALSE(SolveBefore(AttemptSolve(12, 1), 12));
  EXPECT_FALSE(SolveBefore(13, 13));
  EXPECT_FALSE(SolveBefore(kPresenceSolve, 1));  // presence statuses are of no solve
  EXPECT_EQ(GroupIds(3), (std::vector<int>{0, 1, 2}));
}

SessionChannel::Options Quiet(std::vector<std::string>* log) {
  SessionChannel::Options o;
  o.log = [log](const std::string& line) { log->push_back(line); };
  return o;
}

TEST(SessionChannel, ARestartTakesTheJournaledGroupsAttemptsAndDepartures) {
  const std::filesystem::path dir = test::ScratchDir();
  SessionJournalRun run;
  run.robot = 1;
  run.fingerprint = 7;
  run.num_robots = 3;
  run.num_steps = 20;
  run.num_events = 4;
  run.online = true;
  const std::string path = (dir / "rendezvous.bin").string();
  InProcessNetwork net;
  std::vector<std::string> log;
  {
    auto transport = net.connect(1);
    SessionChannel first(1, 3, *transport, Quiet(&log),
                         std::make_unique<SessionJournal>(path, run, dir.string()));
    EXPECT_EQ(first.journaledAttempt(5), 0);
    first.recordGroup(GroupRecord{5, {0, 1, 2}, {}});
    EXPECT_EQ(first.journaledAttempt(5), 0);  // one group journaled: attempt 0
    first.recordGroup(GroupRecord{5, {0, 1}, {}});  // robot 2 left: attempt 1
    EXPECT_EQ(first.journaledAttempt(5), 1);
    EXPECT_EQ(first.journaledGroup(5, 1), nullptr);  // formed now, not taken from a journal
    first.markLeft(2, 5, "test");
  }
  auto transport = net.connect(1);
  SessionChannel again(1, 3, *transport, Quiet(&log),
                       std::make_unique<SessionJournal>(path, run, dir.string()));
  EXPECT_EQ(again.journaledAttempt(5), 1);
  const GroupRecord* group = again.journaledGroup(5, 1);
  ASSERT_NE(group, nullptr);
  EXPECT_EQ(group->robots, (std::vector<int>{0, 1}));
  EXPECT_EQ(again.journaledGroup(5, 0), nullptr);  // only the last attempt is taken
  EXPECT_EQ(again.journaledGroup(6, 0), nullptr);
  EXPECT_TRUE(again.hasLeft(2, 5));
  EXPECT_FALSE(again.hasLeft(0, 5));
}

TEST(SessionChannel, NeedsALogAndWorksWithoutAJournal) {
  InProcessNetwork net;
  auto transport = net.connect(0);
  EXPECT_THROW(SessionChannel(0, 2, *transport, SessionChannel::Options{}, nullptr),
               InvalidInputError);
  std::vector<std::string> log;
  SessionChannel channel(0, 2, *transport, Quiet(&log), nullptr);
  channel.recordGroup(GroupRecord{3, {0, 1}, {}});  // nothing journaled, the attempt counted
  EXPECT_EQ(channel.journaledAttempt(3), 0);
  EXPECT_TRUE(channel.journaled().groups.empty());
}

}  // namespace
}  // namespace moslam::transport_detail
