#include "moslam/experiments/perception_cache.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {

// Two robots, three and two poses, a few detections with arbitrary rotations and information.
PerceivedRun SomeRun() {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  PerceivedRun run;
  run.detections.resize(2);
  run.detections[0].resize(3);
  run.detections[1].resize(2);
  int id = -1;
  for (auto& robot : run.detections) {
    for (std::size_t i = 0; i < robot.size(); i += 2) {
      for (const char* label : {"chair", "table"}) {
        ObjectDetection d;
        d.label = label;
        d.measurement = SE3(SO3::Exp(Vector3(n(rng), n(rng), n(rng))),
                            Vector3(n(rng), n(rng), n(rng)));
        Matrix6 a;
        for (int k = 0; k < 36; ++k) a(k / 6, k % 6) = n(rng);
        d.information = a * a.transpose() + Matrix6::Identity();
        d.object_id = id++;
        robot[i].push_back(d);
      }
    }
  }
  for (std::size_t k = 0; k < kPerceptionMetrics.size(); ++k) run.metrics.push_back(0.1 * static_cast<double>(k));
  run.metrics[7] = std::nan("");  // a median error of no accepted view
  run.report = "perception, chairs25 (2 robots): chair 3/4\n";
  return run;
}

void ExpectSame(const PerceivedRun& a, const PerceivedRun& b) {
  ASSERT_EQ(a.detections.size(), b.detections.size());
  for (std::size_t r = 0; r < a.detections.size(); ++r) {
    ASSERT_EQ(a.detections[r].size(), b.detections[r].size());
    for (std::size_t i = 0; i < a.detections[r].size(); ++i) {
      ASSERT_EQ(a.detections[r][i].size(), b.detections[r][i].size());
      for (std::size_t k = 0; k < a.detections[r][i].size(); ++k) {
        const ObjectDetection& x = a.detections[r][i][k];
        const ObjectDetection& y = b.detections[r][i][k];
        EXPECT_EQ(x.label, y.label);
        EXPECT_EQ(x.measurement.rotation().matrix(), y.measurement.rotation().matrix());
        EXPECT_EQ(x.measurement.translation(), y.measurement.translation());
        EXPECT_EQ(x.information, y.information);
        EXPECT_EQ(x.object_id, y.object_id);
      }
    }
  }
  ASSERT_EQ(a.metrics.size(), b.metrics.size());
  for (std::size_t k = 0; k < a.metrics.size(); ++k) {
    EXPECT_TRUE(a.metrics[k] == b.metrics[k] ||
                (std::isnan(a.metrics[k]) && std::isnan(b.metrics[k])));
  }
  EXPECT_EQ(a.report, b.report);
}

TEST(PerceptionCache, ARunRoundTripsBitForBit) {
  const PerceivedRun run = SomeRun();
  const std::string bytes = EncodePerceivedRun(run, 42);
  const PerceivedRun back = DecodePerceivedRun(bytes, 42);
  ExpectSame(run, back);
  EXPECT_EQ(EncodePerceivedRun(back, 42), bytes);
}

TEST(PerceptionCache, DamagedTruncatedOrForeignBytesAreRejected) {
  const std::string bytes = EncodePerceivedRun(SomeRun(), 42);
  EXPECT_THROW(DecodePerceivedRun(bytes, 43), InvalidInputError);  // another run's entry
  for (std::size_t at = 0; at < bytes.size(); at += 37) {
    std::string damaged = bytes;
    damaged[at] = static_cast<char>(damaged[at] ^ 0x10);
    EXPECT_THROW(DecodePerceivedRun(damaged, 42), InvalidInputError) << "byte " << at;
  }
  EXPECT_THROW(DecodePerceivedRun(bytes.substr(0, bytes.size() - 1), 42), InvalidInputError);
  EXPECT_THROW(DecodePerceivedRun(bytes + '\0', 42), InvalidInputError);
  EXPECT_THROW(DecodePerceivedRun("", 42), InvalidInputError);
}

// Sealed with the right checksum, a value that means nothing sensible is still refused.
TEST(PerceptionCache, ImplausibleValuesWithAValidChecksumAreRejected) {
  const auto rejects = [](PerceivedRun run, const std::string& why) {
    EXPECT_TRUE(
        test::ThrowsNaming([&] { DecodePerceivedRun(EncodePerceivedRun(run, 1), 1); }, why));
  };
  PerceivedRun run = SomeRun();
  ObjectDetection& d = run.detections[0][0][0];
  const ObjectDetection good = d;
  d.measurement = SE3(SO3(2.0 * Matrix3::Identity()), Vector3::Zero());
  rejects(run, "rotation");
  d = good;
  d.information(0, 0) = -1.0;
  rejects(run, "positive definite");
  d = good;
  d.information(1, 0) += 1.0;
  rejects(run, "symmetric");
  d = good;
  d.object_id = -2;
  rejects(run, "object id");
  d = good;
  run.metrics[0] = INFINITY;
  rejects(run, "infinite metric");
  run = SomeRun();
  run.detections[0][0][0].label.clear();
  EXPECT_THROW(EncodePerceivedRun(run, 1), InvalidInputError);
  run = SomeRun();
  run.metrics.pop_back();
  EXPECT_THROW(EncodePerceivedRun(run, 1), InvalidInputError);
}

class PerceptionCacheDir : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (test::ScratchDir() / "cache").string();
  }
  std::string dir_;
};

TEST_F(PerceptionCacheDir, AMissingEntryIsASilentMissADamagedOneAMissWithItsReason) {
  const PerceptionCache cache(dir_);
  std::string why = "stale";
  EXPECT_FALSE(cache.load(5, &why));
  EXPECT_TRUE(why.empty());
  cache.store(SomeRun(), 5);
  const std::optional<PerceivedRun> hit = cache.load(5, &why);
  ASSERT_TRUE(hit);
  ExpectSame(*hit, SomeRun());
  {
    std::fstream f(cache.path(5), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(40);
    f.put('\x7f');
  }
  EXPECT_FALSE(cache.load(5, &why));
  EXPECT_NE(why.find("checksum"), std::string::npos) << why;
  EXPECT_THROW(PerceptionCache(""), InvalidInputError);
}

ExperimentConfig Tiny() {
  ExperimentConfig c;
  c.scenario = "chairs25";
  c.robots = 2;
  c.runs = 1;
  c.seed = 3;
  c.poses_per_robot = 40;
  return c;
}

// Every perception metric of RunMetrics is cached (perception_cached says whether the run was
// replayed, so it is not): one left out would come back from a replayed run as not measured.
TEST(PerceptionCache, CachesEveryPerceptionMetric) {
  ExperimentResult r;
  r.config = Tiny();
  r.runs = {RunMetrics{}};
  r.mean = r.runs[0];
  const nlohmann::json j = nlohmann::json::parse(ResultsToJson({r}));
  std::vector<std::string> perception;
  for (const auto& [name, value] : j["rows"][0]["runs"][0].items()) {
    if (name.rfind("perception_", 0) == 0 && name != "perception_cached") {
      perception.push_back(name);
    }
  }
  EXPECT_EQ(perception.size(), kPerceptionMetrics.size());
  for (double RunMetrics::*field : kPerceptionMetrics) r.runs[0].*field = 7.0;
  const nlohmann::json m = nlohmann::json::parse(ResultsToJson({r}));
  for (const std::string& name : perception) {
    EXPECT_EQ(m["rows"][0]["runs"][0][name], 7.0) << name << " is not cached";
  }
}

// A stand-in for the front-end: keeps every other pose's detections, counts its calls.
struct FakeFrontEnd {
  int calls = 0;
  std::string report(SimulationData& data, RunMetrics& m) {
    ++calls;
    int kept = 0;
    for (RobotMeasurements& robot : data.measurements) {
      for (std::size_t i = 1; i < robot.detections.size(); i += 2) robot.detections[i].clear();
      for (const auto& pose : robot.detections) kept += static_cast<int>(pose.size());
    }
    for (double RunMetrics::*field : kPerceptionMetrics) m.*field = 0.0;
    m.perception_accepted = kept;
    return "kept " + std::to_string(kept);
  }
};

TEST_F(PerceptionCacheDir, ARunIsPerceivedOnceAndReplayedExactly) {
  FakeFrontEnd front_end;
  std::vector<std::string> printed;
  ExperimentConfig c = Tiny();
  c.perceive = CachedPerception(
      [&](SimulationData& data, RunMetrics& m) { return front_end.report(data, m); },
      PerceptionCache(dir_), 11, [&](const std::string& s) { printed.push_back(s); });
  const RunMetrics first = RunSimulationOnce(c, 0);
  const RunMetrics second = RunSimulationOnce(c, 0);
  EXPECT_EQ(front_end.calls, 1);
  EXPECT_EQ(first.perception_cached, 0.0);
  EXPECT_EQ(second.perception_cached, 1.0);
  ASSERT_EQ(printed.size(), 2u);
  EXPECT_EQ(printed[0], printed[1]);
  EXPECT_GT(first.perception_accepted, 0.0);
  EXPECT_EQ(second.perception_accepted, first.perception_accepted);
  // The estimates of the replayed run are those of the perceived one, to the bit.
  EXPECT_EQ(second.landmarks, first.landmarks);
  EXPECT_EQ(second.gn_cost, first.gn_cost);
  EXPECT_EQ(second.gn_ate_poses, first.gn_ate_poses);
  EXPECT_EQ(second.dgs_ate_poses, first.dgs_ate_poses);

  // Another run of the same config has other inputs; another front-end another digest.
  RunSimulationOnce(c, 1);
  EXPECT_EQ(front_end.calls, 2);
  ExperimentConfig other = c;
  other.perceive = CachedPerception(
      [&](SimulationData& data, RunMetrics& m) { return front_end.report(data, m); },
      PerceptionCache(dir_), 12, [](const std::string&) {});
  EXPECT_EQ(RunSimulationOnce(other, 0).perception_cached, 0.0);
  EXPECT_EQ(front_end.calls, 3);

  // A damaged entry: perceived again, the reason printed, the entry rewritten.
  for (const auto& entry : std::filesystem::directory_iterator(dir_)) {
    std::ofstream(entry.path(), std::ios::binary | std::ios::trunc) << "MOSLPRC1";
  }
  printed.clear();
  const RunMetrics again = RunSimulationOnce(c, 0);
  EXPECT_EQ(front_end.calls, 4);
  EXPECT_EQ(again.perception_cached, 0.0);
  EXPECT_EQ(again.gn_ate_poses, first.gn_ate_poses);
  ASSERT_EQ(printed.size(), 2u);
  EXPECT_NE(printed[0].find("perceiving the run again"), std::string::npos) << printed[0];
  EXPECT_EQ(RunSimulationOnce(c, 0).perception_cached, 1.0);
  EXPECT_EQ(front_end.calls, 4);
}

}  // namespace
}  // namespace moslam
