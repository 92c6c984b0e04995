#include "moslam/transport/step_inbox.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <variant>

#include "moslam/common/errors.h"

namespace moslam::transport_detail {
namespace {

bool IsStage(std::uint8_t s) { return s >= 1 && s <= 3; }

}  // namespace

TeamReport ReportOf(const StatusPacket& s) {
  TeamReport r;
  r.sent = s.sent;
  r.initialised = s.initialised;
  r.coarse_ready = s.coarse_ready;
  r.has_share = s.coarse;
  r.weights = s.weights;
  r.covariance = s.covariance;
  r.change = s.change;
  r.bound = s.error_bound;
  r.value[0] = s.value[0];
  r.value[1] = s.value[1];
  return r;
}

void SetReport(const TeamReport& report, StatusPacket& s) {
  s.sent = report.sent;
  s.initialised = report.initialised;
  s.coarse_ready = report.coarse_ready;
  s.coarse = report.has_share;
  s.weights = report.weights;
  s.covariance = report.covariance;
  s.change = report.change;
  s.error_bound = report.bound;
  s.value[0] = report.value[0];
  s.value[1] = report.value[1];
}

StepInbox::StepInbox(int robot, std::uint32_t solve, std::set<int> neighbours,
                     std::set<Key> neighbour_keys)
    : robot_(robot),
      solve_(solve),
      neighbours_(std::move(neighbours)),
      neighbour_keys_(std::move(neighbour_keys)),
      step_neighbours_(neighbours_) {}

IngestNotes StepInbox::ingest(std::vector<Received> packets) {
  IngestNotes notes;
  // Weights and covariances are taken from neighbours only (estimates: also for the variables
  // this robot uses, below).
  auto from_neighbour = [&](int sender, const char* what) {
    if (neighbours_.count(sender)) return true;
    ++notes.rejected;
    notes.lines.push_back(
        fmt::format("rejected: {} from robot {}, which is not a neighbour", what, sender));
    return false;
  };
  for (Received& r : packets) {
    if (auto* st = std::get_if<StatusPacket>(&r.packet)) {
      if (st->solve == solve_) takeStatus(r.sender, *st, notes);  // else another solve (online)
    } else if (auto* e = std::get_if<EstimatesPacket>(&r.packet)) {
      if (e->solve == solve_) takeEstimates(*e, notes);
    } else if (auto* c = std::get_if<CoarsePacket>(&r.packet)) {
      if (c->solve != solve_) continue;
      coarse_[{c->round, c->message.sender}] = c->message;
    } else if (auto* w = std::get_if<WeightsPacket>(&r.packet)) {
      if (w->solve != solve_ || !from_neighbour(w->message.sender, "weights")) continue;
      weights_[{w->round, w->message.sender}] = w->message;
    } else if (auto* v = std::get_if<CovariancePacket>(&r.packet)) {
      if (v->solve != solve_ || !from_neighbour(v->message.sender, "a covariance")) continue;
      covariances_[{v->round, v->message.sender}] = v->message;
    }
    // Object lists: rendezvous data, not used by the DGS protocol.
  }
  return notes;
}

void StepInbox::takeStatus(int sender, const StatusPacket& st, IngestNotes& notes) {
  heard_.insert(sender);
  // The most advanced status; `done` is final; a restart (higher incarnation) replaces what the
  // robot reported before, a failure included.
  const auto it = latest_.find(sender);
  if (it == latest_.end()) {
    latest_.emplace(sender, st);
  } else if (st.incarnation > it->second.incarnation ||
             (!it->second.done && (st.done || st.round >= it->second.round))) {
    it->second = st;
  }
  if (st.state == RobotState::kFailed) {
    notes.lines.push_back(fmt::format("robot {} reports a failure", sender));
  }
  // A failure report is not the status of a step.
  if (IsStage(st.stage) && st.state != RobotState::kFailed && st.state != RobotState::kDone &&
      st.round > 0) {
    statuses_[sender][st.round] = st;
    stepped_.insert(sender);
  }
}

void StepInbox::takeEstimates(const EstimatesPacket& e, IngestNotes& notes) {
  const Message& m = e.message;
  std::string why;
  if (!neighbours_.count(m.sender)) {
    why = fmt::format("DGS estimates from robot {}, which is not a neighbour", m.sender);
  } else {
    for (const Key& k : m.keys) {
      if (!neighbour_keys_.count(k)) {
        why = fmt::format("DGS estimates from robot {} for {}, a variable this robot does not use",
                          m.sender, ToString(k));
        break;
      }
    }
  }
  if (!why.empty()) {
    ++notes.rejected;
    notes.lines.push_back("rejected: " + why);
    return;
  }
  estimates_[{e.round, m.sender}] = m;
}

bool StepInbox::failed(int r) const {
  const auto it = latest_.find(r);
  return it != latest_.end() && it->second.state == RobotState::kFailed;
}

bool StepInbox::done(int r) const {
  const auto it = latest_.find(r);
  return it != latest_.end() && it->second.done;
}

const StatusPacket* StepInbox::statusOf(int r, std::uint32_t s) const {
  const auto it = statuses_.find(r);
  if (it == statuses_.end()) return nullptr;
  const auto jt = it->second.find(s);
  return jt == it->second.end() ? nullptr : &jt->second;
}

bool StepInbox::neighbourOf(int r, const StatusPacket& st) const {
  return step_neighbours_.count(r) &&
         std::binary_search(st.neighbours.begin(), st.neighbours.end(), robot_);
}

std::string StepInbox::missing(int r, std::uint32_t s) const {
  const StatusPacket* st = statusOf(r, s);
  if (!st) return "status";
  const bool neighbour = neighbourOf(r, *st);
  std::vector<std::string> out;
  if (st->sent && neighbour && !estimates_.count({s, r})) out.push_back("estimates");
  if (st->coarse && !coarse_.count({s, r})) out.push_back("coarse share");
  if (st->weights && neighbour && !weights_.count({s, r})) out.push_back("weights");
  if (st->covariance && neighbour && !covariances_.count({s, r})) out.push_back("covariance");
  return fmt::format("{}", fmt::join(out, ", "));
}

TeamStep StepInbox::collect(std::uint32_t s, const std::vector<int>& others, const TeamReport& mine,
                            const CoarseMessage* share) const {
  TeamStep got;
  got.reports[robot_] = mine;
  if (share) got.shares[robot_] = *share;
  for (int r : others) {
    const std::string lacks = missing(r, s);
    if (!lacks.empty()) {
      throw InvalidInputError(
          fmt::format("step inbox: step {} of robot {} collected without its {}", s, r, lacks));
    }
    const StatusPacket& st = *statusOf(r, s);
    const bool neighbour = neighbourOf(r, st);
    got.reports[r] = ReportOf(st);
    if (st.sent && neighbour) got.estimates.push_back(estimates_.at({s, r}));
    if (st.coarse) got.shares[r] = coarse_.at({s, r});
    if (st.weights && neighbour) got.weights[r] = weights_.at({s, r});
    if (st.covariance && neighbour) got.covariances[r] = covariances_.at({s, r});
  }
  return got;
}

void StepInbox::prune(std::uint32_t s) {
  for (auto& [r, by_step] : statuses_) by_step.erase(by_step.begin(), by_step.lower_bound(s));
  estimates_.erase(estimates_.begin(), estimates_.lower_bound({s, 0}));
  coarse_.erase(coarse_.begin(), coarse_.lower_bound({s, 0}));
  weights_.erase(weights_.begin(), weights_.lower_bound({s, 0}));
  covariances_.erase(covariances_.begin(), covariances_.lower_bound({s, 0}));
}

}  // namespace moslam::transport_detail
