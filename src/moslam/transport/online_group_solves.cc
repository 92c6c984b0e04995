#include "moslam/transport/online_group_solves.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <filesystem>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"
#include "moslam/graph/robot_groups.h"
#include "moslam/io/g2o.h"
#include "moslam/io/tum.h"
#include "moslam/online/online_team.h"
#include "moslam/transport/dgs_node.h"
#include "moslam/transport/group_transport.h"

namespace moslam::transport_detail {
namespace {

using Clock = std::chrono::steady_clock;

// The factors of its own graph whose weight is not 1 (rejected by its last robust solve).
std::vector<std::uint32_t> RejectedFactors(const ObjectSlam& slam) {
  std::vector<std::uint32_t> out;
  const std::vector<double>& w = slam.factorWeights();
  for (std::size_t j = 0; j < w.size(); ++j) {
    if (w[j] != 1.0) out.push_back(static_cast<std::uint32_t>(j));
  }
  return out;
}

// The robots connected to `robot` through the rendezvous events of step t, itself included
// (empty when it has none).
std::set<int> RobotsInRange(const std::vector<RendezvousEvent>& events, int t, int robot) {
  std::vector<int> in_range;
  std::vector<std::pair<int, int>> links;
  for (const RendezvousEvent& e : events) {
    if (e.step != t) continue;
    in_range.insert(in_range.end(), {e.alpha, e.beta});
    links.emplace_back(e.alpha, e.beta);
  }
  std::set<int> range;
  for (const std::vector<int>& g : ConnectedRobots(in_range, links)) {
    if (std::binary_search(g.begin(), g.end(), robot)) range.insert(g.begin(), g.end());
  }
  return range;
}

// The DgsNode journal of attempt `attempt` of the group solve of step t (none without a
// state_dir): a robot restarted in the solve resumes it from there (dgs_node.h).
std::filesystem::path SolveDir(const std::string& state_dir, int t, int attempt) {
  if (state_dir.empty()) return {};
  return std::filesystem::path(state_dir) / "solves" /
         (attempt == 0 ? fmt::format("step_{:04d}", t)
                       : fmt::format("step_{:04d}_attempt_{}", t, attempt));
}

// The node options of one attempt of the group solve of step t among `robots` (their local ids
// 0..n-1), robust as OnlineTeam's group solve with options.dgs.gnc.
DgsNodeOptions GroupNodeOptions(const RobotSessionOptions& options, int t, std::uint32_t solve,
                                const std::vector<int>& robots, const RobotGroupPart& part,
                                const std::filesystem::path& solve_dir) {
  DgsNodeOptions node_options = options.dgs;
  node_options.solve = solve;
  node_options.team = GroupIds(robots.size());  // formed by the joining statuses
  node_options.state_dir = solve_dir.string();
  if (node_options.gnc) {
    RobustGroupMasks masks = RobustGroupFactors(part.subgraph, part.team);
    node_options.robust = std::move(masks.robust);
    if (node_options.separator_check) node_options.checked = std::move(masks.checked);
  }
  node_options.log = [log = options.log, t, robots](const std::string& text) {
    log(fmt::format("group solve of step {} (robots {} as 0..{}): {}", t, fmt::join(robots, ","),
                    robots.size() - 1, text));
  };
  return node_options;
}

}  // namespace

OnlineGroupSolves::OnlineGroupSolves(SessionChannel& channel, SessionPairs& pairs,
                                     const std::vector<RendezvousEvent>& events,
                                     const RobotSessionOptions& options)
    : channel_(channel),
      pairs_(pairs),
      events_(events),
      options_(options),
      robot_(channel.robot()) {}

std::optional<SessionSolve> OnlineGroupSolves::solve(ObjectSlam& slam, int t) {
  const auto t0 = Clock::now();
  if (const auto journaled = channel_.journaled().solves.find(t);
      journaled != channel_.journaled().solves.end()) {
    // Taken from the journal (restart): the map and held copies after it, as computed then;
    // nothing is sent.
    return finish(slam, t, channel_.journaled().groups.at(t).robots, journaled->second,
                  TransportStats{}, t0, true);
  }
  Transport& transport = channel_.transport();
  const TransportStats before = transport.stats();
  const std::set<int> range = RobotsInRange(events_, t, robot_);
  // A member that leaves before its first step stops the solve (DgsNode's TeamChangedError):
  // found gone, the group is formed again without it, as if it had left before (attempt a of
  // the solve: AttemptSolve).
  std::vector<int> robots;
  std::optional<RobotGroupPart> part;
  std::optional<DgsNodeResult> result;
  std::filesystem::path solve_dir;
  for (int attempt = channel_.journaledAttempt(t); !result; ++attempt) {
    const auto solve = AttemptSolve(static_cast<std::uint32_t>(t + 1), attempt);
    std::vector<TeamPair> team;
    if (!joinGroup(t, range, solve, attempt, robots, team)) return std::nullopt;
    part =
        BuildRobotGroupPart(slam, robots, pairs_.shared(), team, options_.slam.rendezvous.lambda());
    GroupTransport group_transport(
        transport, robots, solve, [this](Received r) { channel_.ingest({std::move(r)}); },
        channel_.inbox().takePending(solve));
    solve_dir = SolveDir(options_.dgs.state_dir, t, attempt);
    DgsNode node(part->local, part->subgraph, part->initial, group_transport,
                 GroupNodeOptions(options_, t, solve, robots, *part, solve_dir));
    try {
      result = node.run();
    } catch (const TeamChangedError& e) {
      for (int local : e.robots()) {
        channel_.markLeft(robots.at(static_cast<std::size_t>(local)), t,
                          fmt::format("it joined the group solve of step {} and left before "
                                      "its first step",
                                      t));
      }
      if (!solve_dir.empty()) RemoveAll(solve_dir, "group solve");
    }
  }
  const SolveRecord done = recordSolved(slam, t, robots, *part, *result);
  if (!solve_dir.empty()) RemoveAll(solve_dir, "group solve");  // the record replaces it
  return finish(slam, t, robots, done, transport.stats() - before, t0, false);
}

// The outcome of a group solve just run into the robot's verdicts (robust) and its record,
// journaled: its map and held copies, or (the check left some robot of the group unlinked)
// nothing changed, as OnlineTeam.
SolveRecord OnlineGroupSolves::recordSolved(ObjectSlam& slam, int t, const std::vector<int>& robots,
                                            const RobotGroupPart& part,
                                            const DgsNodeResult& solved) {
  SolveRecord done;
  done.step = static_cast<std::uint32_t>(t);
  done.object_object = static_cast<std::uint32_t>(part.object_object);
  done.team_factors = static_cast<std::uint32_t>(part.team_factors);
  if (solved.robust && solved.robust->unlinked) {
    done.unlinked = true;
    done.estimate = slam.estimate();
    done.set_aside = pairs_.setAsideKeys();
    done.rejected = RejectedFactors(slam);
    channel_.record(done);
    return done;
  }
  if (solved.robust) {  // the verdicts first: the held copies are of the accepted pairs
    judge(slam, robots, part, *solved.robust, done);
    applyVerdicts(slam, done, t);
  }
  Values solution = solved.estimate;
  solution.insert(solved.neighbours.begin(), solved.neighbours.end());
  // Members that left during the solve (the node's rule) are gone for good for this robot too:
  // their later rendezvous skipped, no later solve includes them; of their landmarks it takes
  // what the solution holds (what they sent before they left), and keeps its copies of the rest.
  std::set<int> left_solve;
  for (int local : solved.left) {
    const int r = robots.at(static_cast<std::size_t>(local));
    left_solve.insert(r);
    if (channel_.hasLeft(r, t)) continue;
    channel_.markLeft(r, t, fmt::format("left during the group solve of step {}", t));
  }
  GroupUpdate update = RobotGroupUpdate(robots, robot_, solution, pairs_.accepted(), t, left_solve);
  done.estimate = update.estimate;
  done.held = update.held;
  done.rotation_rounds = static_cast<std::uint32_t>(solved.rotation_rounds);
  done.pose_rounds = static_cast<std::uint32_t>(solved.pose_rounds);
  done.refine_steps = static_cast<std::uint32_t>(solved.program.refine.iterations);
  done.protocol_steps = static_cast<std::uint32_t>(solved.program.channel_steps);
  done.refine_status = solved.program.refine.status;
  channel_.record(done);
  return done;
}

// Attempt `attempt` (solve `solve`) of the group solve of step t: publishes the robot's joining
// status and forms the group with its partners in `range` (or takes the group journaled for
// this attempt: restarted in the solve); false when it has no partner left to solve with.
bool OnlineGroupSolves::joinGroup(int t, const std::set<int>& range, std::uint32_t solve,
                                  int attempt, std::vector<int>& robots,
                                  std::vector<TeamPair>& team) {
  robots.clear();
  team.clear();
  std::set<int> partners;
  for (const SharedObject& o : pairs_.shared()) {
    const int a = o.alpha_object.robot, b = o.beta_object.robot;
    const int other = a == robot_ ? b : (b == robot_ ? a : robot_);
    if (other != robot_ && range.count(other) && !channel_.hasLeft(other, t)) {
      partners.insert(other);
    }
  }
  if (partners.empty()) return false;  // linked to no robot in range: nothing to solve together
  StatusPacket join;
  join.robot = robot_;
  join.solve = solve;
  join.neighbours.assign(partners.begin(), partners.end());
  // All its pairs with other robots, and its copies of their landmarks: formGroup keeps those
  // with robots outside the group it forms (GroupTeamFactors picks among the members' copies),
  // so the pairs with a partner found gone while the group forms are held ones.
  for (const TeamPair& p : RobotTeamPairs(robot_, pairs_.accepted(), held_, {robot_})) {
    TeamPairEntry e;
    e.mine = p.mine.index;
    e.other_robot = p.other.robot;
    e.other = p.other.index;
    e.mine_is_alpha = p.mine_is_alpha;
    if (p.held) {
      e.held = true;
      e.step = static_cast<std::uint32_t>(p.copy.step);
      e.pose = p.copy.pose;
    }
    join.team.push_back(e);
  }
  std::sort(join.team.begin(), join.team.end(), TeamPairBefore);
  channel_.transport().publish(join);
  // Drop what earlier solves left; wait for the joining statuses of the closure.
  channel_.inbox().dropPendingBefore(solve, SolveBefore);
  if (const GroupRecord* journaled = channel_.journaledGroup(t, attempt)) {
    robots = journaled->robots;  // restarted in the solve: its partners formed it
    team = journaled->team;
    return true;
  }
  channel_.formGroup(join, partners, range, solve, t, robots, team);
  if (robots.size() < 2) return false;  // its partners in range have all left
  channel_.recordGroup(GroupRecord{static_cast<std::uint32_t>(t), robots, team});
  return true;
}

// The solve's outcome (computed now or journaled) into the robot's state, and its record.
SessionSolve OnlineGroupSolves::finish(ObjectSlam& slam, int t, const std::vector<int>& robots,
                                       const SolveRecord& done, const TransportStats& sent,
                                       Clock::time_point t0, bool replayed) {
  if (!done.unlinked) {
    if (options_.dgs.gnc && replayed) applyVerdicts(slam, done, t);
    for (const auto& [k, x] : done.held) held_[k] = x;
    slam.setEstimate(done.estimate);
    slam.setTeamFactors(
        TeamFactors(robot_, pairs_.accepted(), held_, options_.slam.rendezvous.lambda()));
  }
  SessionSolve rec;
  rec.step = t;
  rec.robots = robots;
  rec.object_object = static_cast<int>(done.object_object);
  rec.team_factors = static_cast<int>(done.team_factors);
  rec.rotation_rounds = static_cast<int>(done.rotation_rounds);
  rec.pose_rounds = static_cast<int>(done.pose_rounds);
  rec.refine_steps = static_cast<int>(done.refine_steps);
  rec.refine_status = done.refine_status;
  rec.protocol_steps = static_cast<int>(done.protocol_steps);
  rec.estimate = slam.estimate();
  rec.unlinked = done.unlinked;
  rec.set_aside = static_cast<int>(pairs_.setAside().size());
  rec.observation_outliers = static_cast<int>(done.rejected.size());
  rec.sent = sent;
  rec.replayed = replayed;
  rec.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  SaveSessionMap(options_.dgs.state_dir, slam, fmt::format("step_{:04d}", t));
  return rec;
}

// The solve's verdicts into `done` (dgs.gnc; OnlineTeam's verdicts, each robot on its own
// pairs): its pairs with the group's robots judged (a separator's weight is its lower robot's,
// the same on both sides), the pairs set aside after it, and the factors of its own graph
// rejected.
void OnlineGroupSolves::judge(const ObjectSlam& slam, const std::vector<int>& robots,
                              const RobotGroupPart& part, const RobustProgramResult& solved,
                              SolveRecord& done) const {
  const JudgedPairs pairs = PairsJudged(part.subgraph, solved.weights, robots);
  const PairVerdicts verdicts =
      JudgePairs(pairs_.shared(), pairs_.setAside(), pairs.judged, pairs.rejected);
  for (const SharedObject& s : verdicts.set_aside) {
    done.set_aside.emplace_back(s.alpha_object, s.beta_object);
  }
  done.rejected = RejectedOwnFactors(solved.weights, part.own_first, slam.numFactors());
}

// The verdicts of a solve record (computed now or journaled) into its state: the pairs set
// aside, and its own factors' weights (GNC's min_weight for the rejected ones).
void OnlineGroupSolves::applyVerdicts(ObjectSlam& slam, const SolveRecord& done, int t) {
  std::vector<double> w(slam.numFactors(), 1.0);
  for (std::uint32_t j : done.rejected) {
    if (j >= w.size()) {
      throw InvalidInputError(
          fmt::format("robot {}: the solve of step {} rejects factor {} of "
                      "its {} (journal of another run?)",
                      robot_, t, j, w.size()));
    }
    w[j] = options_.dgs.gnc->min_weight;
  }
  pairs_.setAside(done.set_aside, t);
  slam.setFactorWeights(std::move(w));
}

void SaveSessionMap(const std::string& state_dir, const ObjectSlam& slam, const std::string& name) {
  if (state_dir.empty()) return;
  const std::filesystem::path dir = std::filesystem::path(state_dir) / "maps";
  const std::filesystem::path tmp = dir / (name + ".tmp"), final_dir = dir / name;
  RemoveAll(tmp, "robot map");
  CreateFolder(tmp, "robot map");
  G2oWriteOptions write;
  write.scheme = KeyScheme::kWithObjects;
  WriteG2oFile((tmp / "map.g2o").string(), slam.graph(), slam.estimate(), write);
  WriteTumTrajectories(tmp.string(), slam.estimate());
  ReplaceDirectory(tmp, final_dir, fmt::format("the map '{}'", name));
}

}  // namespace moslam::transport_detail
