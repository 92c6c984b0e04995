// The in-process transport (delivery, history for late joiners, cuts, validation of received
// packets) and the journal (records survive a reopen; a torn tail is cut).
#include "moslam/transport/transport.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/transport/event_record.h"
#include "moslam/transport/in_process_transport.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/solve_record.h"
#include "moslam/transport/step_record.h"

namespace moslam {
namespace {

using std::chrono::milliseconds;

EstimatesPacket Estimates(int from, int to, std::uint32_t round, double value = 1.0) {
  EstimatesPacket p;
  p.receiver = to;
  p.round = round;
  p.message.stage = DgsStage::kPose;
  p.message.sender = from;
  p.message.iteration = round;
  p.message.initialised = true;
  p.message.keys = {Key::Pose(from, 3), Key::Pose(from, 7)};
  p.message.values.assign(12, value);
  return p;
}

StatusPacket Status(int robot, std::uint32_t round) {
  StatusPacket s;
  s.robot = robot;
  s.state = RobotState::kRotation;
  s.stage = 1;
  s.round = round;
  s.neighbours = {robot + 1};
  return s;
}

// Polls until `n` packets arrived or 5 s passed.
std::vector<Received> PollFor(Transport& t, std::size_t n) {
  std::vector<Received> all;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (all.size() < n && std::chrono::steady_clock::now() < deadline) {
    for (Received& r : t.poll(milliseconds(50))) all.push_back(std::move(r));
  }
  return all;
}

TEST(TransportStats, TheDifferenceOfTwoReadingsSubtractsEveryCounter) {
  TransportStats later, earlier;
  std::int64_t* const fields[] = {
      &later.sent_samples,     &later.sent_bytes,       &later.received_samples,
      &later.received_bytes,   &later.rejected,         &later.estimates_sent,
      &later.estimates_bytes,  &later.status_sent,      &later.status_bytes,
      &later.coarse_sent,      &later.coarse_bytes,     &later.weights_sent,
      &later.weights_bytes,    &later.covariances_sent, &later.covariances_bytes,
      &later.objects_sent,     &later.objects_bytes};
  static_assert(sizeof(fields) / sizeof(fields[0]) * sizeof(std::int64_t) ==
                sizeof(TransportStats));
  for (std::size_t i = 0; i < std::size(fields); ++i) *fields[i] = 1000 + 7 * static_cast<int>(i);
  earlier = later;
  for (std::size_t i = 0; i < std::size(fields); ++i) *fields[i] += static_cast<int>(i) + 1;
  const TransportStats d = later - earlier;
  const std::int64_t* const got[] = {
      &d.sent_samples,   &d.sent_bytes,      &d.received_samples,  &d.received_bytes,
      &d.rejected,       &d.estimates_sent,  &d.estimates_bytes,   &d.status_sent,
      &d.status_bytes,   &d.coarse_sent,     &d.coarse_bytes,      &d.weights_sent,
      &d.weights_bytes,  &d.covariances_sent, &d.covariances_bytes, &d.objects_sent,
      &d.objects_bytes};
  for (std::size_t i = 0; i < std::size(got); ++i) {
    EXPECT_EQ(*got[i], static_cast<std::int64_t>(i) + 1) << "counter " << i;
  }
}

TEST(InProcessTransport, DeliversEstimatesToTheReceiverAndStatusToEveryone) {
  InProcessNetwork net;
  auto t0 = net.connect(0), t1 = net.connect(1), t2 = net.connect(2);
  EXPECT_EQ(t0->alive(), (std::set<int>{1, 2}));
  t0->send(Estimates(0, 1, 4));
  t0->publish(Status(0, 4));
  const auto at1 = PollFor(*t1, 2);
  ASSERT_EQ(at1.size(), 2u);
  const auto& e = std::get<EstimatesPacket>(at1[0].packet);
  EXPECT_EQ(at1[0].sender, 0);
  EXPECT_EQ(e.round, 4u);
  EXPECT_EQ(e.message.keys, Estimates(0, 1, 4).message.keys);
  EXPECT_EQ(std::get<StatusPacket>(at1[1].packet).round, 4u);
  const auto at2 = PollFor(*t2, 1);
  ASSERT_EQ(at2.size(), 1u);  // the status only: the estimates were for robot 1
  EXPECT_TRUE(std::holds_alternative<StatusPacket>(at2[0].packet));
  EXPECT_TRUE(t2->poll(milliseconds(1)).empty());
  EXPECT_EQ(t0->stats().estimates_sent, 1);
  EXPECT_EQ(t0->stats().estimates_bytes,
            static_cast<std::int64_t>(EncodeMessage(Estimates(0, 1, 4).message).size()) + 10);
}

TEST(InProcessTransport, ALateOrRestartedRobotReceivesTheRecentHistory) {
  InProcessNetwork net;
  auto t0 = net.connect(0);
  for (std::uint32_t r = 0; r < 20; ++r) {
    t0->publish(Status(0, r));
    t0->send(Estimates(0, 1, r));
  }
  {
    auto t1 = net.connect(1);
    const auto got = PollFor(*t1, 2 * kTransportHistoryDepth);
    ASSERT_EQ(got.size(), 2u * kTransportHistoryDepth);
    // The last kTransportHistoryDepth of each, in order.
    EXPECT_EQ(std::get<StatusPacket>(got.front().packet).round, 20u - kTransportHistoryDepth);
    EXPECT_EQ(std::get<EstimatesPacket>(got.back().packet).round, 19u);
  }
  EXPECT_TRUE(t0->alive().empty());  // robot 1 left
  auto again = net.connect(1);       // restart: the history again
  EXPECT_EQ(PollFor(*again, 2 * kTransportHistoryDepth).size(), 2u * kTransportHistoryDepth);
  EXPECT_THROW(net.connect(1), InvalidInputError);
}

TEST(InProcessTransport, ACutHoldsPacketsAndHidesThePeerUntilRestored) {
  InProcessNetwork net;
  auto t0 = net.connect(0), t1 = net.connect(1);
  net.setLink(0, 1, false);
  EXPECT_TRUE(t0->alive().empty());
  for (std::uint32_t r = 1; r <= 3; ++r) t0->publish(Status(0, r));
  EXPECT_TRUE(t1->poll(milliseconds(20)).empty());
  net.setLink(0, 1, true);
  EXPECT_EQ(t0->alive(), std::set<int>{1});
  const auto got = PollFor(*t1, 3);
  ASSERT_EQ(got.size(), 3u);
  for (std::uint32_t r = 1; r <= 3; ++r) {
    EXPECT_EQ(std::get<StatusPacket>(got[r - 1].packet).round, r);
  }
}

TEST(InProcessTransport, RejectsAndLogsMalformedPacketsAndUnknownRobots) {
  InProcessNetwork net;
  std::vector<std::string> logged;
  TransportOptions options;
  options.log = [&](const std::string& s) { logged.push_back(s); };
  auto t1 = net.connect(1, options);
  t1->setKnownRobots({0, 1, 2});

  std::vector<std::pair<std::string, Packet>> bad;
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.values[5] = std::nan("");
    bad.emplace_back("non-finite", p);
  }
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.values.pop_back();
    bad.emplace_back("count", p);
  }
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.keys = {Key::Pose(0, 7), Key::Pose(0, 3)};
    bad.emplace_back("order", p);
  }
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.keys[1] = Key::Pose(2, 7);  // another robot's variable
    bad.emplace_back("foreign key", p);
  }
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.stage = static_cast<DgsStage>(9);
    bad.emplace_back("stage", p);
  }
  bad.emplace_back("receiver", Estimates(0, 2, 1));
  {
    EstimatesPacket p = Estimates(0, 1, 1);
    p.message.sender = 2;  // claims to be robot 2
    bad.emplace_back("sender", p);
  }
  {
    StatusPacket s = Status(0, 1);
    s.neighbours = {2, 2};
    bad.emplace_back("neighbours", s);
  }
  {
    StatusPacket s = Status(0, 1);
    s.change = -1.0;
    bad.emplace_back("change", s);
  }
  {
    StatusPacket s = Status(0, 1);
    s.state = static_cast<RobotState>(42);
    bad.emplace_back("state", s);
  }
  {
    ObjectListPacket o;
    o.robot = 0;
    o.objects.push_back({1, "", SE3()});
    bad.emplace_back("empty label", o);
  }
  for (auto& [name, packet] : bad) net.inject(0, 1, packet);
  net.inject(9, 1, Status(9, 1));  // unknown robot
  net.inject(0, 1, Status(0, 1));  // and a good one
  const auto got = PollFor(*t1, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].sender, 0);
  EXPECT_TRUE(t1->poll(milliseconds(1)).empty());
  EXPECT_EQ(t1->stats().rejected, static_cast<std::int64_t>(bad.size()) + 1);
  ASSERT_EQ(logged.size(), bad.size() + 1);
  EXPECT_NE(logged.back().find("unknown robot 9"), std::string::npos) << logged.back();
  EXPECT_NE(logged[0].find("non-finite"), std::string::npos) << logged[0];
}

TEST(InProcessTransport, RefusesToSendInvalidPackets) {
  InProcessNetwork net;
  auto t0 = net.connect(0);
  EXPECT_THROW(t0->send(Estimates(1, 2, 1)), InvalidInputError);  // not its own
  EXPECT_THROW(t0->send(Estimates(0, 0, 1)), InvalidInputError);  // to itself
  StatusPacket s = Status(0, 1);
  s.change = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(t0->publish(s), InvalidInputError);
}

TEST(InProcessTransport, DeliversSharedObjectsToTheReceiverOnlyAndChecksThem) {
  InProcessNetwork net;
  auto t0 = net.connect(0), t1 = net.connect(1), t2 = net.connect(2);
  SharedObjectsPacket h;
  h.sender = 0;
  h.receiver = 1;
  h.step = 4;
  h.pairs = {{1, 2}, {3, 4}};
  t0->send(h);
  const auto got = PollFor(*t1, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<SharedObjectsPacket>(got[0].packet).pairs, h.pairs);
  EXPECT_TRUE(t2->poll(milliseconds(1)).empty());
  EXPECT_EQ(t0->stats().objects_sent, 1);
  h.pairs.push_back({1, 9});  // alpha object 1 twice
  EXPECT_NE(CheckPacket(h, 0, 1, {}), "");
  EXPECT_THROW(t0->send(h), InvalidInputError);
  h.pairs = {{1, 2}};
  EXPECT_NE(CheckPacket(h, 0, 2, {}), "");  // addressed to robot 1, received by robot 2
  // The pairs an answer removes (unknown initial poses) travel and are checked alike.
  h.removed = {{5, 6}, {7, 8}};
  t0->send(h);
  const auto removed = PollFor(*t1, 1);
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(std::get<SharedObjectsPacket>(removed[0].packet).removed, h.removed);
  h.removed.push_back({9, 6});  // beta object 6 twice
  EXPECT_NE(CheckPacket(h, 0, 1, {}), "");
  h.removed = {{std::uint64_t{1} << 60, 1}};  // beyond a key index
  EXPECT_NE(CheckPacket(h, 0, 1, {}), "");
}

// The robust solve's weights: only the receiver gets them, checked like every packet.
TEST(InProcessTransport, DeliversWeightsToTheReceiverOnlyAndChecksThem) {
  InProcessNetwork net;
  auto t0 = net.connect(0), t1 = net.connect(1), t2 = net.connect(2);
  WeightsPacket w;
  w.solve = 3;
  w.round = 12;
  w.message.sender = 0;
  w.message.receiver = 1;
  w.message.round = 2;
  w.message.weights = {1.0, 0.25, 0.0};
  t0->send(w);
  const auto got = PollFor(*t1, 1);
  ASSERT_EQ(got.size(), 1u);
  const auto& g = std::get<WeightsPacket>(got[0].packet);
  EXPECT_EQ(g.message.weights, w.message.weights);
  EXPECT_EQ(g.round, 12u);
  EXPECT_EQ(g.solve, 3u);
  EXPECT_TRUE(t2->poll(milliseconds(1)).empty());
  EXPECT_EQ(t0->stats().weights_sent, 1);
  EXPECT_EQ(t0->stats().weights_bytes, BinarySize(Packet(w)));
  EXPECT_NE(CheckPacket(w, 0, 2, {}), "");  // addressed to robot 1, received by robot 2
  EXPECT_NE(CheckPacket(w, 2, 1, {}), "");  // claims sender 0, came from robot 2
  w.message.weights[1] = 1.5;
  EXPECT_NE(CheckPacket(w, 0, 1, {}), "");
  EXPECT_THROW(t0->send(w), InvalidInputError);
  w.message.weights[1] = std::nan("");
  EXPECT_NE(CheckPacket(w, 0, 1, {}), "");
}

// A DGS node's journal record of a step (step_record.h), with the weights of a robust round.
TEST(StepRecord, RoundTripsWeightsAndRejectsUnannouncedOnes) {
  using transport_detail::AppendStepRecord;
  using transport_detail::ReadStepRecord;
  using transport_detail::StepRecord;
  StepRecord rec;
  rec.step = 9;
  rec.stage = DgsStage::kRefine;
  TeamReport a, b;
  a.weights = true;
  a.value[0] = 2.0;
  rec.result.reports = {{0, a}, {1, b}};
  WeightMessage m;
  m.sender = 0;
  m.receiver = 1;
  m.round = 4;
  m.weights = {0.5, 1.0};
  rec.result.weights[0] = m;
  std::vector<std::uint8_t> bytes;
  AppendStepRecord(rec, bytes);
  const StepRecord back = ReadStepRecord(bytes, 0, "test");
  EXPECT_TRUE(back.result.reports.at(0).weights);
  EXPECT_FALSE(back.result.reports.at(1).weights);
  ASSERT_EQ(back.result.weights.size(), 1u);
  EXPECT_EQ(back.result.weights.at(0).weights, m.weights);
  std::vector<std::uint8_t> again;
  AppendStepRecord(back, again);
  EXPECT_EQ(again, bytes);
  // Weights of a robot whose report does not say weights.
  rec.result.reports[0].weights = false;
  bytes.clear();
  AppendStepRecord(rec, bytes);
  EXPECT_THROW(ReadStepRecord(bytes, 0, "test"), InvalidInputError);
  // Truncated.
  bytes.pop_back();
  EXPECT_THROW(ReadStepRecord(bytes, 0, "test"), InvalidInputError);
}

// The separator check's covariances: only the receiver gets them, checked; a step record keeps
// them when the sender's report announced them.
TEST(InProcessTransport, DeliversCovariancesToTheReceiverOnlyAndJournalsThem) {
  InProcessNetwork net;
  auto t0 = net.connect(0), t1 = net.connect(1), t2 = net.connect(2);
  CovariancePacket c;
  c.solve = 0;
  c.round = 1;
  c.message.sender = 1;
  c.message.receiver = 0;
  c.message.covariance = Eigen::MatrixXd::Identity(12, 12);
  c.message.covariance(3, 9) = c.message.covariance(9, 3) = 0.25;
  t1->send(c);
  const auto got = PollFor(*t0, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<CovariancePacket>(got[0].packet).message.covariance, c.message.covariance);
  EXPECT_TRUE(t2->poll(milliseconds(1)).empty());
  EXPECT_EQ(t1->stats().covariances_sent, 1);
  EXPECT_EQ(t1->stats().covariances_bytes, BinarySize(Packet(c)));
  EXPECT_NE(CheckPacket(c, 1, 2, {}), "");  // addressed to robot 0, received by robot 2
  c.message.covariance(4, 4) = -1.0;
  EXPECT_NE(CheckPacket(c, 1, 0, {}), "");
  EXPECT_THROW(t1->send(c), InvalidInputError);
  c.message.covariance = Eigen::MatrixXd::Identity(6 * 257, 6 * 257);
  EXPECT_NE(CheckPacket(c, 1, 0, {}), "");  // beyond kMaxTransportCovarianceDimension

  using transport_detail::AppendStepRecord;
  using transport_detail::ReadStepRecord;
  using transport_detail::StepRecord;
  StepRecord rec;
  rec.step = 1;
  rec.stage = DgsStage::kRefine;
  TeamReport announced;
  announced.covariance = true;
  rec.result.reports = {{0, TeamReport()}, {1, announced}};
  rec.result.covariances[1] = std::get<CovariancePacket>(got[0].packet).message;
  std::vector<std::uint8_t> bytes;
  AppendStepRecord(rec, bytes);
  const StepRecord back = ReadStepRecord(bytes, 0, "test");
  EXPECT_TRUE(back.result.reports.at(1).covariance);
  EXPECT_EQ(back.result.covariances.at(1).covariance, rec.result.covariances.at(1).covariance);
  rec.result.reports[1].covariance = false;  // unannounced
  bytes.clear();
  AppendStepRecord(rec, bytes);
  EXPECT_THROW(ReadStepRecord(bytes, 0, "test"), InvalidInputError);
}

// The rendezvous journal record of a robot session (event_record.h).
TEST(EventRecord, RoundTripsAndRejectsTruncatedTrailingAndRepeatedObjects) {
  using namespace transport_detail;
  EventRecord r;
  r.event = 7;
  r.pairs = {{1, 2}, {3, 4}};
  r.removed = {{5, 6}};
  std::vector<std::uint8_t> bytes{0xAB};  // a type byte before the fields
  AppendEventRecord(r, bytes);
  const EventRecord back = ReadEventRecord(bytes, 1, "test");
  EXPECT_EQ(back.event, 7u);
  EXPECT_EQ(back.pairs, r.pairs);
  EXPECT_EQ(back.removed, r.removed);
  std::vector<std::uint8_t> cut(bytes.begin(), bytes.end() - 1);
  EXPECT_THROW(ReadEventRecord(cut, 1, "test"), InvalidInputError);
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(ReadEventRecord(longer, 1, "test"), InvalidInputError);
  EXPECT_THROW(ReadEventRecord(bytes, bytes.size() + 1, "test"), InvalidInputError);
  r.removed = {{5, 6}, {5, 8}};  // alpha object 5 twice in one list
  std::vector<std::uint8_t> twice;
  AppendEventRecord(r, twice);
  EXPECT_THROW(ReadEventRecord(twice, 0, "test"), InvalidInputError);
  std::vector<std::uint8_t> huge;  // a count far beyond the bytes: no allocation, an error
  AppendEventRecord({1, {}, {}}, huge);
  huge[4] = huge[5] = huge[6] = huge[7] = 0xFF;
  EXPECT_THROW(ReadEventRecord(huge, 0, "test"), InvalidInputError);
}

// The online group and solve records of a robot session (solve_record.h): bit-exact round trips,
// and what a corrupt journal may hold refused.
TEST(SolveRecord, RoundTripsBitExactAndRejectsCorruptRecords) {
  using namespace transport_detail;
  const SE3 x(SO3::Exp(Vector3(0.1, -0.2, 3.1)), Vector3(1.0 / 3.0, -2e-17, 5.5));
  GroupRecord g;
  g.step = 12;
  g.robots = {1, 3, 4};
  g.team.push_back({Key::Object(1, 4), Key::Object(5, 2), true, true, HeldEstimate{x, 9}});
  g.team.push_back({Key::Object(3, 0), Key::Object(0, 7), false, false, HeldEstimate{}});
  std::vector<std::uint8_t> bytes{0xAB};
  AppendGroupRecord(g, bytes);
  const GroupRecord gb = ReadGroupRecord(bytes, 1, "test");
  EXPECT_EQ(gb.step, 12u);
  EXPECT_EQ(gb.robots, g.robots);
  ASSERT_EQ(gb.team.size(), 2u);
  EXPECT_EQ(gb.team[0].mine, g.team[0].mine);
  EXPECT_EQ(gb.team[0].other, g.team[0].other);
  EXPECT_TRUE(gb.team[0].mine_is_alpha && gb.team[0].held);
  EXPECT_EQ(gb.team[0].copy.step, 9);
  EXPECT_EQ(gb.team[0].copy.pose.rotation().matrix(), x.rotation().matrix());  // bit for bit
  EXPECT_EQ(gb.team[0].copy.pose.translation(), x.translation());
  EXPECT_FALSE(gb.team[1].mine_is_alpha || gb.team[1].held);
  std::vector<std::uint8_t> cut(bytes.begin(), bytes.end() - 1);
  EXPECT_THROW(ReadGroupRecord(cut, 1, "test"), InvalidInputError);
  g.robots = {3, 1};
  std::vector<std::uint8_t> unordered;
  AppendGroupRecord(g, unordered);
  EXPECT_THROW(ReadGroupRecord(unordered, 0, "test"), InvalidInputError);

  SolveRecord s;
  s.step = 12;
  s.estimate = {{Key::Pose(3, 0), SE3()}, {Key::Pose(3, 1), x}, {Key::Object(3, 0), x.inverse()}};
  s.held = {{Key::Object(5, 2), HeldEstimate{x, 12}}};
  s.rotation_rounds = 14;
  s.pose_rounds = 12;
  s.refine_steps = 4;
  s.protocol_steps = 60;
  s.object_object = 3;
  s.team_factors = 2;
  s.refine_status = StageStatus::kConverged;
  s.set_aside = {{Key::Object(3, 1), Key::Object(5, 2)}};
  s.rejected = {2, 7};
  bytes.clear();
  AppendSolveRecord(s, bytes);
  const SolveRecord sb = ReadSolveRecord(bytes, 0, "test");
  ASSERT_EQ(sb.estimate.size(), 3u);
  for (const auto& [k, v] : s.estimate) {
    EXPECT_EQ(sb.estimate.at(k).rotation().matrix(), v.rotation().matrix());
    EXPECT_EQ(sb.estimate.at(k).translation(), v.translation());
  }
  EXPECT_EQ(sb.held.at(Key::Object(5, 2)).step, 12);
  EXPECT_EQ(sb.rotation_rounds, 14u);
  EXPECT_EQ(sb.protocol_steps, 60u);
  EXPECT_EQ(sb.refine_status, StageStatus::kConverged);
  EXPECT_FALSE(sb.unlinked);
  EXPECT_EQ(sb.set_aside, s.set_aside);
  EXPECT_EQ(sb.rejected, s.rejected);
  std::vector<std::uint8_t> again;
  AppendSolveRecord(sb, again);
  EXPECT_EQ(again, bytes);
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(ReadSolveRecord(longer, 0, "test"), InvalidInputError);
  // A NaN in a pose, a rotation that is not one, an unknown refine status.
  std::vector<std::uint8_t> bad = bytes;
  const std::size_t first_pose = 4 + 4 + 11;  // step, count, key
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(&bad[first_pose], &nan, sizeof nan);
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  bad = bytes;
  const double two = 2.0;
  std::memcpy(&bad[first_pose], &two, sizeof two);
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  // After the refine status: flags, the pair set aside (two keys), the two rejected indices.
  const std::size_t flags = bytes.size() - (4 + 2 * 11 + 4 + 2 * 4) - 1;
  bad = bytes;
  bad[flags - 1] = 9;  // the refine status
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  bad = bytes;
  bad[flags] = 1;  // unlinked: a valid record
  EXPECT_TRUE(ReadSolveRecord(bad, 0, "test").unlinked);
  bad[flags] = 2;
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  bad = bytes;
  bad[flags + 1 + 4 + 11] = 3;  // the beta landmark's robot: the alpha's
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  bad = bytes;
  bad[bytes.size() - 4] = 2;  // rejected 2, 2: not increasing
  EXPECT_THROW(ReadSolveRecord(bad, 0, "test"), InvalidInputError);
  std::vector<std::uint8_t> huge = bytes;  // a count far beyond the bytes: an error, no allocation
  huge[4] = huge[5] = huge[6] = huge[7] = 0xFF;
  EXPECT_THROW(ReadSolveRecord(huge, 0, "test"), InvalidInputError);
}

TEST(CheckPacket, AcceptsInfiniteChangeAndValidObjectLists) {
  StatusPacket s = Status(0, 1);
  s.change = std::numeric_limits<double>::infinity();
  EXPECT_EQ(CheckPacket(s, 0, 1, {}), "");
  ObjectListPacket o;
  o.robot = 0;
  o.objects.push_back({1, "chair", SE3(SO3::Exp(Vector3(0.1, 0.2, 0.3)), Vector3(1, 2, 3))});
  o.objects.push_back({2, "table", SE3()});
  EXPECT_EQ(CheckPacket(o, 0, 1, {}), "");
  o.objects.push_back({2, "lamp", SE3()});
  EXPECT_NE(CheckPacket(o, 0, 1, {}), "");  // id listed twice
}

// The team pairs of a joining status (online mapping): increasing, ids in range, another robot's
// landmark, finite poses.
TEST(CheckPacket, ValidatesTeamPairs) {
  StatusPacket s = Status(0, 1);
  TeamPairEntry t;
  t.mine = 4;
  t.other_robot = 2;
  t.other = 9;
  t.held = true;
  t.pose = SE3(SO3::Exp(Vector3(0.1, 0.2, 0.3)), Vector3(1, 2, 3));
  TeamPairEntry u = t;
  u.other = 10;
  s.team = {t, u};
  EXPECT_EQ(CheckPacket(s, 0, 1, {}), "");
  const auto rejected = [&](const std::function<void(StatusPacket&)>& spoil) {
    StatusPacket bad = s;
    spoil(bad);
    return !CheckPacket(bad, 0, 1, {}).empty();
  };
  EXPECT_TRUE(rejected([](StatusPacket& p) { std::swap(p.team[0], p.team[1]); }));  // order
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team[1] = p.team[0]; }));           // twice
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team[0].other_robot = 0; }));       // its own
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team[0].other_robot = 70000; }));
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team[1].other = std::uint64_t{1} << 56; }));
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team[0].mine = std::uint64_t{1} << 56; }));
  EXPECT_TRUE(rejected([](StatusPacket& p) {
    p.team[0].pose = SE3(SO3(), Vector3(std::nan(""), 0.0, 0.0));
  }));
  EXPECT_TRUE(rejected([](StatusPacket& p) { p.team.resize(kMaxObjects + 1, p.team[1]); }));
}

class JournalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = test::ScratchDir() / "journal.bin";
  }
  std::filesystem::path path_;
};

TEST_F(JournalTest, RecordsSurviveReopeningAndATornTailIsCut) {
  const std::vector<std::vector<std::uint8_t>> records = {{1, 2, 3}, {}, std::vector<std::uint8_t>(1000, 7)};
  {
    Journal j(path_.string());
    EXPECT_TRUE(j.records().empty());
    for (const auto& r : records) j.append(r);
  }
  const auto good_size = std::filesystem::file_size(path_);
  {
    std::ofstream out(path_, std::ios::binary | std::ios::app);
    out.write("\x10\x00\x00\x00\x01\x02", 6);  // a record cut short by a crash
  }
  {
    Journal j(path_.string());
    EXPECT_EQ(j.records(), records);
    EXPECT_EQ(j.truncatedBytes(), 6);
    j.append({9});
  }
  EXPECT_EQ(std::filesystem::file_size(path_), good_size + 9);
  Journal j(path_.string());
  ASSERT_EQ(j.records().size(), 4u);
  EXPECT_EQ(j.records().back(), std::vector<std::uint8_t>{9});
}

TEST_F(JournalTest, StopsAtACorruptRecord) {
  {
    Journal j(path_.string());
    j.append({1, 2, 3});
    j.append({4, 5, 6});
  }
  {
    std::fstream f(path_, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(8 + 1);  // a payload byte of the first record
    f.put('\x7f');
  }
  Journal j(path_.string());
  EXPECT_TRUE(j.records().empty());
  EXPECT_EQ(j.truncatedBytes(), 2 * (8 + 3));
}

// A journal path that is a folder (a robot's --state-dir given where its journal file goes) is
// an error of the library's own type naming it, not an I/O exception of the standard library.
TEST_F(JournalTest, AFolderIsRefusedNamingIt) {
  std::filesystem::create_directories(path_);
  EXPECT_TRUE(test::ThrowsNaming<Error>([&] { Journal j(path_.string()); },
                                        path_.string() + ": is a folder, not a file"));
  std::filesystem::remove_all(path_);
}

TEST(Crc32, MatchesTheStandardCheckValue) {
  const std::string s = "123456789";
  EXPECT_EQ(Crc32(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()), 0xCBF43926u);
}

}  // namespace
}  // namespace moslam
