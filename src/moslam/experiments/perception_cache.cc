#include "moslam/experiments/perception_cache.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <utility>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"
#include "moslam/common/whole_file.h"
#include "moslam/sim/world.h"

namespace moslam {

const std::array<double RunMetrics::*, 16> kPerceptionMetrics = {
    &RunMetrics::perception_frames,
    &RunMetrics::perception_detections,
    &RunMetrics::perception_true_detections,
    &RunMetrics::perception_accepted,
    &RunMetrics::perception_accepted_true,
    &RunMetrics::perception_rejected_inliers,
    &RunMetrics::perception_rejected_inliers_false,
    &RunMetrics::perception_median_error_m,
    &RunMetrics::perception_median_error_deg,
    &RunMetrics::perception_ms_render,
    &RunMetrics::perception_ms_detect,
    &RunMetrics::perception_ms_segment,
    &RunMetrics::perception_ms_register,
    &RunMetrics::perception_true_visible,
    &RunMetrics::perception_accepted_visible,
    &RunMetrics::perception_pcd_bytes,
};

namespace {

constexpr char kMagic[8] = {'M', 'O', 'S', 'L', 'P', 'R', 'C', '1'};
constexpr const char* kFormat = "perception cache file";
constexpr std::size_t kMaxLabel = 255;
constexpr std::size_t kMaxReport = std::size_t{1} << 20;
// Bytes of a detection after its label: rotation, translation, information, object id.
constexpr std::size_t kDetectionBytes = (9 + 3 + 36) * 8 + 4;

std::uint64_t DigestDouble(double v, std::uint64_t state) {
  return Fnv1a64(&v, sizeof v, state);
}

ObjectDetection ReadDetection(ByteReader& in) {
  ObjectDetection d;
  const std::uint32_t n = in.u32("label length");
  if (n == 0 || n > kMaxLabel) in.fail("label length " + std::to_string(n) + " not in 1-255");
  d.label = std::string(in.take(n, "label"));
  Matrix3 R;
  for (int i = 0; i < 9; ++i) R(i / 3, i % 3) = in.f64("rotation");
  Vector3 t;
  for (int i = 0; i < 3; ++i) t(i) = in.f64("translation");
  if (!R.allFinite() || !t.allFinite()) in.fail("non-finite measurement");
  if ((R.transpose() * R - Matrix3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      std::abs(R.determinant() - 1.0) > 1e-9) {
    in.fail("the measurement's rotation is not a rotation matrix");
  }
  d.measurement = SE3(SO3(R), t);
  for (int i = 0; i < 36; ++i) d.information(i / 6, i % 6) = in.f64("information");
  if (!d.information.allFinite()) in.fail("non-finite information");
  const double scale = d.information.cwiseAbs().maxCoeff();
  if ((d.information - d.information.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale ||
      Eigen::LLT<Matrix6>(d.information).info() != Eigen::Success) {
    in.fail("the information is not symmetric positive definite");
  }
  d.object_id = in.i32("object id");
  if (d.object_id < -1) in.fail("object id " + std::to_string(d.object_id) + " below -1");
  return d;
}

}  // namespace

std::uint64_t PerceptionInputDigest(const SimulationData& data) {
  const std::string world = WorldToJson(data.world);
  std::uint64_t h = Fnv1a64(world.data(), world.size());
  const auto robots = static_cast<std::uint64_t>(data.trajectories.size());
  h = Fnv1a64(&robots, sizeof robots, h);
  for (const Trajectory& trajectory : data.trajectories) {
    const auto poses = static_cast<std::uint64_t>(trajectory.size());
    h = Fnv1a64(&poses, sizeof poses, h);
    for (const SE3& x : trajectory) {
      for (int i = 0; i < 9; ++i) h = DigestDouble(x.rotation().matrix()(i / 3, i % 3), h);
      for (int i = 0; i < 3; ++i) h = DigestDouble(x.translation()(i), h);
    }
  }
  return h;
}

std::string EncodePerceivedRun(const PerceivedRun& run, std::uint64_t fingerprint) {
  if (run.metrics.size() != kPerceptionMetrics.size()) {
    throw InvalidInputError("EncodePerceivedRun: " + std::to_string(run.metrics.size()) +
                            " metrics, expected " + std::to_string(kPerceptionMetrics.size()));
  }
  if (run.report.size() > kMaxReport) {
    throw InvalidInputError("EncodePerceivedRun: a report of more than 1 MiB");
  }
  ByteWriter out;
  out.bytes(std::string_view(kMagic, sizeof kMagic));
  out.u64(fingerprint);
  out.u32(static_cast<std::uint32_t>(run.detections.size()));
  for (const auto& robot : run.detections) {
    out.u32(static_cast<std::uint32_t>(robot.size()));
    for (const auto& pose : robot) {
      out.u32(static_cast<std::uint32_t>(pose.size()));
      for (const ObjectDetection& d : pose) {
        if (d.label.empty() || d.label.size() > kMaxLabel) {
          throw InvalidInputError("EncodePerceivedRun: label '" + d.label +
                                  "' is not 1-255 bytes long");
        }
        out.u32(static_cast<std::uint32_t>(d.label.size()));
        out.bytes(d.label);
        for (int i = 0; i < 9; ++i) out.f64(d.measurement.rotation().matrix()(i / 3, i % 3));
        for (int i = 0; i < 3; ++i) out.f64(d.measurement.translation()(i));
        for (int i = 0; i < 36; ++i) out.f64(d.information(i / 6, i % 6));
        out.i32(d.object_id);
      }
    }
  }
  out.u32(static_cast<std::uint32_t>(run.metrics.size()));
  for (double v : run.metrics) out.f64(v);
  out.u32(static_cast<std::uint32_t>(run.report.size()));
  out.bytes(run.report);
  out.seal();
  return out.take();
}

PerceivedRun DecodePerceivedRun(std::string_view bytes, std::uint64_t fingerprint) {
  ByteReader in(SealedBody(bytes, sizeof kMagic + 8, kFormat), kFormat);
  if (in.take(sizeof kMagic, "magic") != std::string_view(kMagic, sizeof kMagic)) {
    in.fail("bad magic (not a perception cache file of this version)");
  }
  if (in.u64("fingerprint") != fingerprint) in.fail("fingerprint mismatch (another run)");
  PerceivedRun run;
  run.detections.resize(in.count(4, "robots"));
  for (auto& robot : run.detections) {
    robot.resize(in.count(4, "poses"));
    for (auto& pose : robot) {
      const std::uint32_t n = in.count(4 + 1 + kDetectionBytes, "detections");
      pose.reserve(n);
      for (std::uint32_t k = 0; k < n; ++k) pose.push_back(ReadDetection(in));
    }
  }
  const std::uint32_t metrics = in.count(8, "metrics");
  if (metrics != kPerceptionMetrics.size()) {
    in.fail(std::to_string(metrics) + " metrics, expected " +
            std::to_string(kPerceptionMetrics.size()));
  }
  for (std::uint32_t k = 0; k < metrics; ++k) {
    const double v = in.f64("metric");
    if (std::isinf(v)) in.fail("infinite metric");
    run.metrics.push_back(v);
  }
  const std::uint32_t report = in.count(1, "report");
  if (report > kMaxReport) in.fail("a report of more than 1 MiB");
  run.report = std::string(in.take(report, "report"));
  in.finish();
  return run;
}

PerceptionCache::PerceptionCache(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) throw InvalidInputError("PerceptionCache: the directory must not be empty");
}

std::string PerceptionCache::path(std::uint64_t fingerprint) const {
  std::ostringstream name;
  name << std::hex << fingerprint << ".perceived";
  return (std::filesystem::path(dir_) / name.str()).string();
}

std::optional<PerceivedRun> PerceptionCache::load(std::uint64_t fingerprint,
                                                  std::string* why_not) const {
  return ReadDecodedFile(path(fingerprint), why_not, [&](const std::string& bytes) {
    return DecodePerceivedRun(bytes, fingerprint);
  });
}

void PerceptionCache::store(const PerceivedRun& run, std::uint64_t fingerprint) const {
  WriteWholeFile(path(fingerprint), EncodePerceivedRun(run, fingerprint), "PerceptionCache");
}

ExperimentConfig::Perceive CachedPerception(ReportingPerceive perceive, PerceptionCache cache,
                                            std::uint64_t front_end,
                                            std::function<void(const std::string&)> print) {
  return [perceive = std::move(perceive), cache = std::move(cache), front_end,
          print = std::move(print)](SimulationData& data, RunMetrics& m) {
    const std::uint64_t input = PerceptionInputDigest(data);
    const std::uint64_t fingerprint = Fnv1a64(&front_end, sizeof front_end, input);
    std::string why_not;
    if (std::optional<PerceivedRun> hit = cache.load(fingerprint, &why_not)) {
      bool fits = hit->detections.size() == data.trajectories.size() &&
                  data.measurements.size() == data.trajectories.size();
      for (std::size_t r = 0; fits && r < data.trajectories.size(); ++r) {
        fits = hit->detections[r].size() == data.trajectories[r].size();
      }
      if (fits) {
        for (std::size_t r = 0; r < data.measurements.size(); ++r) {
          data.measurements[r].detections = std::move(hit->detections[r]);
        }
        for (std::size_t k = 0; k < kPerceptionMetrics.size(); ++k) {
          m.*kPerceptionMetrics[k] = hit->metrics[k];
        }
        m.perception_cached = 1.0;
        print(hit->report);
        return;
      }
      why_not = cache.path(fingerprint) + ": its robots or poses differ from the run's";
    }
    if (!why_not.empty()) print("perception cache: " + why_not + "; perceiving the run again");
    PerceivedRun run;
    run.report = perceive(data, m);
    m.perception_cached = 0.0;
    for (const RobotMeasurements& robot : data.measurements) {
      run.detections.push_back(robot.detections);
    }
    for (double RunMetrics::*field : kPerceptionMetrics) run.metrics.push_back(m.*field);
    print(run.report);
    cache.store(run, fingerprint);
  };
}

}  // namespace moslam
