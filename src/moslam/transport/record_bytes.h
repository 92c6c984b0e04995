// Journal records (read and written with common/byte_io.h) and run fingerprints shared by the
// journaled protocols (dgs_node.cc, robot_session.cc). Internal to the transport module.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/separator_consistency.h"
#include "moslam/geometry/se3.h"
#include "moslam/graph/key.h"
#include "moslam/robust/gnc.h"

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

// The first record of a journal, the same in every journaled protocol: its type byte (1), the
// protocol's 8-byte magic, the robot and the fingerprint of the run that wrote it.
inline constexpr std::uint8_t kJournalHeaderRecord = 1;
inline std::vector<std::uint8_t> JournalHeader(const char (&magic)[8], int robot,
                                               std::uint64_t fingerprint) {
  WireWriter w;
  w.u8(kJournalHeaderRecord).bytes(magic, 8).u16(static_cast<std::uint16_t>(robot)).u64(fingerprint);
  return w.take();
}
// Whether `record` is the header JournalHeader writes for these; throws InvalidInputError naming
// `what` when it is shorter.
inline bool IsJournalHeader(const std::vector<std::uint8_t>& record, const char (&magic)[8],
                            int robot, std::uint64_t fingerprint, const std::string& what) {
  ByteReader p = JournalRecordReader(record, 0, what);
  const bool header = p.u8("record type") == kJournalHeaderRecord;
  const bool ours = p.take(8, "magic") == std::string_view(magic, 8);
  return header && ours && p.u16("robot") == robot && p.u64("fingerprint") == fingerprint;
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
                   o.refinement.initial_lambda, o.refinement.max_lambda, o.refinement.min_lambda,
                   o.refinement.absolute_cost_tolerance}) {
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

// The robust solve's options a distributed solve's result depends on (dgs_node.h,
// robust_program.h): GNC, the separator check before it and the re-tests of its rejects, the
// one-to-one rule after GNC (added only when on: the fingerprints of journals written before it
// stay); none without gnc.
inline void AddRobustOptions(Fingerprint& f, const std::optional<GncOptions>& gnc,
                             const std::optional<SeparatorConsistencyOptions>& check,
                             bool retest_left_out, bool retest_groups,
                             bool one_to_one_after_gnc = false) {
  f.add(static_cast<std::uint64_t>(gnc.has_value()));
  if (!gnc) return;
  if (one_to_one_after_gnc) f.add(std::string("one-to-one after GNC"));
  for (double v : {gnc->threshold, gnc->mu_step, gnc->weight_tolerance, gnc->min_weight}) f.add(v);
  f.add(static_cast<std::uint64_t>(gnc->max_iterations));
  f.add(static_cast<std::uint64_t>(check.has_value()));
  if (check) {
    f.add(check->threshold);
    for (int v : {check->min_support, check->linked_min_support,
                  static_cast<int>(check->map_uncertainty),
                  static_cast<int>(check->one_to_one_objects), static_cast<int>(retest_left_out),
                  static_cast<int>(retest_groups)}) {
      f.add(static_cast<std::uint64_t>(v));
    }
  }
}

}  // namespace moslam::transport_detail
