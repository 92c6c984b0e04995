// Small RAII wrappers of the Cyclone DDS C API (dds/dds.h): each owns one entity handle and
// deletes it (with its children) when destroyed; move-only. Failures throw DdsError with the
// Cyclone return code text and what was attempted.
//
//   dds::Domain domain(7, LoopbackConfigXml(7, 4));   // optional: explicit configuration
//   dds::Participant participant(7);
//   dds::Qos qos = dds::Qos::Reliable(depth);
//   dds::Topic topic(participant, moslam_msg_dds__Status__desc, "rt/moslam/status", qos);
//   dds::Writer writer(participant, topic, qos);   writer.write(&sample);
//   dds::Reader reader(participant, topic, qos);   reader.take(max, callback);
//
// Declare parents before children so that children are deleted first.
#pragma once

#include <dds/dds.h>

#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "moslam/common/errors.h"

namespace moslam::dds {

class DdsError : public Error {
 public:
  DdsError(const std::string& what, dds_return_t code);
  dds_return_t code() const { return code_; }

 private:
  dds_return_t code_;
};

class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity() { reset(); }
  Entity(Entity&& other) noexcept : handle_(other.handle_) { other.handle_ = 0; }
  Entity& operator=(Entity&& other) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  dds_entity_t get() const { return handle_; }
  explicit operator bool() const { return handle_ > 0; }
  void reset();

 protected:
  dds_entity_t handle_ = 0;
};

// A domain created with an explicit XML configuration (instead of CYCLONEDDS_URI). Participants
// created afterwards on this domain id in this process use it.
class Domain : public Entity {
 public:
  Domain(dds_domainid_t id, const std::string& config_xml);
};

class Participant : public Entity {
 public:
  explicit Participant(dds_domainid_t domain);
};

class Qos {
 public:
  Qos();
  ~Qos();
  Qos(Qos&& other) noexcept : qos_(other.qos_) { other.qos_ = nullptr; }
  Qos& operator=(Qos&&) = delete;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;
  // Reliable, transient-local, keep-last `depth` (writer history, replayed to late joiners),
  // automatic liveliness with `lease`.
  static Qos Reliable(int depth, std::chrono::milliseconds lease);
  // As Reliable but keep-all (readers: nothing is dropped before it is taken) and ignoring the
  // samples of its own participant.
  static Qos ReliableKeepAll(std::chrono::milliseconds lease);
  const dds_qos_t* get() const { return qos_; }
  dds_qos_t* get() { return qos_; }

 private:
  dds_qos_t* qos_;
};

class Topic : public Entity {
 public:
  Topic(const Participant& participant, const dds_topic_descriptor_t& type,
        const std::string& name, const Qos& qos);
};

class Writer : public Entity {
 public:
  Writer(const Participant& participant, const Topic& topic, const Qos& qos);
  void write(const void* sample);
};

class Reader : public Entity {
 public:
  Reader(const Participant& participant, const Topic& topic, const Qos& qos);
  // Takes up to `max` samples (loaned, returned before this returns) and calls `each` with
  // every sample and its info (invalid samples included: instance state changes). Returns how
  // many were taken.
  int take(int max, const std::function<void(const void*, const dds_sample_info_t&)>& each);
};

// A wait set with a read condition (any sample state) per attached reader.
class WaitSet : public Entity {
 public:
  explicit WaitSet(const Participant& participant);
  void attach(const Reader& reader);
  // Blocks until a reader has data or `timeout` elapses; returns whether one has data.
  bool wait(std::chrono::milliseconds timeout);

 private:
  std::vector<Entity> conditions_;
};

}  // namespace moslam::dds
