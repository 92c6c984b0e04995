#include "moslam/transport/session_pairs.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {
namespace {

// Beta (robot 1) answers alpha (robot 0): pairs (alpha landmark, beta landmark), as a decoded
// message (SharedObjectsMessage) or as received from the network (SharedObjectsPacket).
template <typename Message>
Message FromBeta(decltype(Message::pairs) pairs, decltype(Message::removed) removed = {}) {
  Message m;
  m.sender = 1;
  m.receiver = 0;
  m.pairs = std::move(pairs);
  m.removed = std::move(removed);
  return m;
}
SharedObjectsMessage Answer(decltype(SharedObjectsMessage::pairs) pairs,
                            decltype(SharedObjectsMessage::removed) removed = {}) {
  return FromBeta<SharedObjectsMessage>(std::move(pairs), std::move(removed));
}

TEST(SessionPairs, ARendezvousRemovesFirstThenAppendsAndUnsetsWhatLeaves) {
  SessionPairs p(0);
  EXPECT_EQ(p.apply(Answer({{1, 5}, {2, 6}, {3, 7}}), 10).size(), 3u);
  p.setAside({{Key::Object(0, 2), Key::Object(1, 6)}, {Key::Object(0, 3), Key::Object(1, 7)}}, 10);
  EXPECT_EQ(p.accepted().size(), 1u);
  // The next rendezvous removes (2, 6), which was set aside, and adds (4, 8).
  const std::vector<SharedObject> added = p.apply(Answer({{4, 8}}, {{2, 6}}), 20);
  ASSERT_EQ(added.size(), 1u);
  EXPECT_EQ(added[0].alpha_object, Key::Object(0, 4));
  ASSERT_EQ(p.shared().size(), 3u);
  EXPECT_EQ(p.shared()[2].beta_object, Key::Object(1, 8));  // appended
  ASSERT_EQ(p.setAside().size(), 1u);                       // (2, 6) is no longer set aside
  EXPECT_EQ(p.setAsideKeys()[0], std::make_pair(Key::Object(0, 3), Key::Object(1, 7)));
  EXPECT_EQ(p.accepted().size(), 2u);
}

TEST(SessionPairs, AJournalOfAnotherRunIsRefusedAndChangesNothing) {
  SessionPairs p(0);
  p.apply(Answer({{1, 5}, {2, 6}}), 10);
  p.setAside({{Key::Object(0, 1), Key::Object(1, 5)}}, 10);
  try {
    p.apply(Answer({{3, 7}}, {{2, 6}, {9, 9}}), 30);  // (9, 9) was never shared
    FAIL() << "no throw";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("step 30"), std::string::npos) << e.what();
  }
  EXPECT_EQ(p.shared().size(), 2u);  // (2, 6) still there, (3, 7) not added
  EXPECT_THROW(p.setAside({{Key::Object(0, 9), Key::Object(1, 9)}}, 40), InvalidInputError);
  ASSERT_EQ(p.setAside().size(), 1u);
  EXPECT_EQ(p.setAside()[0].alpha_object, Key::Object(0, 1));
}

// What robot 0 (alpha, 4 landmarks) receives from robot 1 (beta).
SharedObjectsPacket Received(decltype(SharedObjectsPacket::pairs) pairs,
                             decltype(SharedObjectsPacket::removed) removed = {}) {
  return FromBeta<SharedObjectsPacket>(std::move(pairs), std::move(removed));
}

TEST(SessionPairs, AnAnswerFromTheNetworkIsCheckedAgainstThePairsTheTwoShare) {
  SessionPairs p(0);
  p.apply(Answer({{1, 5}}), 10);
  SharedObjectsMessage with_two;  // robot 2 answered robot 0 before: pair (2 of robot 0, 9)
  with_two.sender = 2;
  with_two.receiver = 0;
  with_two.pairs = {{2, 9}};
  p.apply(with_two, 12);
  const auto why = [&](const SharedObjectsPacket& answer, bool known) {
    return p.checkAnswer(answer, 4, known);
  };
  EXPECT_EQ(why(Received({{0, 6}, {3, 7}}, {{1, 5}}), true), "");
  EXPECT_EQ(why(Received({{2, 9}}), true), "");  // shared with robot 2, not with robot 1
  EXPECT_EQ(why(Received({{4, 6}}), false), "names object 4 of this robot, which has 4");
  EXPECT_EQ(why(Received({{0, 1ull << 32}}), false), "object id 4294967296 exceeds 32 bits");
  EXPECT_EQ(why(Received({{1, 5}}), false),
            "pair (1, 5) uses an object already shared between the two");
  // Known initial poses: an object shared with beta is not paired again, with another partner
  // either; unknown: a rendezvous may pair it anew (the consistency check removes the old pair).
  EXPECT_NE(why(Received({{1, 6}}), true), "");
  EXPECT_NE(why(Received({{0, 5}}), true), "");
  EXPECT_EQ(why(Received({{1, 6}}), false), "");
  EXPECT_EQ(why(Received({}, {{2, 9}}), true),
            "removes pair (2, 9), which the two do not share");
  EXPECT_EQ(why(Received({}, {{5, 1}}), true), "removes pair (5, 1), which the two do not share");
}

}  // namespace
}  // namespace moslam::transport_detail
