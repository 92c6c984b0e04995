// Little-endian journal records and run fingerprints shared by the journaled protocols
// (dgs_node.cc, robot_session.cc). Internal to the transport module.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/geometry/se3.h"
#include "moslam/graph/key.h"

namespace moslam::transport_detail {

// Appends little-endian integers and length-prefixed byte strings.
class RecordWriter {
 public:
  RecordWriter& u8(std::uint8_t v) { return le(v, 1); }
  RecordWriter& u16(std::uint16_t v) { return le(v, 2); }
  RecordWriter& u32(std::uint32_t v) { return le(v, 4); }
  RecordWriter& u64(std::uint64_t v) { return le(v, 8); }
  RecordWriter& f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    return le(bits, 8);
  }
  RecordWriter& raw(const std::vector<std::uint8_t>& v) {
    u32(static_cast<std::uint32_t>(v.size()));
    b_.insert(b_.end(), v.begin(), v.end());
    return *this;
  }
  std::vector<std::uint8_t>& data() { return b_; }

 private:
  RecordWriter& le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
    return *this;
  }
  std::vector<std::uint8_t> b_;
};

// The fields of a record from `offset` (just after its type byte) to the end; throws
// InvalidInputError "<what>: truncated journal record" when the record is shorter.
inline std::vector<std::uint8_t> RecordBody(const std::vector<std::uint8_t>& bytes,
                                            std::size_t offset, const std::string& what) {
  if (offset > bytes.size()) throw InvalidInputError(what + ": truncated journal record");
  return {bytes.begin() + static_cast<std::ptrdiff_t>(offset), bytes.end()};
}

// Reads what RecordWriter wrote; throws InvalidInputError "<what>: truncated journal record".
class RecordReader {
 public:
  RecordReader(const std::vector<std::uint8_t>& b, std::string what)
      : b_(b), what_(std::move(what)) {}
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  double f64() {
    const std::uint64_t bits = le(8);
    double v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  std::vector<std::uint8_t> raw() {
    const std::uint32_t n = u32();
    need(n);
    std::vector<std::uint8_t> v(b_.begin() + static_cast<std::ptrdiff_t>(pos_),
                                b_.begin() + static_cast<std::ptrdiff_t>(pos_ + n));
    pos_ += n;
    return v;
  }
  bool atEnd() const { return pos_ == b_.size(); }

 private:
  void need(std::size_t n) const {
    if (b_.size() - pos_ < n) throw InvalidInputError(what_ + ": truncated journal record");
  }
  std::uint64_t le(int n) {
    need(static_cast<std::size_t>(n));
    std::uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= std::uint64_t{b_[pos_ + static_cast<std::size_t>(i)]} << (8 * i);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  const std::vector<std::uint8_t>& b_;
  std::string what_;
  std::size_t pos_ = 0;
};

// FNV-1a over what a run depends on: a journal is only replayed by the run that wrote it.
class Fingerprint {
 public:
  void add(const void* data, std::size_t n) { h_ = Fnv1a64(data, n, h_); }
  void add(double v) { add(&v, sizeof v); }
  void add(std::uint64_t v) { add(&v, sizeof v); }
  void add(const std::string& s) {
    add(static_cast<std::uint64_t>(s.size()));
    add(s.data(), s.size());
  }
  void add(const Key& k) {
    add(static_cast<std::uint64_t>(k.robot));
    add(static_cast<std::uint64_t>(k.kind));
    add(k.index);
  }
  void add(const SE3& x) {
    const Matrix3& R = x.rotation().matrix();
    for (int i = 0; i < 9; ++i) add(R(i));
    for (int i = 0; i < 3; ++i) add(x.translation()(i));
  }
  void add(const Matrix6& m) {
    for (int i = 0; i < 36; ++i) add(m(i));
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = kFnvOffset;
};

// The solver options a distributed solve's result depends on.
inline void AddSolverOptions(Fingerprint& f, const DgsOptions& o) {
  for (double v : {o.eta_rotation, o.eta_pose, o.gamma, o.refinement.relative_cost_tolerance,
                   o.refinement.sweep_tolerance, o.refinement.cg_tolerance, o.refinement.gamma,
                   o.refinement.initial_lambda, o.refinement.max_lambda}) {
    f.add(v);
  }
  for (int v : {o.max_iterations, o.error_bound_window, static_cast<int>(o.stopping),
                static_cast<int>(o.pose_solver), static_cast<int>(o.flagged_initialisation),
                static_cast<int>(o.weight_by_information), static_cast<int>(o.coarse_correction),
                static_cast<int>(o.refine), static_cast<int>(o.refinement.solver),
                static_cast<int>(o.refinement.preconditioner), o.refinement.max_iterations,
                o.refinement.max_sweeps}) {
    f.add(static_cast<std::uint64_t>(v));
  }
}

}  // namespace moslam::transport_detail
