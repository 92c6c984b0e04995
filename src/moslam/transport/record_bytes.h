// Journal records (read and written with common/byte_io.h) and run fingerprints shared by the
// journaled protocols (dgs_node.cc, robot_session.cc). Internal to the transport module.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/geometry/se3.h"
#include "moslam/graph/key.h"

namespace moslam::transport_detail {

// A reader of a journal record's fields from `offset` to its end (the record must outlive it);
// its errors name the journal (`what`). Throws InvalidInputError when the record is shorter than
// `offset`.
inline ByteReader JournalRecordReader(const std::vector<std::uint8_t>& bytes, std::size_t offset,
                                      const std::string& what) {
  if (offset > bytes.size()) throw InvalidInputError(what + ": truncated journal record");
  return ByteReader(std::string_view(reinterpret_cast<const char*>(bytes.data()) + offset,
                                     bytes.size() - offset),
                    what + " (journal record)");
}

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
