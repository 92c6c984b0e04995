// libFuzzer target: the text files a user hands moslam besides g2o graphs
// (fuzz/g2o_reader_fuzz.cc): a world (`--world`, sim/world.h), a TUM trajectory (io/tum.h), the
// text files of a TUM RGB-D sequence (`moslam perceive`: camera.txt, rgb.txt, depth.txt,
// groundtruth.txt; render/tum_sequence.h), a YOLO label file (`moslam detect --data`,
// detection/yolo_dataset.h) and one robot's file of a distributed-mapper folder with its
// separators (`moslam robot`, transport/robot_data.h), a detector's class names file (`moslam
// detect --classes`, detection/detector.h), a robot's summary.json as `moslam team` reads it back
// (apps/robot_summaries.h: every field read through the checked accessors). The first byte picks
// the reader, the rest is its input; a sequence's four texts are the input cut at its first three
// NUL bytes. A reader may only reject input with a moslam::Error; any other exception, a crash, a
// sanitizer report or a hang is a bug. What is accepted must hold what the reader promises (finite
// poses, rotations orthonormal, label boxes of positive size within [0, 1], a world that validates
// and reads back from its own JSON, class names distinct, trimmed and printable, a summary's
// integers within their types).
#include <Eigen/LU>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/detection/detector.h"
#include "moslam/detection/yolo_dataset.h"
#include "moslam/io/tum.h"
#include "moslam/render/tum_sequence.h"
#include "moslam/sim/world.h"
#include "moslam/transport/robot_data.h"
#include "robot_summaries.h"

namespace {

void Require(bool ok) {
  if (!ok) __builtin_trap();
}

void RequireRigid(const moslam::SE3& pose) {
  const moslam::Matrix3& R = pose.rotation().matrix();
  Require(R.allFinite() && pose.translation().allFinite());
  Require((R.transpose() * R - moslam::Matrix3::Identity()).norm() < 1e-9);
  Require(std::abs(R.determinant() - 1.0) < 1e-9);
}

// The input cut at its first `parts - 1` NUL bytes (fewer parts when it holds fewer NULs).
std::vector<std::string> Split(const std::string& input, std::size_t parts) {
  std::vector<std::string> out;
  std::size_t begin = 0;
  while (out.size() + 1 < parts) {
    const std::size_t nul = input.find('\0', begin);
    if (nul == std::string::npos) break;
    out.push_back(input.substr(begin, nul - begin));
    begin = nul + 1;
  }
  out.push_back(input.substr(begin));
  return out;
}

void Read(std::uint8_t which, const std::string& input) {
  using namespace moslam;
  switch (which % 7) {
    case 0: {
      const World w = WorldFromJson(input, "fuzz.json");
      ValidateWorld(w, "accepted world");
      const World again = WorldFromJson(WorldToJson(w), "written world");
      Require(again.objects.size() == w.objects.size() && again.classes.size() == w.classes.size());
      for (const ObjectInstance& o : w.objects) RequireRigid(o.pose);
      break;
    }
    case 1: {
      std::istringstream in(input);
      const Values values = ParseTumTrajectory(in, "fuzz.tum", which % 7);
      for (const auto& [key, pose] : values) RequireRigid(pose);
      break;
    }
    case 2: {
      const std::vector<std::string> texts = Split(input, 4);
      TumSequenceText text;
      // The camera file and the ground truth are optional: even selectors leave them out.
      if (which & 0x10) text.camera = texts[0];
      text.rgb = texts.size() > 1 ? texts[1] : std::string();
      text.depth = texts.size() > 2 ? texts[2] : std::string();
      if (texts.size() > 3 && (which & 0x20)) text.groundtruth = texts[3];
      TumReadOptions options;
      if (!text.camera) options.intrinsics = PinholeIntrinsics{};
      const TumSequence seq = ParseTumSequence(text, "fuzz_sequence", options);
      Require(seq.intrinsics.width >= 1 && seq.intrinsics.height >= 1);
      Require(std::isfinite(seq.depth_scale) && seq.depth_scale > 0.0);
      for (std::size_t i = 0; i < seq.frames.size(); ++i) {
        const TumFrame& f = seq.frames[i];
        Require(std::isfinite(f.rgb_timestamp) && std::isfinite(f.depth_timestamp));
        Require(std::abs(f.rgb_timestamp - f.depth_timestamp) <= options.max_time_difference);
        if (i > 0) Require(seq.frames[i - 1].rgb_timestamp <= f.rgb_timestamp);
        if (f.world_T_camera) RequireRigid(*f.world_T_camera);
      }
      break;
    }
    case 3: {
      const int classes = 1 + which % 12;
      for (const YoloLabel& l : ParseYoloLabels(input, "fuzz.txt", classes)) {
        Require(l.class_id >= 0 && l.class_id < classes);
        Require(l.cx >= 0.0f && l.cx <= 1.0f && l.cy >= 0.0f && l.cy <= 1.0f);
        Require(l.w > 0.0f && l.w <= 1.0f && l.h > 0.0f && l.h <= 1.0f);
      }
      break;
    }
    case 4: {
      G2oReadOptions options;
      options.scheme = (which & 0x10) ? KeyScheme::kWithObjects : KeyScheme::kPosesOnly;
      std::istringstream in(input);
      const Dataset d = ParseRobotG2o(in, "fuzz/0.g2o", options);
      for (const auto& factor : d.graph.factors()) {
        Require(factor.a() != factor.b());
        Require(factor.sqrtInformation().allFinite());
      }
      for (const auto& [key, pose] : d.initial) RequireRigid(pose);
      break;
    }
    case 5: {
      const std::vector<std::string> names = ParseClassNames(input, "fuzz.names");
      Require(!names.empty());
      std::set<std::string> distinct;
      for (const std::string& name : names) {
        Require(!name.empty() && distinct.insert(name).second);
        for (char c : name) {
          const auto u = static_cast<unsigned char>(c);
          Require(u >= 0x20 && u != 0x7f);
        }
        Require(name.front() != ' ' && name.back() != ' ');
      }
      break;
    }
    case 6: {
      const cli::JsonFields summary = cli::JsonFields::Parse(input, "fuzz/summary.json");
      if (!summary.json().is_object()) break;
      // Each field read every way `moslam team` reads one; each read returns or refuses.
      const auto tolerate = [](auto&& read) {
        try {
          read();
        } catch (const Error&) {
        }
      };
      for (const auto& item : summary.json().items()) {
        const std::string& key = item.key();
        tolerate([&] { Require(summary.get<int>(key) == summary.json()[key].get<int>()); });
        tolerate([&] { summary.get<std::int64_t>(key); });
        tolerate([&] { summary.get<double>(key); });
        tolerate([&] { summary.get<std::vector<int>>(key); });
        tolerate([&] {
          for (const cli::JsonFields& e : summary.items(key, (which & 0x10) != 0)) {
            tolerate([&] { e.get<int>("alpha"); });
            tolerate(
                [&] { Require(e.as<std::vector<std::uint64_t>>().size() == e.json().size()); });
          }
        });
      }
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string input(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    Read(data[0], input);
  } catch (const moslam::Error&) {
    // Rejected cleanly.
  }
  return 0;
}
