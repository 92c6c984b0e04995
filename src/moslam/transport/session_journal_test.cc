#include "moslam/transport/session_journal.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"

namespace moslam::transport_detail {
namespace {

class SessionJournalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::ScratchDir();
    run_.robot = 1;
    run_.fingerprint = 0xF00D;
    run_.num_robots = 3;
    run_.num_steps = 50;
    run_.num_events = 10;
    run_.online = true;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path() const { return (dir_ / "rendezvous.bin").string(); }
  // The message of the InvalidInputError opening the journal with `run` throws ("" if none).
  std::string OpenError(const SessionJournalRun& run) const {
    try {
      SessionJournal j(path(), run, dir_.string());
    } catch (const InvalidInputError& e) {
      return e.what();
    }
    return "";
  }

  std::filesystem::path dir_;
  SessionJournalRun run_;
};

TEST_F(SessionJournalTest, AReopenedJournalGivesBackWhatItRecorded) {
  SolveRecord solve;
  solve.step = 7;
  solve.estimate.emplace(Key::Pose(1, 3), SE3(SO3::Exp(Vector3(0.1, 0.2, 0.3)), Vector3(1, 2, 3)));
  {
    SessionJournal j(path(), run_, dir_.string());
    EXPECT_TRUE(j.contents().events.empty());
    j.append(EventRecord{4, {{1, 2}, {3, 5}}, {{0, 0}}});
    j.append(GroupRecord{7, {0, 1}, {}});
    j.append(GroupRecord{7, {1, 2}, {}});  // a second attempt at step 7
    j.append(solve);
    j.append(LeftRecord{2, 9});
  }
  const SessionJournal j(path(), run_, dir_.string());
  const SessionJournalContents& c = j.contents();
  ASSERT_EQ(c.events.count(4), 1u);
  EXPECT_EQ(c.events.at(4).pairs, (ObjectPairs{{1, 2}, {3, 5}}));
  EXPECT_EQ(c.events.at(4).removed, (ObjectPairs{{0, 0}}));
  EXPECT_EQ(c.groups.at(7).robots, (std::vector<int>{1, 2}));  // the last attempt's
  EXPECT_EQ(c.group_records.at(7), 2);
  ASSERT_EQ(c.solves.count(7), 1u);
  EXPECT_EQ(c.solves.at(7).estimate.at(Key::Pose(1, 3)).translation(), Vector3(1, 2, 3));
  ASSERT_EQ(c.left.size(), 1u);
  EXPECT_EQ(c.left[0].robot, 2);
  EXPECT_EQ(c.left[0].step, 9u);
}

TEST_F(SessionJournalTest, AnotherRunsJournalIsRefusedWithTheStateDirectory) {
  { SessionJournal j(path(), run_, dir_.string()); }
  SessionJournalRun other = run_;
  other.fingerprint = 0xBEEF;
  EXPECT_NE(OpenError(other).find("journal of another run"), std::string::npos);
  EXPECT_NE(OpenError(other).find(dir_.string()), std::string::npos);
  other = run_;
  other.robot = 2;
  EXPECT_NE(OpenError(other).find("journal of another run"), std::string::npos);
  EXPECT_EQ(OpenError(run_), "");
}

TEST_F(SessionJournalTest, RecordsOutsideTheRunAreRefused) {
  {
    SessionJournal j(path(), run_, dir_.string());
    j.append(SolveRecord{});  // step 0, with no group record
  }
  EXPECT_NE(OpenError(run_).find("has no group record"), std::string::npos);
  SessionJournalRun batch = run_;
  batch.online = false;
  EXPECT_NE(OpenError(batch).find("a group solve in a batch journal"), std::string::npos);

  std::filesystem::remove(path());
  {
    SessionJournal j(path(), run_, dir_.string());
    j.append(EventRecord{10, {}, {}});  // events 0..9
  }
  EXPECT_NE(OpenError(run_).find("event out of range"), std::string::npos);

  std::filesystem::remove(path());
  {
    SessionJournal j(path(), run_, dir_.string());
    j.append(GroupRecord{5, {0, 2}, {}});  // a group without this robot
  }
  EXPECT_NE(OpenError(run_).find("robots not in the team"), std::string::npos);

  std::filesystem::remove(path());
  {
    SessionJournal j(path(), run_, dir_.string());
    j.append(LeftRecord{3, 1});  // robots 0..2
  }
  EXPECT_NE(OpenError(run_).find("not among its partners"), std::string::npos);
}

}  // namespace
}  // namespace moslam::transport_detail
