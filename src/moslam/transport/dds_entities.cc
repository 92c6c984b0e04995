#include "moslam/transport/dds_entities.h"

#include <array>

namespace moslam::dds {
namespace {

dds_entity_t Check(dds_entity_t result, const std::string& what) {
  if (result < 0) throw DdsError(what, result);
  return result;
}

dds_duration_t Duration(std::chrono::milliseconds d) { return DDS_MSECS(d.count()); }

}  // namespace

DdsError::DdsError(const std::string& what, dds_return_t code)
    : Error("DDS: " + what + ": " + dds_strretcode(code)), code_(code) {}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    reset();
    handle_ = other.handle_;
    other.handle_ = 0;
  }
  return *this;
}

void Entity::reset() {
  // A child deleted with its parent already is gone: that error is expected and ignored.
  if (handle_ > 0) (void)dds_delete(handle_);
  handle_ = 0;
}

Domain::Domain(dds_domainid_t id, const std::string& config_xml)
    : Entity(Check(dds_create_domain(id, config_xml.c_str()),
                   "create domain " + std::to_string(id) +
                       " (invalid configuration, or the domain exists in this process)")) {}

Participant::Participant(dds_domainid_t domain)
    : Entity(Check(dds_create_participant(domain, nullptr, nullptr),
                   "create participant on domain " + std::to_string(domain) +
                       " (check CYCLONEDDS_URI / the network interface)")) {}

Qos::Qos() : qos_(dds_create_qos()) {}
Qos::~Qos() {
  if (qos_) dds_delete_qos(qos_);
}

namespace {

// XCDR1 only, written and accepted: Cyclone DDS 0.10.2 (Debian 12) validates an XCDR2 sequence of
// 8-byte elements against 4 bytes per element and then reads past the buffer
// (fuzz/dds_samples_fuzz.cc); a peer that offers XCDR2 is not matched.
void OnlyXcdr1(dds_qos_t* qos) {
  const dds_data_representation_id_t xcdr1[] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qset_data_representation(qos, 1, xcdr1);
}

}  // namespace

Qos Qos::Reliable(int depth, std::chrono::milliseconds lease) {
  Qos q;
  OnlyXcdr1(q.qos_);
  dds_qset_reliability(q.qos_, DDS_RELIABILITY_RELIABLE, DDS_SECS(10));
  dds_qset_durability(q.qos_, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q.qos_, DDS_HISTORY_KEEP_LAST, depth);
  // Cyclone keeps durability_service.history samples for late joiners (default: the last one).
  dds_qset_durability_service(q.qos_, 0, DDS_HISTORY_KEEP_LAST, depth, DDS_LENGTH_UNLIMITED,
                              DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  dds_qset_liveliness(q.qos_, DDS_LIVELINESS_AUTOMATIC, Duration(lease));
  return q;
}

Qos Qos::ReliableKeepAll(std::chrono::milliseconds lease) {
  Qos q;
  OnlyXcdr1(q.qos_);
  dds_qset_reliability(q.qos_, DDS_RELIABILITY_RELIABLE, DDS_SECS(10));
  dds_qset_durability(q.qos_, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q.qos_, DDS_HISTORY_KEEP_ALL, 0);
  // A participant does not read its own samples.
  dds_qset_ignorelocal(q.qos_, DDS_IGNORELOCAL_PARTICIPANT);
  dds_qset_liveliness(q.qos_, DDS_LIVELINESS_AUTOMATIC, Duration(lease));
  return q;
}

Topic::Topic(const Participant& participant, const dds_topic_descriptor_t& type,
             const std::string& name, const Qos& qos)
    : Entity(Check(dds_create_topic(participant.get(), &type, name.c_str(), qos.get(), nullptr),
                   "create topic " + name)) {}

Writer::Writer(const Participant& participant, const Topic& topic, const Qos& qos)
    : Entity(Check(dds_create_writer(participant.get(), topic.get(), qos.get(), nullptr),
                   "create writer")) {}

void Writer::write(const void* sample) {
  const dds_return_t rc = dds_write(handle_, sample);
  if (rc < 0) throw DdsError("write", rc);
}

Reader::Reader(const Participant& participant, const Topic& topic, const Qos& qos)
    : Entity(Check(dds_create_reader(participant.get(), topic.get(), qos.get(), nullptr),
                   "create reader")) {}

int Reader::take(int max, const std::function<void(const void*, const dds_sample_info_t&)>& each) {
  constexpr int kBatch = 64;
  std::array<void*, kBatch> samples{};
  std::array<dds_sample_info_t, kBatch> infos{};
  int total = 0;
  while (total < max) {
    samples.fill(nullptr);
    const int want = std::min(kBatch, max - total);
    const dds_return_t n =
        dds_take(handle_, samples.data(), infos.data(), static_cast<size_t>(want),
                 static_cast<uint32_t>(want));
    if (n < 0) throw DdsError("take", n);
    if (n == 0) break;
    try {
      for (dds_return_t i = 0; i < n; ++i) each(samples[static_cast<std::size_t>(i)], infos[static_cast<std::size_t>(i)]);
    } catch (...) {
      (void)dds_return_loan(handle_, samples.data(), n);
      throw;
    }
    (void)dds_return_loan(handle_, samples.data(), n);
    total += n;
    if (n < want) break;
  }
  return total;
}

WaitSet::WaitSet(const Participant& participant)
    : Entity(Check(dds_create_waitset(participant.get()), "create wait set")) {}

void WaitSet::attach(const Reader& reader) {
  Entity condition(Check(dds_create_readcondition(reader.get(), DDS_ANY_STATE),
                         "create read condition"));
  const dds_return_t rc = dds_waitset_attach(handle_, condition.get(), reader.get());
  if (rc < 0) throw DdsError("attach to wait set", rc);
  conditions_.push_back(std::move(condition));
}

bool WaitSet::wait(std::chrono::milliseconds timeout) {
  const dds_return_t n = dds_waitset_wait(handle_, nullptr, 0, Duration(timeout));
  if (n < 0) throw DdsError("wait", n);
  return n > 0;
}

}  // namespace moslam::dds
