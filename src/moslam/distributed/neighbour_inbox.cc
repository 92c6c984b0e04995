#include "moslam/distributed/neighbour_inbox.h"

#include <algorithm>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

NeighbourInbox::Stage& NeighbourInbox::stage(DgsStage stage) {
  Stage& box = stages_[stage];
  const std::size_t n = graph_.neighbours().size();
  if (box.values.size() != n) {
    box.values.assign(n, Eigen::VectorXd::Zero(StageDimension(stage)));
    box.has.assign(n, 0);
    box.initialised.assign(n, 0);
  }
  return box;
}

ReceiveStatus NeighbourInbox::receive(const Message& m, bool left) {
  const int robot = graph_.robot();
  if (m.sender == robot) {
    throw InvalidInputError("DGS robot " + std::to_string(robot) + ": message from itself");
  }
  const int dim = StageDimension(m.stage);
  if (m.values.size() != m.keys.size() * static_cast<std::size_t>(dim)) {
    throw InvalidInputError("DGS robot " + std::to_string(robot) + ": message from robot " +
                            std::to_string(m.sender) + " has " + std::to_string(m.values.size()) +
                            " values for " + std::to_string(m.keys.size()) + " keys");
  }
  for (const Key& k : m.keys) {
    if (k.robot != m.sender) {
      throw InvalidInputError("DGS robot " + std::to_string(robot) + ": message from robot " +
                              std::to_string(m.sender) + " carries " + ToString(k) +
                              ", another robot's variable");
    }
  }
  Stage& box = stage(m.stage);
  const auto last = box.last_iteration.find(m.sender);
  const std::int64_t last_iteration = last == box.last_iteration.end() ? -1 : last->second;
  if (!left && static_cast<std::int64_t>(m.iteration) == last_iteration) {
    ++duplicates_;
    return ReceiveStatus::kDuplicate;
  }
  if (left || static_cast<std::int64_t>(m.iteration) < last_iteration) {
    ++stale_;
    return ReceiveStatus::kStale;
  }
  box.last_iteration[m.sender] = m.iteration;
  for (std::size_t i = 0; i < m.keys.size(); ++i) {
    const int slot = graph_.slot(m.keys[i]);
    if (slot < 0) continue;  // a variable this robot does not need
    const auto j = static_cast<std::size_t>(slot);
    box.values[j] = Eigen::Map<const Eigen::VectorXd>(m.entry(i), dim);
    box.has[j] = 1;
    if (m.initialised) box.initialised[j] = 1;
  }
  return ReceiveStatus::kAccepted;
}

const Eigen::VectorXd* NeighbourInbox::get(DgsStage stage, int slot) const {
  const auto it = stages_.find(stage);
  if (it == stages_.end() || it->second.has.empty()) return nullptr;
  const auto j = static_cast<std::size_t>(slot);
  return it->second.has[j] ? &it->second.values[j] : nullptr;
}

Eigen::VectorXd* NeighbourInbox::mutableValue(DgsStage s, int slot) {
  Stage& box = stage(s);
  const auto j = static_cast<std::size_t>(slot);
  return box.has[j] ? &box.values[j] : nullptr;
}

void NeighbourInbox::set(DgsStage s, int slot, const Eigen::VectorXd& value) {
  Stage& box = stage(s);
  const auto j = static_cast<std::size_t>(slot);
  box.values[j] = value;
  box.has[j] = 1;
}

void NeighbourInbox::add(DgsStage s, int slot, const Eigen::VectorXd& delta) {
  Stage& box = stage(s);
  const auto j = static_cast<std::size_t>(slot);
  if (!box.has[j]) {
    box.values[j].setZero();
    box.has[j] = 1;
  }
  box.values[j] += delta;
}

bool NeighbourInbox::initialisedSlot(DgsStage stage, int slot) const {
  const auto it = stages_.find(stage);
  return it != stages_.end() && !it->second.initialised.empty() &&
         it->second.initialised[static_cast<std::size_t>(slot)] != 0;
}

void NeighbourInbox::forget(DgsStage s) {
  Stage& box = stage(s);
  std::fill(box.has.begin(), box.has.end(), 0);
}

}  // namespace moslam
