// The Cyclone DDS transport inside one process (each test its own DDS domain, loopback-only
// configuration): IDL round trip of every type, history for a late joiner, liveliness, and
// malformed samples or unknown robots rejected and logged without disturbing the receiver.
// Between processes: apps/team_test.cc.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "moslam/common/throws_naming_testing.h"
#include "moslam/transport/dds_entities.h"
#include "moslam/transport/dds_transport.h"
#include "moslam/transport/idl/DgsEstimates.h"
#include "moslam/transport/idl/ObjectList.h"
#include "moslam/transport/idl/SharedObjects.h"
#include "moslam/transport/idl/Status.h"

namespace moslam {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

// Domain ids of this file: 40..44 (apps/team_test.cc: 45..59 and 70..73,
// scripts/test-network.sh: 60..69).
struct Fixture {
  explicit Fixture(int domain_id, int participants = 3)
      : domain(domain_id, LoopbackConfigXml(domain_id, participants)) {}
  DdsTransportOptions options(std::vector<std::string>* log = nullptr) const {
    DdsTransportOptions o;
    o.domain = static_cast<int>(domain_id());
    o.liveliness_lease = milliseconds(1000);
    if (log) {
      o.transport.log = [log](const std::string& s) { log->push_back(s); };
    } else {
      o.transport.log = [](const std::string&) {};
    }
    return o;
  }
  dds_domainid_t domain_id() const {
    dds_domainid_t id = 0;
    (void)dds_get_domainid(domain.get(), &id);
    return id;
  }
  dds::Domain domain;
};

// Polls until `pred(all)` holds or 10 s passed.
std::vector<Received> PollUntil(Transport& t,
                                const std::function<bool(const std::vector<Received>&)>& pred) {
  std::vector<Received> all;
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  while (!pred(all) && Clock::now() < deadline) {
    for (Received& r : t.poll(milliseconds(50))) all.push_back(std::move(r));
  }
  return all;
}

std::vector<Received> PollFor(Transport& t, std::size_t n) {
  return PollUntil(t, [n](const std::vector<Received>& v) { return v.size() >= n; });
}

EstimatesPacket Estimates(int from, int to, std::uint32_t round) {
  EstimatesPacket p;
  p.receiver = to;
  p.round = round;
  p.message.stage = DgsStage::kRotation;
  p.message.sender = from;
  p.message.iteration = round + 3;
  p.message.initialised = true;
  p.message.keys = {Key::Pose(from, 0), Key::Pose(from, 99), Key::Object(from, 5)};
  for (int i = 0; i < 27; ++i) p.message.values.push_back(std::sin(i + 0.25) * 1e3 / (i + 1));
  return p;
}

TEST(DdsTransport, RoundTripsEveryTypeExactly) {
  Fixture f(40);
  DdsTransport t0(0, f.options()), t1(1, f.options());
  EstimatesPacket e = Estimates(0, 1, 17);
  e.solve = 73;
  StatusPacket s;
  s.robot = 0;
  s.solve = 74;
  s.incarnation = 2;
  s.state = RobotState::kPose;
  s.stage = 2;
  s.round = 41;
  s.iteration = 40;
  s.sent = true;
  s.initialised = true;
  s.change = std::numeric_limits<double>::infinity();
  s.neighbours = {1, 3, 700};
  TeamPairEntry held_pair;
  held_pair.mine = 5;
  held_pair.other_robot = 3;
  held_pair.other = (std::uint64_t{1} << 56) - 1;
  held_pair.mine_is_alpha = true;
  held_pair.held = true;
  held_pair.step = 88;
  held_pair.pose = SE3(SO3::Exp(Vector3(-0.4, 0.2, 2.9)), Vector3(-1, 0.5, 7));
  TeamPairEntry bare_pair;
  bare_pair.mine = 6;
  bare_pair.other_robot = 700;
  s.team = {held_pair, bare_pair};
  ObjectListPacket o;
  o.robot = 0;
  o.revision = 9;
  o.step = 31;
  o.objects.push_back({4, "chair", SE3(SO3::Exp(Vector3(0.3, -0.2, 1.1)), Vector3(1, -2, 3.5))});
  o.objects.push_back({(std::uint64_t{1} << 56) - 1, std::string(64, 'x'), SE3()});
  SharedObjectsPacket h;
  h.sender = 0;
  h.receiver = 1;
  h.step = 31;
  h.pairs = {{3, 7}, {(std::uint64_t{1} << 56) - 1, 0}};
  h.removed = {{5, 2}};
  s.weights = true;
  s.covariance = true;
  WeightsPacket w;
  w.solve = 75;
  w.round = 41;
  w.message.sender = 0;
  w.message.receiver = 1;
  w.message.round = 6;
  w.message.weights = {1.0, 0.0, 0.123456789012345678};
  t0.send(e);
  t0.publish(s);
  t0.publish(o);
  t0.send(h);
  t0.send(w);
  CovariancePacket c;
  c.solve = 76;
  c.round = 42;
  c.message.sender = 0;
  c.message.receiver = 1;
  c.message.covariance = Eigen::MatrixXd::Identity(6, 6) * 0.3;
  c.message.covariance(0, 5) = c.message.covariance(5, 0) = -1.0 / 7.0;
  t0.send(c);
  // The refinement's coarse space by pieces: pieces and piece blocks as published.
  CoarsePacket k;
  k.solve = 77;
  k.round = 43;
  k.message.kind = CoarseKind::kPieceMatrix;
  k.message.stage = DgsStage::kRefine;
  k.message.sender = 0;
  k.message.k = 6;
  k.message.ncols = 1;
  k.message.center = {1.0, -2.0, 0.5};
  k.message.pieces = {{3, {0.0, 1.0, 2.0}}, {0xFFFFFFFFu, {4.0, 5.0, 6.0}}};
  k.message.piece_blocks = {{3, 0, 3, std::vector<double>(36, 0.5)},
                            {3, 1, 7, std::vector<double>(36, -1.0 / 3.0)},
                            {0xFFFFFFFFu, 0, 3, std::vector<double>(36, 2.0)}};
  t0.publish(k);

  std::vector<Received> got = PollUntil(t1, [](const std::vector<Received>& v) {
    int n = 0;
    for (const Received& r : v) n += std::holds_alternative<StatusPacket>(r.packet) ? 0 : 1;
    return n >= 6 && v.size() >= 7;
  });
  const CoarsePacket* gk = nullptr;
  for (const Received& r : got) {
    if (auto* p = std::get_if<CoarsePacket>(&r.packet)) gk = p;
  }
  ASSERT_TRUE(gk);
  EXPECT_EQ(gk->solve, 77u);
  EXPECT_EQ(gk->message.kind, CoarseKind::kPieceMatrix);
  EXPECT_EQ(EncodeCoarseMessage(gk->message), EncodeCoarseMessage(k.message));  // bit for bit
  const EstimatesPacket* ge = nullptr;
  const StatusPacket* gs = nullptr;
  const ObjectListPacket* go = nullptr;
  const SharedObjectsPacket* gh = nullptr;
  const WeightsPacket* gw = nullptr;
  const CovariancePacket* gc = nullptr;
  for (const Received& r : got) {
    if (auto* p = std::get_if<CovariancePacket>(&r.packet)) gc = p;
    if (auto* p = std::get_if<WeightsPacket>(&r.packet)) gw = p;
    if (auto* p = std::get_if<SharedObjectsPacket>(&r.packet)) gh = p;
    EXPECT_EQ(r.sender, 0);
    if (auto* p = std::get_if<EstimatesPacket>(&r.packet)) ge = p;
    if (auto* p = std::get_if<StatusPacket>(&r.packet)) gs = p;
    if (auto* p = std::get_if<ObjectListPacket>(&r.packet)) go = p;
  }
  ASSERT_TRUE(ge && gs && go && gh && gw && gc);
  EXPECT_EQ(gc->solve, 76u);
  EXPECT_EQ(gc->round, 42u);
  EXPECT_EQ(gc->message.sender, 0);
  EXPECT_EQ(gc->message.receiver, 1);
  EXPECT_EQ(gc->message.covariance, c.message.covariance);  // bit for bit, symmetric
  EXPECT_TRUE(gs->covariance);
  EXPECT_EQ(gw->solve, 75u);
  EXPECT_EQ(gw->round, 41u);
  EXPECT_EQ(gw->message.sender, 0);
  EXPECT_EQ(gw->message.receiver, 1);
  EXPECT_EQ(gw->message.round, 6u);
  EXPECT_EQ(gw->message.weights, w.message.weights);  // bit for bit
  EXPECT_TRUE(gs->weights);
  EXPECT_EQ(gh->sender, 0);
  EXPECT_EQ(gh->receiver, 1);
  EXPECT_EQ(gh->step, 31u);
  EXPECT_EQ(gh->pairs, h.pairs);
  EXPECT_EQ(gh->removed, h.removed);
  EXPECT_EQ(go->step, 31u);
  EXPECT_EQ(ge->receiver, 1);
  EXPECT_EQ(ge->round, 17u);
  EXPECT_EQ(ge->solve, 73u);
  EXPECT_EQ(gs->solve, 74u);
  EXPECT_EQ(ge->message.stage, e.message.stage);
  EXPECT_EQ(ge->message.iteration, e.message.iteration);
  EXPECT_EQ(ge->message.initialised, e.message.initialised);
  EXPECT_EQ(ge->message.keys, e.message.keys);
  EXPECT_EQ(ge->message.values, e.message.values);  // bit for bit
  EXPECT_EQ(gs->incarnation, 2u);
  EXPECT_EQ(gs->state, RobotState::kPose);
  EXPECT_EQ(gs->round, 41u);
  EXPECT_EQ(gs->iteration, 40u);
  EXPECT_TRUE(gs->sent && gs->initialised && !gs->done);
  EXPECT_TRUE(std::isinf(gs->change));
  EXPECT_EQ(gs->neighbours, s.neighbours);
  ASSERT_EQ(gs->team.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const TeamPairEntry &a = gs->team[i], &b = s.team[i];
    EXPECT_EQ(a.mine, b.mine);
    EXPECT_EQ(a.other_robot, b.other_robot);
    EXPECT_EQ(a.other, b.other);
    EXPECT_EQ(a.mine_is_alpha, b.mine_is_alpha);
    EXPECT_EQ(a.held, b.held);
    EXPECT_EQ(a.step, b.step);
    EXPECT_LT((a.pose.rotation().matrix() - b.pose.rotation().matrix()).norm(), 1e-12);
    EXPECT_EQ(a.pose.translation(), b.pose.translation());
  }
  ASSERT_EQ(go->objects.size(), 2u);
  EXPECT_EQ(go->revision, 9u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(go->objects[i].id, o.objects[i].id);
    EXPECT_EQ(go->objects[i].label, o.objects[i].label);
    EXPECT_LT((go->objects[i].pose.rotation().matrix() - o.objects[i].pose.rotation().matrix())
                  .norm(),
              1e-12);
    EXPECT_EQ(go->objects[i].pose.translation(), o.objects[i].pose.translation());
  }
  // CDR (XCDR1, 8-byte alignment) sizes: 4 (encapsulation) + 20 (header fields, padded) + keys
  // (length, 3 x 8) + values (length, 4 padding, 27 x 8); both ends count the same bytes.
  const TransportStats s0 = t0.stats(), s1 = t1.stats();
  EXPECT_EQ(s0.estimates_sent, 1);
  EXPECT_EQ(s0.estimates_bytes, 4 + 20 + 4 + 3 * 8 + 4 + 4 + 27 * 8);
  EXPECT_EQ(s0.objects_sent, 2);  // the object list and the answer
  // 4 + 4 (sender, receiver) + 12 (solve, round, GNC round) + 4 (length) + 4 (padding) + 3 x 8.
  EXPECT_EQ(s0.weights_sent, 1);
  EXPECT_EQ(s0.weights_bytes, 4 + 4 + 12 + 4 + 4 + 3 * 8);
  // 4 + 4 (sender, receiver) + 12 (solve, round, dimension) + 4 (length) + 4 (padding) + 21 x 8.
  EXPECT_EQ(s0.covariances_sent, 1);
  EXPECT_EQ(s0.covariances_bytes, 4 + 4 + 12 + 4 + 4 + 21 * 8);
  EXPECT_EQ(s0.sent_bytes, s1.received_bytes);
  EXPECT_EQ(s1.rejected, 0);
}

TEST(DdsTransport, ALateJoinerReceivesTheRecentHistoryAndLivelinessTracksPeers) {
  Fixture f(41);
  auto t0 = std::make_unique<DdsTransport>(0, f.options());
  for (std::uint32_t r = 0; r < 20; ++r) {
    StatusPacket s;
    s.robot = 0;
    s.round = r;
    t0->publish(s);
    t0->send(Estimates(0, 1, r));
  }
  DdsTransport t1(1, f.options());
  const auto got = PollFor(t1, 2 * kTransportHistoryDepth);
  ASSERT_EQ(got.size(), 2u * kTransportHistoryDepth);
  std::uint32_t last_status = 0, first_status = 100;
  for (const Received& r : got) {
    if (auto* s = std::get_if<StatusPacket>(&r.packet)) {
      last_status = std::max(last_status, s->round);
      first_status = std::min(first_status, s->round);
    }
  }
  EXPECT_EQ(first_status, 20u - kTransportHistoryDepth);
  EXPECT_EQ(last_status, 19u);
  EXPECT_EQ(t1.alive(), std::set<int>{0});
  t0.reset();  // robot 0 leaves
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  while (!t1.alive().empty() && Clock::now() < deadline) (void)t1.poll(milliseconds(50));
  EXPECT_TRUE(t1.alive().empty());
}

TEST(DdsTransport, RejectsAndLogsMalformedSamplesAndUnknownRobots) {
  Fixture f(42);
  std::vector<std::string> log;
  DdsTransport receiver(1, f.options(&log));
  receiver.setKnownRobots({0, 1});
  // A misbehaving peer writing raw samples on the receiver's topics.
  dds::Participant rogue(f.domain_id());
  const dds::Qos qos = dds::Qos::Reliable(kTransportHistoryDepth, milliseconds(1000));
  dds::Topic inbox(rogue, moslam_msg_dds__DgsEstimates__desc, EstimatesTopicName(1), qos);
  dds::Topic status(rogue, moslam_msg_dds__Status__desc, StatusTopicName(), qos);
  dds::Topic objects(rogue, moslam_msg_dds__ObjectList__desc, ObjectsTopicName(), qos);
  dds::Writer inbox_writer(rogue, inbox, qos), status_writer(rogue, status, qos),
      objects_writer(rogue, objects, qos);

  std::uint64_t keys[2] = {0u << 1, 5u << 1};
  double values[18];
  for (double& v : values) v = 0.5;
  auto estimates = [&]() {
    moslam_msg_dds__DgsEstimates_ s{};
    s.sender = 0;
    s.receiver = 1;
    s.stage = 1;
    s.round = 1;
    s.iteration = 1;
    s.initialised = true;
    s.keys = {2, 2, keys, false};
    s.values = {18, 18, values, false};
    return s;
  };
  int bad = 0;
  {
    auto s = estimates();
    s.values._length = 17;  // wrong count
    inbox_writer.write(&s);
    ++bad;
  }
  {
    auto s = estimates();
    s.stage = 7;
    inbox_writer.write(&s);
    ++bad;
  }
  {
    auto s = estimates();
    s.receiver = 3;
    inbox_writer.write(&s);
    ++bad;
  }
  {
    auto s = estimates();
    s.sender = 9;  // unknown robot
    inbox_writer.write(&s);
    ++bad;
  }
  {
    values[4] = std::numeric_limits<double>::quiet_NaN();
    auto s = estimates();
    inbox_writer.write(&s);
    values[4] = 0.5;
    ++bad;
  }
  {
    std::uint64_t bad_keys[2] = {5u << 1, 0u << 1};  // not increasing
    auto s = estimates();
    s.keys._buffer = bad_keys;
    inbox_writer.write(&s);
    ++bad;
  }
  {
    moslam_msg_dds__Status_ s{};
    s.robot = 0;
    s.state = 77;
    status_writer.write(&s);
    ++bad;
  }
  {
    moslam_msg_dds__ObjectPose_ pose{};
    pose.id = 1;
    std::strcpy(pose.label, "chair");
    pose.orientation[3] = 2.0;  // not a unit quaternion
    moslam_msg_dds__ObjectList_ s{};
    s.robot = 0;
    s.objects = {1, 1, &pose, false};
    objects_writer.write(&s);
    ++bad;
  }
  {
    auto s = estimates();  // finally a valid one
    inbox_writer.write(&s);
  }
  const auto got = PollUntil(receiver, [&](const std::vector<Received>& v) {
    return !v.empty() && receiver.stats().rejected >= bad;
  });
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<EstimatesPacket>(got[0].packet).message.values,
            std::vector<double>(values, values + 18));
  EXPECT_EQ(receiver.stats().rejected, bad);
  int rejected_lines = 0;
  for (const std::string& line : log) rejected_lines += line.rfind("rejected: ", 0) == 0;
  EXPECT_EQ(rejected_lines, bad);
  bool named_unknown = false;
  for (const std::string& line : log) {
    named_unknown = named_unknown || line.find("unknown robot 9") != std::string::npos;
  }
  EXPECT_TRUE(named_unknown);
}

// Both QoS profiles pin the data representation to XCDR1 (dds_entities.cc: Cyclone DDS 0.10.2's
// XCDR2 validation reads past short sequences), so a peer offering XCDR2 does not match.
TEST(DdsEntities, EveryProfileAcceptsXcdr1Only) {
  for (const dds::Qos& q : {dds::Qos::Reliable(4, std::chrono::milliseconds(1000)),
                            dds::Qos::ReliableKeepAll(std::chrono::milliseconds(1000))}) {
    uint32_t n = 0;
    dds_data_representation_id_t* values = nullptr;
    ASSERT_TRUE(dds_qget_data_representation(q.get(), &n, &values));
    ASSERT_EQ(n, 1u);
    EXPECT_EQ(values[0], DDS_DATA_REPRESENTATION_XCDR1);
    dds_free(values);
  }
}

// A Cyclone DDS call that fails throws DdsError (a moslam::Error, so the commands report it as
// any other): the message names what was attempted and Cyclone's reason, and code() keeps the
// return code. Here the second domain of one id in one process, which Cyclone refuses.
TEST(DdsEntities, AFailedCallThrowsDdsErrorNamingWhatAndWhy) {
  const Fixture first(44, 1);
  try {
    dds::Domain second(44, LoopbackConfigXml(44, 1));
    ADD_FAILURE() << "a second domain 44 was created";
  } catch (const dds::DdsError& e) {
    EXPECT_LT(e.code(), 0);
    const std::string what = e.what();
    EXPECT_NE(what.find("create domain 44"), std::string::npos) << what;
    EXPECT_NE(what.find(dds_strretcode(e.code())), std::string::npos) << what;
  }
  EXPECT_TRUE(test::ThrowsNaming<Error>([] { dds::Domain(44, LoopbackConfigXml(44, 1)); },
                                        "DDS: create domain 44"));
  // The first domain is untouched: a participant joins it.
  EXPECT_TRUE(static_cast<bool>(dds::Participant(44)));
}

TEST(DdsTransport, ValidatesOptionsAndRobotIds) {
  DdsTransportOptions o;
  o.domain = 300;
  EXPECT_THROW(DdsTransport(0, o), InvalidInputError);
  o.domain = 43;
  EXPECT_THROW(DdsTransport(-1, o), InvalidInputError);
  EXPECT_THROW(DdsTransport(70000, o), InvalidInputError);
}

TEST(DdsConfig, LoopbackConfigurationListsEveryPeerWithItsPort) {
  const std::string xml = LoopbackConfigXml(5, 3, 1);
  EXPECT_NE(xml.find("<NetworkInterface name=\"lo\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<AllowMulticast>false</AllowMulticast>"), std::string::npos);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NE(xml.find("127.0.0.1:" + std::to_string(7400 + 250 * 5 + 10 + 2 * i)),
              std::string::npos);
  }
  EXPECT_EQ(xml.find("127.0.0.1:" + std::to_string(7400 + 250 * 5 + 10 + 2 * 4)),
            std::string::npos);
}

TEST(DdsConfig, AConfigurationThatWouldNotReadAsMeantIsRefusedNamingTheField) {
  CycloneConfig good;
  good.interfaces = {"lo", "eth0", "192.168.1.7", "fe80::1%eth0"};
  good.peers = {"127.0.0.1:7410", "robot-3.local:7412", "[fe80::1]:7414"};
  EXPECT_NO_THROW(good.validate());
  const auto refused = [&](const std::function<void(CycloneConfig&)>& change,
                           const std::string& field) {
    CycloneConfig c = good;
    change(c);
    return test::ThrowsNaming([&] { CycloneConfigXml(c); }, field);
  };
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.interfaces.clear(); }, "interfaces is empty"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.interfaces[1] = "lo\"/><Peers"; }, "interfaces[1]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.interfaces[0] = ""; }, "interfaces[0]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.peers[0] = "127.0.0.1"; }, "peers[0]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.peers[1] = "host:0"; }, "peers[1]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.peers[1] = "host:65536"; }, "peers[1]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.peers[2] = "a b:7410"; }, "peers[2]"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.peers[2] = ":7410"; }, "peers[2]"));
  EXPECT_TRUE(
      refused([](CycloneConfig& c) { c.max_participant_index = -1; }, "max_participant_index"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.spdp_interval = std::chrono::milliseconds(0); },
                      "spdp_interval"));
  EXPECT_TRUE(refused([](CycloneConfig& c) { c.lease = std::chrono::milliseconds(-5); }, "lease"));
  // Participants whose discovery ports pass 65535 (domain 232 leaves room for 62).
  EXPECT_NO_THROW(LoopbackConfigXml(232, 60, 2));
  EXPECT_THROW(LoopbackConfigXml(232, 62, 2), InvalidInputError);
}

}  // namespace
}  // namespace moslam
