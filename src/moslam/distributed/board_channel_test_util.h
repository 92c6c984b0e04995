// A TeamChannel for tests (not part of the library): a team of robot programs, one thread per
// robot, over a shared in-memory board. Every robot's step s completes once all robots have
// posted their step s; what it returns went through the binary encodings (the bytes a network
// carries). A robot whose program throws calls abort(why): the others' waits then throw
// TeamAborted instead of waiting for its step forever, and failure() is the first why.
#pragma once

#include <condition_variable>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "moslam/distributed/messages.h"
#include "moslam/distributed/robot_program.h"

namespace moslam::test {

// What a robot's step throws once another robot aborted the board.
struct TeamAborted : std::runtime_error {
  TeamAborted() : std::runtime_error("another robot of the team failed") {}
};

class SharedBoard {
 public:
  explicit SharedBoard(int robots) : robots_(robots) {}

  // Called by a robot whose program failed: every wait, now and later, throws TeamAborted.
  void abort(const std::string& why) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!aborted_) failure_ = why;
    aborted_ = true;
    changed_.notify_all();
  }
  // The first abort's why ("" when none).
  std::string failure() {
    std::lock_guard<std::mutex> lock(mutex_);
    return failure_;
  }

  TeamStep post(int robot, std::size_t s, const std::vector<OutgoingMessage>& out,
                const TeamReport& report, const CoarseMessage* share,
                const std::vector<WeightMessage>& weights,
                const std::vector<CovarianceMessage>& covariances) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (aborted_) throw TeamAborted();
    Round& round = rounds_[s];
    for (const CovarianceMessage& c : covariances) {
      round.covariances[c.receiver][robot] =
          DecodeCovarianceMessage(EncodeCovarianceMessage(c));
    }
    for (const OutgoingMessage& o : out) round.inbox[o.to].push_back(o.message);
    for (const WeightMessage& w : weights) {
      round.weights[w.receiver][robot] = DecodeWeightMessage(EncodeWeightMessage(w));
    }
    round.reports[robot] = report;
    if (share) round.shares[robot] = DecodeCoarseMessage(EncodeCoarseMessage(*share));
    if (static_cast<int>(round.reports.size()) == robots_) changed_.notify_all();
    changed_.wait(lock,
                  [&]() { return aborted_ || static_cast<int>(round.reports.size()) == robots_; });
    if (aborted_) throw TeamAborted();
    TeamStep got;
    for (const Message& m : round.inbox[robot]) {
      got.estimates.push_back(DecodeMessage(EncodeMessage(m)));
    }
    got.reports = round.reports;
    got.shares = round.shares;
    got.weights = round.weights[robot];
    got.covariances = round.covariances[robot];
    return got;
  }

 private:
  struct Round {
    std::map<int, std::vector<Message>> inbox;
    std::map<int, TeamReport> reports;
    std::map<int, CoarseMessage> shares;
    std::map<int, std::map<int, WeightMessage>> weights;  // receiver -> sender -> message
    std::map<int, std::map<int, CovarianceMessage>> covariances;  // alike
  };
  int robots_;
  bool aborted_ = false;
  std::string failure_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::size_t, Round> rounds_;
};

class BoardChannel : public TeamChannel {
 public:
  BoardChannel(SharedBoard& board, int robot) : board_(board), robot_(robot) {}
  TeamStep step(DgsStage, const std::vector<OutgoingMessage>& estimates, const TeamReport& report,
                const CoarseMessage* share, const std::vector<WeightMessage>& weights,
                const std::vector<CovarianceMessage>& covariances) override {
    ++steps_;
    return board_.post(robot_, steps_ - 1, estimates, report, share, weights, covariances);
  }
  std::set<int> absent() const override { return {}; }
  std::size_t steps() const { return steps_; }

 private:
  SharedBoard& board_;
  int robot_;
  std::size_t steps_ = 0;
};

}  // namespace moslam::test
