// Perceived runs kept on disk (`moslam simulate --perception rendered --perception-cache DIR`).
// The front-end on rendered frames takes minutes per run where everything after it takes seconds,
// and the robustness tables perceive the same runs again for every row (known and unknown initial
// poses, every fraction of injected associations): with the cache, each run is perceived once.
//
// An entry holds what the perception hook (ExperimentConfig::perceive) gives a run: the object
// detections of every pose of every robot, the run's perception metrics (kPerceptionMetrics, the
// timings included: those of the run that filled the entry) and the report it printed. It is
// keyed by a FINGERPRINT of the run's inputs (PerceptionInputDigest: the world as WorldToJson
// writes it and every robot's trajectory, bit for bit) and of the front-end: a digest the caller
// makes of everything else the result depends on (the executable, the detector's files, the
// templates, the options; the perception executable: apps/simulate_perception.cc). A rebuilt
// front-end or another option gives another fingerprint, hence another file: a stale entry is
// never used. A replayed run equals the perceived one exactly (doubles are stored bit for bit).
//
// File format (little-endian; one file <dir>/<fingerprint hex>.perceived):
//   magic "MOSLPRC1" | u64 fingerprint | u32 robots
//   | per robot: u32 poses | per pose: u32 detections | per detection: u32 label length, label
//     bytes, 9 x f64 rotation (row-major), 3 x f64 translation, 36 x f64 information
//     (row-major), i32 ground-truth object id
//   | u32 metrics (kPerceptionMetrics.size()) | f64 each | u32 report length | report bytes
//   | u64 FNV-1a 64 of every byte before it.
// Decoding validates every field (sizes against the bytes left, the checksum, the fingerprint the
// caller expects, a label of 1-255 bytes, an orthonormal rotation with determinant 1 to 1e-9,
// finite translation, a finite symmetric positive-definite information, an object id >= -1,
// metrics finite or NaN, no trailing byte) and throws InvalidInputError naming the first problem;
// PerceptionCache::load turns that into a miss with the reason, and the run is perceived again
// (a damaged file loses nothing).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "moslam/experiments/simulation_experiment.h"
#include "moslam/sim/sensing.h"

namespace moslam {

// The perception metrics an entry keeps, in file order.
extern const std::array<double RunMetrics::*, 16> kPerceptionMetrics;

struct PerceivedRun {
  // detections[r][i]: robot r's detections at pose i (RobotMeasurements::detections).
  std::vector<std::vector<std::vector<ObjectDetection>>> detections;
  std::vector<double> metrics;  // kPerceptionMetrics' fields, in order
  std::string report;           // what the front-end printed for the run
};

// Digest of what the rendered frames of a run are made from: the world and the trajectories.
std::uint64_t PerceptionInputDigest(const SimulationData& data);

// The bytes of the format above; throws InvalidInputError when `run` cannot be stored (a label
// longer than 255 bytes, a metrics count other than kPerceptionMetrics.size()).
std::string EncodePerceivedRun(const PerceivedRun& run, std::uint64_t fingerprint);

// Parses and validates `bytes`; throws InvalidInputError on any mismatch or damage.
PerceivedRun DecodePerceivedRun(std::string_view bytes, std::uint64_t fingerprint);

class PerceptionCache {
 public:
  // `dir` is created on the first store(). Throws InvalidInputError if dir is empty.
  explicit PerceptionCache(std::string dir);

  // The entry, or nullopt: none (`why_not` left empty), or an unusable one (`why_not` says why).
  std::optional<PerceivedRun> load(std::uint64_t fingerprint, std::string* why_not = nullptr) const;
  // Writes the entry (a temporary file renamed into place: readers never see half a file).
  // Throws InvalidInputError naming the path when it cannot.
  void store(const PerceivedRun& run, std::uint64_t fingerprint) const;

  std::string path(std::uint64_t fingerprint) const;
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

// A perception hook that returns the report it would print.
using ReportingPerceive = std::function<std::string(SimulationData&, RunMetrics&)>;

// The perception hook with the cache in front of `perceive`: a run whose inputs
// (PerceptionInputDigest) were perceived before by the same front-end (`front_end`, the caller's
// digest) is replayed from `cache`: its detections replace the data's, its metrics are set and
// RunMetrics::perception_cached is 1; otherwise `perceive` runs (perception_cached 0) and the
// entry is stored. An entry that does not fit the run (robots, poses) or cannot be read is a miss,
// and `print` receives the reason before the run's report. Throws what `perceive` and
// PerceptionCache::store throw.
ExperimentConfig::Perceive CachedPerception(ReportingPerceive perceive, PerceptionCache cache,
                                            std::uint64_t front_end,
                                            std::function<void(const std::string&)> print);

}  // namespace moslam
