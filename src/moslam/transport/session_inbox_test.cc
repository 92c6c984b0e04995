#include "moslam/transport/session_inbox.h"

#include <gtest/gtest.h>

namespace moslam::transport_detail {
namespace {

Received List(int sender, std::uint32_t step, std::uint32_t revision) {
  ObjectListPacket p;
  p.robot = sender;
  p.step = step;
  p.revision = revision;
  return {sender, p};
}

Received Status(int sender, std::uint32_t solve) {
  StatusPacket p;
  p.robot = sender;
  p.solve = solve;
  return {sender, p};
}

Received Estimates(int sender, std::uint32_t solve) {
  EstimatesPacket p;
  p.solve = solve;
  return {sender, p};
}

TEST(SessionInbox, SortsWhatArrivesAndHandsEachSolveItsPackets) {
  SessionInbox inbox;
  inbox.add(List(2, 5, 1));
  inbox.add(Status(2, kPresenceSolve));  // the membership's alone: not kept
  inbox.add(Status(3, 7));
  inbox.add(List(2, 5, 2));  // a restarted sender's second list of the step
  inbox.add(Estimates(3, 8));
  inbox.add(List(2, 9, 1));
  SharedObjectsPacket answer;
  answer.sender = 1;
  answer.step = 5;
  inbox.add({1, answer});
  inbox.add(Estimates(1, 7));

  ASSERT_EQ(inbox.lists(2, 5).size(), 2u);
  EXPECT_EQ(inbox.lists(2, 5).front().revision, 1u);  // arrival order
  EXPECT_EQ(inbox.answers(1, 5).size(), 1u);
  EXPECT_TRUE(inbox.answers(2, 5).empty());
  EXPECT_EQ(inbox.pending().size(), 3u);

  const std::vector<Received> seven = inbox.takePending(7);
  ASSERT_EQ(seven.size(), 2u);
  EXPECT_EQ(seven[0].sender, 3);  // arrival order
  EXPECT_EQ(seven[1].sender, 1);
  ASSERT_EQ(inbox.pending().size(), 1u);
  EXPECT_EQ(SolveOf(inbox.pending()[0]), 8u);

  inbox.add(Estimates(2, 9));
  inbox.dropPendingBefore(9, [](std::uint32_t a, std::uint32_t b) { return a < b; });
  ASSERT_EQ(inbox.pending().size(), 1u);
  EXPECT_EQ(SolveOf(inbox.pending()[0]), 9u);
  EXPECT_EQ(inbox.takePending().size(), 1u);
  EXPECT_TRUE(inbox.pending().empty());

  inbox.dropListsUpTo(5);
  EXPECT_TRUE(inbox.lists(2, 5).empty());
  EXPECT_EQ(inbox.lists(2, 9).size(), 1u);
}

}  // namespace
}  // namespace moslam::transport_detail
