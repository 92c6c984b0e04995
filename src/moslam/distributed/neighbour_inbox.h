// What a DGS agent (robot_agent.h) received from its neighbours: per stage, the latest estimate
// of each neighbour variable (by LocalGraph slot), the last iteration accepted from each sender
// and which variables came in a message flagged initialised (flagged initialisation, DGS.md, per
// variable: robot_agent.h).
//
// receive() keeps, per stage and sender, only messages newer than the last accepted (iteration
// strictly larger); duplicates and older messages (stale, reordered) are counted and ignored, as
// are messages of a stage the agent has left.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <vector>

#include "moslam/distributed/dgs_types.h"
#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/messages.h"

namespace moslam {

enum class ReceiveStatus { kAccepted, kDuplicate, kStale };

class NeighbourInbox {
 public:
  // `graph` must outlive the inbox.
  explicit NeighbourInbox(const LocalGraph& graph) : graph_(graph) {}

  // Throws InvalidInputError on a message from the robot itself, a value count that does not
  // match the keys, or a key of another robot than the sender. `left`: the message's stage is
  // one the agent has left (counted stale).
  ReceiveStatus receive(const Message& message, bool left);

  // The latest value of the neighbour variable in `slot` in `stage`, or nullptr if none arrived
  // (or it was forgotten).
  const Eigen::VectorXd* get(DgsStage stage, int slot) const;
  // The same, writable: the coarse correction moves the copies of the neighbours' variables.
  Eigen::VectorXd* mutableValue(DgsStage stage, int slot);
  // The value of the variable in `slot`, as if received.
  void set(DgsStage stage, int slot, const Eigen::VectorXd& value);
  // value += delta for the variable in `slot` (one not received counts as 0 and is then held).
  void add(DgsStage stage, int slot, const Eigen::VectorXd& delta);
  // Whether the variable in `slot` came in a message of `stage` flagged initialised (its owner
  // solved it: an agent sends only the variables it has solved once it is initialised).
  bool initialisedSlot(DgsStage stage, int slot) const;
  // Forgets the values of `stage` (not the iterations accepted).
  void forget(DgsStage stage);

  std::int64_t duplicates() const { return duplicates_; }
  std::int64_t stale() const { return stale_; }

 private:
  struct Stage {
    std::vector<Eigen::VectorXd> values;  // by slot
    std::vector<char> has;
    std::vector<char> initialised;  // by slot: carried by a message flagged initialised
    std::map<int, std::int64_t> last_iteration;
  };
  Stage& stage(DgsStage stage);

  const LocalGraph& graph_;
  std::map<DgsStage, Stage> stages_;
  std::int64_t duplicates_ = 0, stale_ = 0;
};

}  // namespace moslam
