#include "moslam/transport/session_channel.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <utility>

#include "moslam/common/errors.h"
#include "moslam/transport/group_formation.h"

namespace moslam::transport_detail {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::uint32_t kAttemptShift = 24;

}  // namespace

std::uint32_t AttemptSolve(std::uint32_t solve, int attempt) {
  return solve + (static_cast<std::uint32_t>(attempt) << kAttemptShift);
}

bool SolveBefore(std::uint32_t a, std::uint32_t b) {
  if (a == kPresenceSolve) return false;
  constexpr std::uint32_t step_mask = (1u << kAttemptShift) - 1;
  const std::uint32_t sa = a & step_mask, sb = b & step_mask;
  return sa < sb || (sa == sb && (a >> kAttemptShift) < (b >> kAttemptShift));
}

std::vector<int> GroupIds(std::size_t n) {
  std::vector<int> ids(n);
  for (std::size_t i = 0; i < n; ++i) ids[i] = static_cast<int>(i);
  return ids;
}

SessionChannel::SessionChannel(int robot, int num_robots, Transport& transport, Options options,
                               std::unique_ptr<SessionJournal> journal)
    : robot_(robot),
      transport_(transport),
      options_(std::move(options)),
      journal_(std::move(journal)) {
  if (!options_.log) throw InvalidInputError("SessionChannel: the log is required");
  TeamMembership::Options membership;
  membership.leave_timeout = options_.leave_timeout;
  membership.log = options_.log;
  membership.journal = [this](int r, int step) {
    record(LeftRecord{static_cast<std::uint16_t>(r), static_cast<std::uint32_t>(step)});
  };
  membership_ =
      std::make_unique<TeamMembership>(robot_, num_robots, transport_, std::move(membership));
  if (!journal_) return;
  // What the journal held when it was opened (session_journal.h): the answers, groups and
  // solves of a process before this one, and the partners it found gone.
  const SessionJournalContents& held = journal_->contents();
  group_records_ = held.group_records;
  for (const LeftRecord& left : held.left) {
    membership_->restore(left.robot, static_cast<int>(left.step));  // self: left the team
  }
  if (!held.events.empty()) {
    options_.log(
        fmt::format("restart: {} rendezvous taken from {}", held.events.size(), journal_->path()));
  }
  if (!held.solves.empty()) {
    options_.log(fmt::format("restart: {} group solves taken from {}", held.solves.size(),
                             journal_->path()));
  }
}

void SessionChannel::ingest(std::vector<Received> packets) {
  for (Received& r : packets) {
    membership_->onPacket(r);
    inbox_.add(std::move(r));
  }
}

const SessionJournalContents& SessionChannel::journaled() const {
  static const SessionJournalContents kNone;  // no journal: nothing held
  return journal_ ? journal_->contents() : kNone;
}

int SessionChannel::journaledAttempt(int t) const {
  const auto it = group_records_.find(t);
  return it == group_records_.end() ? 0 : it->second - 1;
}

const GroupRecord* SessionChannel::journaledGroup(int t, int attempt) const {
  const std::map<int, GroupRecord>& groups = journaled().groups;
  const auto it = groups.find(t);
  if (it == groups.end() || attempt != journaledAttempt(t)) return nullptr;
  return &it->second;
}

void SessionChannel::recordGroup(const GroupRecord& group) {
  record(group);
  ++group_records_[static_cast<int>(group.step)];
}

void SessionChannel::formGroup(const StatusPacket& join, const std::set<int>& partners,
                               const std::set<int>& range, std::uint32_t solve, int t,
                               std::vector<int>& robots, std::vector<TeamPair>& team,
                               std::vector<int>* closure) {
  std::set<int> group{robot_};
  group.insert(partners.begin(), partners.end());
  const auto deadline = Clock::now() + options_.join_timeout;
  std::map<int, Clock::time_point> not_alive_since;
  JoiningStatuses heard;
  while (true) {
    // The first status of each (not its DgsNode's later ones: a robot that read those formed
    // another closure, and took the batch solve of the whole team while the others left it).
    heard = ReadJoiningStatuses(inbox_.pending(), solve, range);
    GrowClosure(group, heard.neighbours, &range);
    std::vector<int> missing;
    for (int r : group) {
      if (r != robot_ && !heard.neighbours.count(r) && !hasLeft(r, t) &&
          !foundLeft(r, t, not_alive_since)) {
        missing.push_back(r);
      }
    }
    if (missing.empty()) break;
    if (Clock::now() > deadline) {
      throw Error(
          fmt::format("robot {}: the group solve of step {} did not form within {} ms: "
                      "no status from robot(s) {}",
                      robot_, t, options_.join_timeout.count(), fmt::join(missing, ", ")));
    }
    ingest(transport_.poll(std::chrono::milliseconds(50)));
  }
  if (closure) closure->assign(group.begin(), group.end());
  std::vector<int> heard_members;
  for (int r : group) {
    if (heard.neighbours.count(r)) heard_members.push_back(r);
  }
  membership_->applyGoneLists(heard_members, t);  // gone for one, gone for all (self: it leaves)
  for (int r : group) {                           // without the robots that left
    if (r == robot_ || (heard.neighbours.count(r) && !hasLeft(r, t))) robots.push_back(r);
  }
  heard.team[robot_] = join.team;
  team = GroupHeldPairs(robots, heard.team);
}

}  // namespace moslam::transport_detail
