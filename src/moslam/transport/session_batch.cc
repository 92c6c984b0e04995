#include "moslam/transport/session_batch.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <filesystem>
#include <iterator>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/io/g2o.h"
#include "moslam/online/group_solve.h"
#include "moslam/robust/gnc.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/group_transport.h"
#include "moslam/transport/solve_record.h"

namespace moslam::transport_detail {
namespace {

// Hands the packets received during the rendezvous phase (DGS statuses and estimates of robots
// that finished it first) to the DGS node before anything new.
class PrefetchedTransport final : public Transport {
 public:
  PrefetchedTransport(Transport& inner, std::vector<Received> pending)
      : inner_(inner), pending_(std::move(pending)) {}
  int self() const override { return inner_.self(); }
  void send(const EstimatesPacket& p) override { inner_.send(p); }
  void send(const SharedObjectsPacket& p) override { inner_.send(p); }
  void send(const WeightsPacket& p) override { inner_.send(p); }
  void send(const CovariancePacket& p) override { inner_.send(p); }
  void publish(const StatusPacket& p) override { inner_.publish(p); }
  void publish(const ObjectListPacket& p) override { inner_.publish(p); }
  void publish(const CoarsePacket& p) override { inner_.publish(p); }
  std::vector<Received> poll(std::chrono::milliseconds timeout) override {
    if (pending_.empty()) return inner_.poll(timeout);
    std::vector<Received> out = std::move(pending_);
    pending_.clear();
    for (Received& r : inner_.poll(std::chrono::milliseconds(0))) out.push_back(std::move(r));
    return out;
  }
  std::set<int> alive() const override { return inner_.alive(); }
  void setKnownRobots(const std::set<int>& robots) override { inner_.setKnownRobots(robots); }
  TransportStats stats() const override { return inner_.stats(); }

 private:
  Transport& inner_;
  std::vector<Received> pending_;
};

// A batch robust solve whose separator check left a robot unlinked has no estimate of the
// team: an error, as RunRobustDgs throws it in one process.
void RefuseUnlinked(const DgsNodeResult& solved, int robot) {
  if (!solved.robust || !solved.robust->unlinked) return;
  throw UnderdeterminedError(fmt::format(
      "robot {}: the separator check left some robot of the team without a pair it accepts "
      "(a robot pair with fewer than min_support pairwise-consistent shared objects keeps none "
      "unless its robots are linked through confirmed pairs): no team estimate",
      robot));
}

}  // namespace

SessionBatchSolve::SessionBatchSolve(SessionChannel& channel, const SessionPairs& pairs,
                                     int num_robots, int num_steps,
                                     const RobotSessionOptions& options)
    : channel_(channel),
      pairs_(pairs),
      num_robots_(num_robots),
      num_steps_(num_steps),
      options_(options),
      robot_(channel.robot()) {}

void SessionBatchSolve::run(const ObjectSlam& slam, RobotSessionResult& result) {
  // A robot of the team that leaves before its first step stops the solve (DgsNode's
  // TeamChangedError); the team is formed again without it, as when it had left before.
  const int end = num_steps_;
  for (int attempt = channel_.journaledAttempt(end);; ++attempt) {
    std::vector<int> closure, robots;
    const bool departures = formGroup(closure, robots, attempt);
    try {
      if (departures) {
        solveWithoutTheRobotsThatLeft(slam, closure, robots, attempt, result);
      } else {
        result.subgraph = SessionSubgraph(slam, pairs_.shared(), options_.slam.rendezvous.lambda());
        solveTeam(closure, result);
      }
      return;
    } catch (const TeamChangedError& e) {
      for (int r : e.robots()) {
        channel_.markLeft(departures ? robots.at(static_cast<std::size_t>(r)) : r, end,
                          "it joined the batch solve and left before its first step");
      }
      result.subgraph = PoseGraph();
    }
  }
}

// Before the batch solve every robot with shared pairs publishes a joining status of solve
// 1 + T listing every robot it shares pairs with, gone or not, and waits for those of the closure
// (SessionChannel::formGroup): a robot that left for good publishes none and is found gone (or
// was, at a rendezvous), so every robot of the closure finds the same departures. Returns whether
// some robot of `closure` (increasing, this robot among them) left; `robots`: the closure without
// them. The closure is journaled (a group record of step T), so a robot restarted in the solve
// takes the same way. Attempt a > 0 (the team formed again: run()) uses solve
// AttemptSolve(1 + T, a).
bool SessionBatchSolve::formGroup(std::vector<int>& closure, std::vector<int>& robots,
                                  int attempt) {
  const int end = num_steps_;
  if (channel_.membership().out()) {  // it left the team: its own map is its result
    closure = robots = {robot_};
    return true;
  }
  const auto solve = AttemptSolve(static_cast<std::uint32_t>(end + 1), attempt);
  if (const GroupRecord* journaled = channel_.journaledGroup(end, attempt)) {
    closure = journaled->robots;
  } else {
    std::set<int> partners;
    for (const SharedObject& o : pairs_.shared()) {
      for (int r : {o.alpha_object.robot, o.beta_object.robot}) {
        if (r != robot_) partners.insert(r);
      }
    }
    if (partners.empty()) return false;  // linked to no robot: the batch solve as before
    StatusPacket join;
    join.robot = robot_;
    join.solve = solve;
    join.neighbours.assign(partners.begin(), partners.end());
    channel_.transport().publish(join);
    std::set<int> everyone;
    for (int r = 0; r < num_robots_; ++r) everyone.insert(r);
    std::vector<TeamPair> none;
    channel_.formGroup(join, partners, everyone, solve, end, robots, none, &closure);
    channel_.recordGroup(GroupRecord{static_cast<std::uint32_t>(end), closure, {}});
  }
  robots.clear();
  for (int r : closure) {
    if (r == robot_ || !channel_.hasLeft(r, end)) robots.push_back(r);
  }
  return robots.size() != closure.size();
}

// The batch solve of the whole team (none of its robots left): DgsNode on the robot's subgraph;
// its team the closure the joining statuses formed (empty, for a robot linked to none: the node
// forms it).
void SessionBatchSolve::solveTeam(const std::vector<int>& closure, RobotSessionResult& result) {
  PrefetchedTransport dgs_transport(channel_.transport(), channel_.inbox().takePending());
  DgsNodeOptions node_options = options_.dgs;
  node_options.team = closure;
  if (node_options.gnc && node_options.robust.empty()) {
    node_options.robust = ObjectFactors(result.subgraph);
  }
  DgsNode node(robot_, result.subgraph, result.initial, dgs_transport, node_options);
  result.dgs = node.run();
  RefuseUnlinked(result.dgs, robot_);
}

// The batch solve of `robots`, the closure without the robots that left: their pairs dropped, the
// robots re-labelled 0..k-1 (GroupTransport) so that the lowest of them holds the gauge (robot 0
// may have left), as the in-process twin solves the joint graph of the robots that stay
// (BuildGroupProblem without held estimates). Its DgsNode journals in <state_dir>/solves/batch;
// the result, in the robots' own ids, in <state_dir>/result.g2o.
void SessionBatchSolve::solveWithoutTheRobotsThatLeft(const ObjectSlam& slam,
                                                      const std::vector<int>& closure,
                                                      const std::vector<int>& robots, int attempt,
                                                      RobotSessionResult& result) {
  std::vector<int> gone;
  std::set_difference(closure.begin(), closure.end(), robots.begin(), robots.end(),
                      std::back_inserter(gone));
  const auto real = [&](Key k) {
    return Key{robots[static_cast<std::size_t>(k.robot)], k.kind, k.index};
  };
  if (robots.size() < 2) {  // every partner left: its own map is its result
    for (const auto& [k, x] : slam.estimate()) result.dgs.estimate.emplace(k, x);
    result.dgs.team = robots;
    result.subgraph = slam.graph();
    save(result);
    return;
  }
  const auto solve = AttemptSolve(static_cast<std::uint32_t>(num_steps_ + 1), attempt);
  RobotGroupPart part =
      BuildRobotGroupPart(slam, robots, pairs_.shared(), {}, options_.slam.rendezvous.lambda());
  GroupTransport group_transport(
      channel_.transport(), robots, solve, [this](Received r) { channel_.ingest({std::move(r)}); },
      channel_.inbox().takePending(solve));
  DgsNodeOptions node_options = options_.dgs;
  node_options.solve = solve;
  node_options.team = GroupIds(robots.size());
  if (!options_.dgs.state_dir.empty()) {
    node_options.state_dir =
        (std::filesystem::path(options_.dgs.state_dir) / "solves" /
         (attempt == 0 ? std::string("batch") : fmt::format("batch_attempt_{}", attempt)))
            .string();
  }
  if (node_options.gnc && node_options.robust.empty()) {
    node_options.robust = ObjectFactors(part.subgraph);
  }
  node_options.log = [this, gone, robots](const std::string& text) {
    options_.log(fmt::format("batch solve without robot(s) {} (robots {} as 0..{}): {}",
                             fmt::join(gone, ","), fmt::join(robots, ","), robots.size() - 1,
                             text));
  };
  DgsNode node(part.local, part.subgraph, std::move(part.initial), group_transport, node_options);
  DgsNodeResult solved = node.run();
  RefuseUnlinked(solved, robot_);
  for (const RelativePoseFactor& f : part.subgraph.factors()) {
    result.subgraph.add(
        RelativePoseFactor(real(f.a()), real(f.b()), f.measured(), f.information()));
  }
  Values estimate, neighbours;
  for (const auto& [k, x] : solved.estimate) estimate.emplace(real(k), x);
  for (const auto& [k, x] : solved.neighbours) neighbours.emplace(real(k), x);
  solved.estimate = std::move(estimate);
  solved.neighbours = std::move(neighbours);
  for (std::vector<int>* ids : {&solved.team, &solved.left}) {
    for (int& r : *ids) r = robots[static_cast<std::size_t>(r)];
  }
  result.dgs = std::move(solved);
  save(result);
}

// <state_dir>/result.g2o as the batch DgsNode writes it: the subgraph and the estimate.
void SessionBatchSolve::save(const RobotSessionResult& result) const {
  if (options_.dgs.state_dir.empty()) return;
  const std::filesystem::path dir(options_.dgs.state_dir);
  G2oWriteOptions write;
  write.scheme = KeyScheme::kWithObjects;
  write.atomic = true;
  WriteG2oFile((dir / "result.g2o").string(), result.subgraph, result.dgs.estimate, write);
}

}  // namespace moslam::transport_detail
