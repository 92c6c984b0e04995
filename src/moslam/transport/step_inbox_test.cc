#include "moslam/transport/step_inbox.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {
namespace {

// Robot 1 of solve 7; its separators reach robots 0 and 2, whose poses 0 it uses.
StepInbox MakeInbox() { return StepInbox(1, 7, {0, 2}, {Key::Pose(0, 0), Key::Pose(2, 0)}); }

StatusPacket Status(int robot, std::uint32_t round, std::vector<int> neighbours = {1}) {
  StatusPacket st;
  st.robot = robot;
  st.solve = 7;
  st.state = RobotState::kPose;
  st.stage = static_cast<std::uint8_t>(DgsStage::kPose);
  st.round = round;
  st.neighbours = std::move(neighbours);
  return st;
}

Received From(int sender, Packet packet) { return Received{sender, std::move(packet)}; }

EstimatesPacket Estimates(int sender, std::uint32_t round, const Key& key) {
  EstimatesPacket p;
  p.receiver = 1;
  p.solve = 7;
  p.round = round;
  p.message.stage = DgsStage::kPose;
  p.message.sender = sender;
  p.message.appendPose(key, SE3());
  return p;
}

WeightsPacket Weights(int sender, std::uint32_t round) {
  WeightsPacket w;
  w.solve = 7;
  w.round = round;
  w.message.sender = sender;
  w.message.receiver = 1;
  w.message.weights = {1.0};
  return w;
}

TEST(StepInbox, AStepIsCompleteOnceTheStatusAndThePacketsItAnnouncesArrived) {
  StepInbox inbox = MakeInbox();
  EXPECT_EQ(inbox.missing(0, 1), "status");
  StatusPacket st = Status(0, 1);
  st.sent = true;
  st.weights = true;
  st.coarse = true;
  st.value[0] = 2.5;
  inbox.ingest({From(0, st)});
  EXPECT_EQ(inbox.missing(0, 1), "estimates, coarse share, weights");
  EXPECT_THROW(inbox.collect(1, {0}, TeamReport{}, nullptr), InvalidInputError);
  CoarsePacket c;
  c.solve = 7;
  c.round = 1;
  c.message.sender = 0;
  const IngestNotes notes =
      inbox.ingest({From(0, Estimates(0, 1, Key::Pose(0, 0))), From(0, Weights(0, 1)), From(0, c)});
  EXPECT_EQ(notes.rejected, 0);
  EXPECT_EQ(inbox.missing(0, 1), "");
  TeamReport mine;
  mine.value[0] = 1.0;
  const TeamStep got = inbox.collect(1, {0}, mine, nullptr);
  ASSERT_EQ(got.reports.size(), 2u);
  EXPECT_EQ(got.reports.at(0).value[0], 2.5);
  EXPECT_TRUE(got.reports.at(0).sent);
  EXPECT_EQ(got.reports.at(1).value[0], 1.0);
  ASSERT_EQ(got.estimates.size(), 1u);
  EXPECT_EQ(got.estimates[0].keys, std::vector<Key>{Key::Pose(0, 0)});
  EXPECT_EQ(got.weights.count(0), 1u);
  EXPECT_EQ(got.shares.count(0), 1u);
}

TEST(StepInbox, ARobotThatDoesNotListThisOneSendsItNothingToWaitFor) {
  StepInbox inbox = MakeInbox();
  StatusPacket st = Status(2, 1, /*neighbours=*/{3});
  st.sent = true;
  st.weights = true;
  inbox.ingest({From(2, st)});
  EXPECT_EQ(inbox.missing(2, 1), "");
  // Nor does a neighbour of the subgraph that is not one of the agent at work.
  inbox.setStepNeighbours({0});
  inbox.ingest({From(2, Status(2, 2))});
  StatusPacket sent = Status(2, 3);
  sent.sent = true;
  inbox.ingest({From(2, sent)});
  EXPECT_EQ(inbox.missing(2, 3), "");
  EXPECT_TRUE(inbox.collect(3, {2}, TeamReport{}, nullptr).estimates.empty());
}

TEST(StepInbox, PacketsFromNonNeighboursAndForUnusedVariablesAreTurnedAway) {
  StepInbox inbox = MakeInbox();
  const IngestNotes notes = inbox.ingest({
      From(3, Estimates(3, 1, Key::Pose(3, 0))),  // not a neighbour
      From(0, Estimates(0, 1, Key::Pose(0, 5))),  // a variable robot 1 does not use
      From(3, Weights(3, 1)),                     // weights from a robot not a neighbour
  });
  EXPECT_EQ(notes.rejected, 3);
  ASSERT_EQ(notes.lines.size(), 3u);
  EXPECT_NE(notes.lines[0].find("robot 3, which is not a neighbour"), std::string::npos);
  EXPECT_NE(notes.lines[1].find("a variable this robot does not use"), std::string::npos);
  EXPECT_NE(notes.lines[2].find("weights from robot 3"), std::string::npos);
  StatusPacket st = Status(0, 1);
  st.sent = true;
  inbox.ingest({From(0, st)});
  EXPECT_EQ(inbox.missing(0, 1), "estimates");  // the rejected one was not filed
}

TEST(StepInbox, TheLatestStatusIsTheMostAdvancedAndARestartReplacesAFailure) {
  StepInbox inbox = MakeInbox();
  StatusPacket other_solve = Status(0, 9);
  other_solve.solve = 8;
  inbox.ingest({From(0, other_solve)});
  EXPECT_TRUE(inbox.heard().empty());  // another solve's status is not this one's
  inbox.ingest({From(0, Status(0, 4)), From(0, Status(0, 3))});
  EXPECT_EQ(inbox.latest().at(0).round, 4u);
  EXPECT_TRUE(inbox.stepped(0));
  StatusPacket failed = Status(0, 5);
  failed.state = RobotState::kFailed;
  const IngestNotes notes = inbox.ingest({From(0, failed)});
  EXPECT_TRUE(inbox.failed(0));
  ASSERT_EQ(notes.lines.size(), 1u);
  EXPECT_EQ(notes.lines[0], "robot 0 reports a failure");
  EXPECT_EQ(inbox.missing(0, 5), "status");  // a failure report is not the status of a step
  StatusPacket restarted = Status(0, 1);
  restarted.incarnation = 1;
  inbox.ingest({From(0, restarted)});
  EXPECT_FALSE(inbox.failed(0));
  EXPECT_EQ(inbox.latest().at(0).round, 1u);
  StatusPacket done = Status(0, 6);
  done.incarnation = 1;
  done.state = RobotState::kDone;
  done.done = true;
  inbox.ingest({From(0, done), From(0, [] {
                  StatusPacket later = Status(0, 7);
                  later.incarnation = 1;
                  return later;
                }())});
  EXPECT_TRUE(inbox.done(0));                // done is final within an incarnation
  EXPECT_EQ(inbox.missing(0, 6), "status");  // nor is a done report the status of a step
}

// Every field of a report crosses in the status: each set to a value other than its default.
TEST(StepInbox, AReportSurvivesTheStatusThatCarriesIt) {
  TeamReport r;
  r.sent = r.initialised = r.coarse_ready = r.has_share = r.weights = r.covariance = true;
  r.change = 0.25;
  r.bound = 0.5;
  r.value[0] = -3.0;
  r.value[1] = 7.0;
  StatusPacket st = Status(2, 4);
  SetReport(r, st);
  EXPECT_EQ(st.round, 4u);  // the rest untouched
  const TeamReport back = ReportOf(st);
  EXPECT_TRUE(back.sent && back.initialised && back.coarse_ready && back.has_share &&
              back.weights && back.covariance);
  EXPECT_EQ(back.change, 0.25);
  EXPECT_EQ(back.bound, 0.5);
  EXPECT_EQ(back.value[0], -3.0);
  EXPECT_EQ(back.value[1], 7.0);
}

TEST(StepInbox, PruneForgetsTheStepsBefore) {
  StepInbox inbox = MakeInbox();
  StatusPacket st1 = Status(0, 1);
  st1.sent = true;
  inbox.ingest({From(0, st1), From(0, Estimates(0, 1, Key::Pose(0, 0))), From(0, Status(0, 2))});
  EXPECT_EQ(inbox.missing(0, 1), "");
  inbox.prune(2);
  EXPECT_EQ(inbox.missing(0, 1), "status");
  EXPECT_EQ(inbox.missing(0, 2), "");
}

}  // namespace
}  // namespace moslam::transport_detail
