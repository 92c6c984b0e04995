#include "moslam/transport/dgs_node.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <tuple>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/robot_agent.h"
#include "moslam/io/g2o.h"
#include "moslam/transport/journal.h"
#include "moslam/transport/record_bytes.h"

namespace moslam {

void DgsNodeOptions::validate() const {
  DriverOptions(*this).validate();
  auto positive = [](std::chrono::milliseconds v, const char* name) {
    if (v.count() <= 0) {
      throw InvalidInputError(std::string("DGS node options: ") + name + " must be positive");
    }
  };
  positive(join_timeout, "join_timeout");
  positive(leave_timeout, "leave_timeout");
  positive(stall_timeout, "stall_timeout");
  positive(finish_timeout, "finish_timeout");
}

DgsOptions DriverOptions(const DgsNodeOptions& o) {
  DgsOptions d;
  d.eta_rotation = o.eta_rotation;
  d.eta_pose = o.eta_pose;
  d.gamma = o.gamma;
  d.order = SweepOrder::kJacobi;
  d.max_iterations = o.max_iterations;
  d.flagged_initialisation = o.flagged_initialisation;
  d.weight_by_information = o.weight_by_information;
  return d;
}

namespace {

using Clock = std::chrono::steady_clock;
constexpr char kJournalMagic[8] = {'M', 'O', 'S', 'L', 'J', 'N', 'L', '1'};

enum class RecordType : std::uint8_t {
  kHeader = 1,    // magic, robot, fingerprint
  kStart = 2,     // a process start
  kTeam = 3,      // the team's robots
  kRound = 4,     // stage, round, the estimates delivered (round 0: the stage starts)
  kLeft = 5,      // a robot left: robot, stage, round
  kStageEnd = 6,  // stage, rounds, converged
  kDone = 7,      // finished
};

using transport_detail::Fingerprint;
using Bytes = transport_detail::RecordWriter;
using Parse = transport_detail::RecordReader;

std::uint64_t RunFingerprint(int robot, const PoseGraph& g, const Values& initial,
                             const DgsNodeOptions& o) {
  Fingerprint f;
  f.add(static_cast<std::uint64_t>(robot));
  f.add(o.eta_rotation);
  f.add(o.eta_pose);
  f.add(o.gamma);
  f.add(static_cast<std::uint64_t>(o.max_iterations));
  f.add(static_cast<std::uint64_t>(o.flagged_initialisation) * 2 +
        static_cast<std::uint64_t>(o.weight_by_information));
  for (const RelativePoseFactor& factor : g.factors()) {
    f.add(factor.a());
    f.add(factor.b());
    f.add(factor.measured());
    f.add(factor.information());
  }
  for (const PriorFactor& p : g.priors()) {
    f.add(p.key());
    f.add(p.prior());
    f.add(p.information());
  }
  for (const auto& [k, x] : initial) {
    if (k.robot != robot) continue;
    f.add(k);
    f.add(x);
  }
  return f.value();
}

bool IsStage(std::uint8_t s) { return s >= 1 && s <= 2; }

}  // namespace

class DgsNode::Impl {
 public:
  Impl(int robot, PoseGraph subgraph, Values initial, Transport& transport,
       DgsNodeOptions options)
      : robot_(robot),
        subgraph_(std::move(subgraph)),
        initial_(std::move(initial)),
        transport_(transport),
        options_(std::move(options)) {
    options_.validate();
    if (transport_.self() != robot_) {
      throw InvalidInputError(fmt::format("DGS node: robot {} given the transport of robot {}",
                                          robot_, transport_.self()));
    }
    // The anchor (first pose of robot 0) matters only to its owner; the others pass a key of
    // robot 0 they do not own.
    const Key anchor = robot_ == 0 ? GaugeAnchor(subgraph_) : Key::Pose(0, 0);
    AgentOptions ao;
    ao.gamma = options_.gamma;
    ao.flagged_initialisation = options_.flagged_initialisation;
    ao.weight_by_information = options_.weight_by_information;
    agent_ = std::make_unique<RobotAgent>(robot_, subgraph_, initial_, anchor, ao);
    neighbours_ = agent_->neighbourRobots();
    neighbour_keys_ = agent_->neighbourVariables();
    // Snapshots of a graph with object landmarks use the g2o key scheme with objects.
    for (const Key& k : subgraph_.keys()) {
      if (k.isObject()) g2o_options_.scheme = KeyScheme::kWithObjects;
    }
    if (!options_.state_dir.empty()) {
      std::filesystem::create_directories(options_.state_dir);
      journal_ = std::make_unique<Journal>(
          (std::filesystem::path(options_.state_dir) / "journal.bin").string());
    }
    restore();
  }

  DgsNodeResult run() {
    if (ran_) throw InvalidInputError("DGS node: run() is called once");
    ran_ = true;
    const auto t0 = Clock::now();
    try {
      if (journal_) journal_->append(Bytes().u8(static_cast<std::uint8_t>(RecordType::kStart)).data());
      if (team_.empty()) formTeam();
      transport_.setKnownRobots(team_);
      for (int r : team_) {
        if (r != robot_ && !left_.count(r)) live_.insert(r);
      }
      if (!in_stage_) startStage(DgsStage::kRotation, true);
      announce();
      if (!finished_) runStages();
      saveResult();
      waitForPeers();
    } catch (const std::exception&) {
      StatusPacket st = status();
      st.state = RobotState::kFailed;
      try {
        transport_.publish(st);
      } catch (const std::exception&) {
      }
      throw;
    }
    result_.estimate = agent_->estimate();
    result_.team.assign(team_.begin(), team_.end());
    result_.left.assign(left_.begin(), left_.end());
    result_.transport = transport_.stats();
    result_.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return result_;
  }

 private:
  void log(const std::string& text) const {
    fmt::print(stderr, "moslam robot {}: {}\n", robot_, text);
    std::fflush(stderr);
  }

  // ---- persistence ----------------------------------------------------------------------
  void restore() {
    const std::uint64_t fingerprint = RunFingerprint(robot_, subgraph_, initial_, options_);
    if (!journal_) return;
    result_.journal_truncated_bytes = journal_->truncatedBytes();
    const auto& records = journal_->records();
    if (records.empty()) {
      Bytes b;
      b.u8(static_cast<std::uint8_t>(RecordType::kHeader));
      for (char c : kJournalMagic) b.u8(static_cast<std::uint8_t>(c));
      b.u16(static_cast<std::uint16_t>(robot_)).u64(fingerprint);
      journal_->append(b.data());
      return;
    }
    const std::string what = journal_->path();
    for (std::size_t i = 0; i < records.size(); ++i) {
      Parse p(records[i], what);
      const auto type = static_cast<RecordType>(p.u8());
      if (i == 0) {
        char magic[8];
        for (char& c : magic) c = static_cast<char>(p.u8());
        const int robot = p.u16();
        const std::uint64_t fp = p.u64();
        if (type != RecordType::kHeader || std::memcmp(magic, kJournalMagic, 8) != 0 ||
            robot != robot_ || fp != fingerprint) {
          throw InvalidInputError(
              "state directory " + options_.state_dir +
              " holds the journal of another run (other robot, data or options): remove it or "
              "choose another --out");
        }
        continue;
      }
      switch (type) {
        case RecordType::kStart:
          ++result_.incarnation;
          break;
        case RecordType::kTeam: {
          const int n = p.u16();
          for (int k = 0; k < n; ++k) team_.insert(p.u16());
          break;
        }
        case RecordType::kRound: {
          const std::uint8_t stage = p.u8();
          const std::uint32_t round = p.u32();
          const std::uint32_t count = p.u32();
          if (!IsStage(stage)) throw InvalidInputError(what + ": bad stage in a round record");
          std::vector<Message> messages;
          for (std::uint32_t k = 0; k < count; ++k) messages.push_back(DecodeMessage(p.raw()));
          if (round == 0) {
            startStage(static_cast<DgsStage>(stage), false, messages);
          } else {
            if (!in_stage_ || static_cast<std::uint8_t>(stage_) != stage || round != round_ + 1) {
              throw InvalidInputError(what + ": round records out of sequence");
            }
            applyRound(messages, false);
            ++result_.replayed_rounds;
          }
          break;
        }
        case RecordType::kLeft: {
          const int r = p.u16();
          left_.insert(r);
          (void)p.u8();
          (void)p.u32();
          break;
        }
        case RecordType::kStageEnd: {
          const std::uint8_t stage = p.u8();
          const std::uint32_t rounds = p.u32();
          const bool converged = p.u8() != 0;
          noteStageEnd(static_cast<DgsStage>(stage), rounds, converged);
          break;
        }
        case RecordType::kDone:
          agent_->finish();
          finished_ = true;
          break;
        default:
          throw InvalidInputError(what + ": unknown journal record type " +
                                  std::to_string(static_cast<int>(type)));
      }
    }
    if (result_.replayed_rounds > 0 || finished_) {
      log(fmt::format("restart {}: replayed {} rounds from {} ({}{})", result_.incarnation,
                      result_.replayed_rounds, journal_->path(),
                      finished_ ? "finished" : ToString(stage_) + " round " + std::to_string(round_),
                      journal_->truncatedBytes() ? ", torn tail cut" : ""));
    }
  }

  void record(std::vector<std::uint8_t>& payload) {
    if (journal_) journal_->append(payload);
  }

  void snapshot(bool force) {
    if (options_.state_dir.empty()) return;
    const auto now = Clock::now();
    if (!force && now - last_snapshot_ < std::chrono::seconds(1)) return;
    last_snapshot_ = now;
    const std::filesystem::path dir(options_.state_dir);
    const auto tmp = dir / "estimate.g2o.tmp";
    WriteG2oFile(tmp.string(), subgraph_, agent_->estimate(), g2o_options_);
    std::filesystem::rename(tmp, dir / "estimate.g2o");
  }

  void saveResult() {
    if (options_.state_dir.empty()) return;
    snapshot(true);
    const std::filesystem::path dir(options_.state_dir);
    const auto tmp = dir / "result.g2o.tmp";
    WriteG2oFile(tmp.string(), subgraph_, agent_->estimate(), g2o_options_);
    std::filesystem::rename(tmp, dir / "result.g2o");
  }

  // ---- protocol ---------------------------------------------------------------------------
  StatusPacket status() const {
    StatusPacket st;
    st.robot = robot_;
    st.incarnation = result_.incarnation;
    st.neighbours.assign(neighbours_.begin(), neighbours_.end());
    if (!in_stage_) return st;  // joining
    st.state = finished_ ? RobotState::kDone
                         : (stage_ == DgsStage::kRotation ? RobotState::kRotation
                                                          : RobotState::kPose);
    st.stage = static_cast<std::uint8_t>(stage_);
    st.round = round_;
    st.iteration = static_cast<std::uint32_t>(agent_->iteration());
    st.sent = sent_;
    st.initialised = agent_->initialised();
    st.done = finished_;
    st.change = agent_->initialised() ? agent_->lastChange()
                                      : std::numeric_limits<double>::infinity();
    return st;
  }

  // Publishes this round's estimates (if it sent any) and status.
  void announce() {
    if (sent_ && !finished_) {
      for (const OutgoingMessage& o : agent_->outgoing()) {
        EstimatesPacket p;
        p.receiver = o.to;
        p.round = round_;
        p.message = o.message;
        transport_.send(p);
        ++result_.estimate_messages;
        result_.estimate_binary_bytes += static_cast<std::int64_t>(EncodeMessage(p.message).size());
      }
    }
    transport_.publish(status());
  }

  void formTeam() {
    const auto deadline = Clock::now() + options_.join_timeout;
    transport_.publish(status());
    std::set<int> known = neighbours_;
    known.insert(robot_);
    heard_.insert(robot_);
    while (true) {
      ingest(transport_.poll(std::chrono::milliseconds(50)));
      // The closure: robots heard from add their neighbours, until nothing changes.
      for (bool grew = true; grew;) {
        grew = false;
        for (int r : std::vector<int>(known.begin(), known.end())) {
          const auto it = latest_.find(r);
          if (it == latest_.end()) continue;
          for (int n : it->second.neighbours) grew = known.insert(n).second || grew;
        }
      }
      std::vector<int> missing;
      for (int r : known) {
        if (!heard_.count(r)) missing.push_back(r);
      }
      if (missing.empty()) break;
      if (Clock::now() > deadline) {
        throw Error(fmt::format("robot {}: the team did not form within {} ms: no status from "
                                "robot(s) {} (not started, or not reachable over the network)",
                                robot_, options_.join_timeout.count(), fmt::join(missing, ", ")));
      }
    }
    if (!known.count(0)) {
      throw UnderdeterminedError(fmt::format(
          "robot {}: its team {} has no robot 0, whose first pose fixes the gauge", robot_,
          fmt::join(known, ", ")));
    }
    team_ = known;
    Bytes b;
    b.u8(static_cast<std::uint8_t>(RecordType::kTeam)).u16(static_cast<std::uint16_t>(team_.size()));
    for (int r : team_) b.u16(static_cast<std::uint16_t>(r));
    record(b.data());
    log(fmt::format("team of {}: robots {}", team_.size(), fmt::join(team_, ", ")));
  }

  // `last`: the estimates of the previous stage's last round, delivered before the stage starts
  // (the driver delivers them at the end of that sweep: startPose() projects them).
  void startStage(DgsStage stage, bool write, const std::vector<Message>& last = {}) {
    if (write) {
      Bytes b;
      b.u8(static_cast<std::uint8_t>(RecordType::kRound))
          .u8(static_cast<std::uint8_t>(stage))
          .u32(0)
          .u32(static_cast<std::uint32_t>(last.size()));
      for (const Message& m : last) b.raw(EncodeMessage(m));
      record(b.data());
    }
    for (const Message& m : last) agent_->receive(m);
    if (stage == DgsStage::kRotation) {
      agent_->startRotation();
    } else {
      agent_->startPose();
    }
    in_stage_ = true;
    stage_ = stage;
    round_ = 0;
    sent_ = !options_.flagged_initialisation;
    if (options_.on_round) options_.on_round({stage_, 0, sent_, 0.0, !write});
  }

  void noteStageEnd(DgsStage stage, std::uint32_t rounds, bool converged) {
    if (stage == DgsStage::kRotation) {
      result_.rotation_rounds = static_cast<int>(rounds);
      result_.rotation_converged = converged;
    } else {
      result_.pose_rounds = static_cast<int>(rounds);
      result_.pose_converged = converged;
    }
  }

  // Delivers the previous round's estimates, solves once.
  void applyRound(const std::vector<Message>& messages, bool write) {
    if (write) {
      Bytes b;
      b.u8(static_cast<std::uint8_t>(RecordType::kRound))
          .u8(static_cast<std::uint8_t>(stage_))
          .u32(round_ + 1)
          .u32(static_cast<std::uint32_t>(messages.size()));
      for (const Message& m : messages) b.raw(EncodeMessage(m));
      record(b.data());
    }
    for (const Message& m : messages) agent_->receive(m);
    sent_ = agent_->iterate();
    ++round_;
    if (options_.on_round) {
      options_.on_round({stage_, round_, sent_,
                         agent_->initialised() ? agent_->lastChange()
                                               : std::numeric_limits<double>::infinity(),
                         !write});
    }
  }

  static std::pair<int, std::uint32_t> at(const StatusPacket& s) {
    return {s.stage, s.round};
  }

  void ingest(std::vector<Received> packets) {
    for (Received& r : packets) {
      if (auto* st = std::get_if<StatusPacket>(&r.packet)) {
        heard_.insert(r.sender);
        // The most advanced status; `done` is final; a restarted robot's re-announcement (same
        // round) replaces a failure it reported before.
        const auto it = latest_.find(r.sender);
        if (it == latest_.end()) {
          latest_.emplace(r.sender, *st);
        } else if (!it->second.done && (st->done || at(*st) >= at(it->second))) {
          it->second = *st;
        }
        if (st->state == RobotState::kFailed) {
          log(fmt::format("robot {} reports a failure", r.sender));
        }
        // A failure report is not the status of a round.
        if (IsStage(st->stage) && st->state != RobotState::kFailed) {
          statuses_[r.sender].emplace(at(*st), *st);
        }
      } else if (auto* e = std::get_if<EstimatesPacket>(&r.packet)) {
        const Message& m = e->message;
        std::string why;
        if (!neighbours_.count(m.sender)) {
          why = fmt::format("DGS estimates from robot {}, which is not a neighbour", m.sender);
        } else {
          for (const Key& k : m.keys) {
            if (!neighbour_keys_.count(k)) {
              why = fmt::format("DGS estimates from robot {} for {}, a variable this robot does "
                                "not use",
                                m.sender, ToString(k));
              break;
            }
          }
        }
        if (!why.empty()) {
          ++result_.rejected_estimates;
          log("rejected: " + why);
          continue;
        }
        if (!IsStage(static_cast<std::uint8_t>(m.stage))) continue;  // refinement: not here
        inbox_.emplace(std::make_tuple(static_cast<int>(m.stage), e->round, m.sender), m);
      }
      // Object lists: rendezvous data, not used by the DGS protocol.
    }
  }

  // Has `r` decided past `stage` (a later stage, done)?
  bool movedOn(int r, DgsStage stage) const {
    const auto it = latest_.find(r);
    if (it == latest_.end()) return false;
    const StatusPacket& s = it->second;
    return s.done || s.stage > static_cast<std::uint8_t>(stage);
  }
  // A robot that reported a failure counts as not alive (it may be restarted).
  bool failed(int r) const {
    const auto it = latest_.find(r);
    return it != latest_.end() && it->second.state == RobotState::kFailed;
  }

  const StatusPacket* statusOf(int r, std::uint32_t round) const {
    const auto it = statuses_.find(r);
    if (it == statuses_.end()) return nullptr;
    const auto jt = it->second.find({static_cast<int>(stage_), round});
    return jt == it->second.end() ? nullptr : &jt->second;
  }

  bool expectsEstimates(int r, const StatusPacket& s) const {
    return s.sent && neighbours_.count(r) &&
           std::binary_search(s.neighbours.begin(), s.neighbours.end(), robot_);
  }

  // The robots the current round still waits for.
  std::vector<int> waitingFor() const {
    std::vector<int> out;
    for (int r : live_) {
      const StatusPacket* s = statusOf(r, round_);
      if (s) {
        if (expectsEstimates(r, *s) &&
            !inbox_.count(std::make_tuple(static_cast<int>(stage_), round_, r))) {
          out.push_back(r);
        }
      } else if (!movedOn(r, stage_)) {
        out.push_back(r);
      }
    }
    return out;
  }

  bool converged() const {
    if (round_ == 0) return false;
    const double eta =
        stage_ == DgsStage::kRotation ? options_.eta_rotation : options_.eta_pose;
    const StatusPacket mine = status();
    bool ok = mine.initialised && mine.change <= eta;
    for (int r : live_) {
      const StatusPacket* s = statusOf(r, round_);
      if (s) ok = ok && s->initialised && s->change <= eta;
    }
    return ok;
  }

  void runStages() {
    auto last_progress = Clock::now();
    std::map<int, Clock::time_point> not_alive_since;
    while (true) {
      // Wait for the round's statuses and estimates.
      while (true) {
        const std::vector<int> waiting = waitingFor();
        if (waiting.empty()) break;
        ingest(transport_.poll(std::chrono::milliseconds(100)));
        const auto now = Clock::now();
        const std::set<int> alive = transport_.alive();
        for (int r : waiting) {
          if (alive.count(r) && !failed(r)) {
            not_alive_since.erase(r);
            continue;
          }
          const auto [it, inserted] = not_alive_since.emplace(r, now);
          if (now - it->second >= options_.leave_timeout) {
            log(fmt::format("robot {} left ({} round {}): continuing without it", r,
                            ToString(stage_), round_));
            live_.erase(r);
            left_.insert(r);
            record(Bytes()
                       .u8(static_cast<std::uint8_t>(RecordType::kLeft))
                       .u16(static_cast<std::uint16_t>(r))
                       .u8(static_cast<std::uint8_t>(stage_))
                       .u32(round_)
                       .data());
          }
        }
        if (now - last_progress > options_.stall_timeout) {
          throw Error(fmt::format("robot {}: no progress for {} ms in {} round {}, waiting for "
                                  "robot(s) {}",
                                  robot_, options_.stall_timeout.count(), ToString(stage_),
                                  round_, fmt::join(waiting, ", ")));
        }
      }
      last_progress = Clock::now();

      const bool done_converged = converged();
      if (done_converged || round_ >= static_cast<std::uint32_t>(options_.max_iterations)) {
        record(Bytes()
                   .u8(static_cast<std::uint8_t>(RecordType::kStageEnd))
                   .u8(static_cast<std::uint8_t>(stage_))
                   .u32(round_)
                   .u8(done_converged ? 1 : 0)
                   .data());
        noteStageEnd(stage_, round_, done_converged);
        snapshot(true);
        if (stage_ == DgsStage::kRotation) {
          for (auto& [r, by_round] : statuses_) {
            by_round.erase(by_round.begin(), by_round.lower_bound({static_cast<int>(DgsStage::kPose), 0}));
          }
          startStage(DgsStage::kPose, true, takeRoundMessages());
          announce();
          continue;
        }
        record(Bytes().u8(static_cast<std::uint8_t>(RecordType::kDone)).data());
        agent_->finish();
        finished_ = true;
        announce();
        return;
      }

      applyRound(takeRoundMessages(), true);
      announce();
      snapshot(false);
      // Statuses older than the previous round are no longer needed.
      for (auto& [r, by_round] : statuses_) {
        by_round.erase(by_round.begin(),
                       by_round.lower_bound({static_cast<int>(stage_), round_ > 0 ? round_ - 1 : 0}));
      }
    }
  }

  // The estimates of the current round (by sender), removed from the inbox with older ones.
  std::vector<Message> takeRoundMessages() {
    std::vector<Message> messages;
    for (auto it = inbox_.begin(); it != inbox_.end();) {
      const auto& [stage, round, sender] = it->first;
      if (stage < static_cast<int>(stage_) ||
          (stage == static_cast<int>(stage_) && round < round_)) {
        it = inbox_.erase(it);  // late (a robot that left): the agent moved on
        continue;
      }
      if (stage == static_cast<int>(stage_) && round == round_) {
        messages.push_back(std::move(it->second));
        it = inbox_.erase(it);
        continue;
      }
      ++it;
    }
    return messages;
  }

  void waitForPeers() {
    const auto deadline = Clock::now() + options_.finish_timeout;
    std::map<int, Clock::time_point> not_alive_since;
    while (Clock::now() < deadline) {
      std::vector<int> pending;
      const std::set<int> alive = transport_.alive();
      const auto now = Clock::now();
      for (int r : live_) {
        const auto it = latest_.find(r);
        if (it != latest_.end() && it->second.done) continue;
        if (!alive.count(r) || failed(r)) {
          const auto [jt, inserted] = not_alive_since.emplace(r, now);
          if (now - jt->second >= options_.leave_timeout) continue;  // gone
        } else {
          not_alive_since.erase(r);
        }
        pending.push_back(r);
      }
      if (pending.empty()) return;
      ingest(transport_.poll(std::chrono::milliseconds(100)));
    }
    log("finish: not every robot reported done before the finish timeout");
  }

  int robot_;
  PoseGraph subgraph_;
  Values initial_;
  Transport& transport_;
  DgsNodeOptions options_;
  std::unique_ptr<RobotAgent> agent_;
  std::set<int> neighbours_;
  std::set<Key> neighbour_keys_;
  std::unique_ptr<Journal> journal_;
  G2oWriteOptions g2o_options_;

  std::set<int> team_, live_, left_, heard_;
  bool in_stage_ = false;
  DgsStage stage_ = DgsStage::kRotation;
  std::uint32_t round_ = 0;
  bool sent_ = false;
  bool finished_ = false;
  bool ran_ = false;

  std::map<int, StatusPacket> latest_;  // per robot: its most advanced status
  std::map<int, std::map<std::pair<int, std::uint32_t>, StatusPacket>> statuses_;
  std::map<std::tuple<int, std::uint32_t, int>, Message> inbox_;  // (stage, round, sender)
  Clock::time_point last_snapshot_{};
  DgsNodeResult result_;
};

DgsNode::DgsNode(int robot, PoseGraph subgraph, Values initial, Transport& transport,
                 DgsNodeOptions options)
    : impl_(std::make_unique<Impl>(robot, std::move(subgraph), std::move(initial), transport,
                                   std::move(options))) {}

DgsNode::~DgsNode() = default;

DgsNodeResult DgsNode::run() { return impl_->run(); }

}  // namespace moslam
