#include "moslam/render/tum_sequence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/render/renderer.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

fs::path FreshDir(const std::string& name) { return test::ScratchDir(name); }

void WriteFile(const fs::path& p, const std::string& text) {
  std::ofstream f(p);
  f << text;
}

TEST(TumSequence, WriteReadRoundTrip) {
  const fs::path dir = FreshDir("roundtrip");
  RenderConfig rc;
  rc.intrinsics = PinholeIntrinsics::FromHorizontalFov(160, 120, 60.0);
  const Renderer r(MakeHouseWorld(), rc);
  std::vector<RenderedFrame> frames;
  {
    TumSequenceWriter w(dir.string(), rc.intrinsics);
    for (int i = 0; i < 3; ++i) {
      const SE3 body(SO3::Exp(Vector3(0.0, 0.0, 0.3 * i)), Vector3(1.5 + 0.5 * i, 1.5, 0.5));
      frames.push_back(r.render(body, static_cast<std::uint64_t>(i), 100.0 + 0.5 * i));
      w.add(frames.back().rgbd, frames.back().world_T_camera);
    }
    w.close();
    EXPECT_EQ(w.size(), 3);
  }
  const TumSequence s = ReadTumSequence(dir.string());
  ASSERT_EQ(s.frames.size(), 3u);
  EXPECT_EQ(s.intrinsics.width, 160);
  EXPECT_DOUBLE_EQ(s.intrinsics.fx, rc.intrinsics.fx);
  EXPECT_DOUBLE_EQ(s.depth_scale, 5000.0);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(s.frames[i].rgb_timestamp, 100.0 + 0.5 * static_cast<double>(i), 1e-9);
    ASSERT_TRUE(s.frames[i].world_T_camera.has_value());
    const SE3 d = s.frames[i].world_T_camera->between(frames[i].world_T_camera);
    EXPECT_LT(SE3::Log(d).norm(), 1e-8);
    const RgbdFrame f = LoadTumFrame(s, i);
    EXPECT_EQ(cv::norm(f.rgb, frames[i].rgbd.rgb, cv::NORM_INF), 0.0);
    // Depth: 1/5000 m units, so within half a unit (plus float rounding) of what was written.
    cv::Mat diff;
    cv::absdiff(f.depth, frames[i].rgbd.depth, diff);
    double max_diff = 0.0;
    cv::minMaxLoc(diff, nullptr, &max_diff);
    EXPECT_LE(max_diff, 0.5 / 5000.0 + 1e-6);
    EXPECT_EQ(cv::countNonZero(f.depth == 0.0f), cv::countNonZero(frames[i].rgbd.depth == 0.0f));
  }
  EXPECT_THROW(LoadTumFrame(s, 3), InvalidInputError);

  // Images a frame cannot be made of are refused naming the file: an 8-bit depth image, a
  // colour image of another size than the intrinsics', a missing image.
  const fs::path depth0 = dir / s.frames[0].depth_file;
  cv::imwrite(depth0.string(), cv::Mat(120, 160, CV_8UC1, cv::Scalar(7)));
  EXPECT_TRUE(test::ThrowsNaming([&] { LoadTumFrame(s, 0); },
                                 depth0.string() + ": depth must be a 16-bit single-channel PNG"));
  cv::imwrite((dir / s.frames[1].rgb_file).string(), cv::Mat(60, 80, CV_8UC3, cv::Scalar(1, 2, 3)));
  EXPECT_TRUE(test::ThrowsNaming([&] { LoadTumFrame(s, 1); },
                                 "images are 80x60 / 160x120, the intrinsics say 160x120"));
  fs::remove(dir / s.frames[2].rgb_file);
  EXPECT_TRUE(test::ThrowsNaming([&] { LoadTumFrame(s, 2); }, "cannot read the colour image"));
}

// A hand-written sequence: association by nearest timestamp within the tolerance.
fs::path HandWritten(const std::string& name, const std::string& rgb, const std::string& depth) {
  const fs::path dir = FreshDir(name);
  fs::create_directories(dir);
  WriteFile(dir / "camera.txt", "# fx fy cx cy width height depth_scale\n525 525 319.5 239.5 640 480 5000\n");
  WriteFile(dir / "rgb.txt", rgb);
  WriteFile(dir / "depth.txt", depth);
  return dir;
}

TEST(TumSequence, AssociatesByNearestTimestamp) {
  const std::string header = "# color images\n# file: 'x'\n# timestamp filename\n";
  const fs::path dir = HandWritten(
      "assoc", header + "1.000 rgb/1.png\n2.000 rgb/2.png\n3.000 rgb/3.png\n",
      header + "1.010 depth/a.png\n1.990 depth/b.png\n2.004 depth/c.png\n3.5 depth/d.png\n");
  const TumSequence s = ReadTumSequence(dir.string());
  ASSERT_EQ(s.frames.size(), 2u);  // 3.0 has no depth within 0.02 s
  EXPECT_EQ(s.frames[0].depth_file, "depth/a.png");
  EXPECT_EQ(s.frames[1].depth_file, "depth/c.png");  // nearer than b
  EXPECT_FALSE(s.frames[0].world_T_camera.has_value());  // no groundtruth.txt
  TumReadOptions wide;
  wide.max_time_difference = 0.6;
  EXPECT_EQ(ReadTumSequence(dir.string(), wide).frames.size(), 3u);
  // At the tolerance's edge the difference decides, not the rounded window: 0.1 - 0.08 is
  // 0.020000000000000004 in doubles, beyond 0.02, though 0.1 - 0.02 rounds to 0.08 (the fuzzer's
  // find, fuzz/text_files_fuzz.cc).
  TumSequenceText edge;
  edge.camera = "525 525 319.5 239.5 640 480 5000\n";
  edge.rgb = "0.1 rgb/a.png\n";
  edge.depth = "0.08 depth/a.png\n";
  EXPECT_TRUE(ParseTumSequence(edge, dir.string()).frames.empty());
  edge.depth = "0.0801 depth/a.png\n";
  EXPECT_EQ(ParseTumSequence(edge, dir.string()).frames.size(), 1u);
}

// The texts of a sequence parsed without its directory (what ReadTumSequence does once it has
// read them); a ground-truth quaternion of any finite non-zero norm is normalised (one of 1e200
// used to escape the reader as std::invalid_argument; seen while writing fuzz/text_files_fuzz.cc).
TEST(TumSequence, ParsesTheTextsOfASequence) {
  TumSequenceText text;
  text.camera = "# fx fy cx cy width height depth_scale\n525 525 319.5 239.5 640 480 5000\n";
  text.rgb = "1.000 rgb/1.png\n2.000 rgb/2.png\n";
  text.depth = "1.005 depth/1.png\n2.000 depth/2.png\n";
  text.groundtruth = "1.0 1 2 3 0 0 1e200 1e200\n2.0 4 5 6 0 0 0 1e-200\n";
  const TumSequence s = ParseTumSequence(text, "/no/such/dir");
  EXPECT_EQ(s.intrinsics.width, 640);
  EXPECT_EQ(s.depth_scale, 5000.0);
  ASSERT_EQ(s.frames.size(), 2u);
  ASSERT_TRUE(s.frames[0].world_T_camera && s.frames[1].world_T_camera);
  const Matrix3 quarter_turn = SO3::FromQuaternion(1.0, 0.0, 0.0, 1.0).matrix();
  EXPECT_LT((s.frames[0].world_T_camera->rotation().matrix() - quarter_turn).norm(), 1e-15);
  EXPECT_EQ(s.frames[0].world_T_camera->translation(), Vector3(1, 2, 3));
  EXPECT_LT((s.frames[1].world_T_camera->rotation().matrix() - Matrix3::Identity()).norm(), 1e-15);
  text.groundtruth = "1.0 1 2 3 0 0 0 0\n";
  EXPECT_TRUE(test::ThrowsNaming([&] { ParseTumSequence(text, "/no/such/dir"); },
                                 "/no/such/dir/groundtruth.txt:1"));
}

TEST(TumSequence, MalformedLinesAreRejectedWithFileAndLine) {
  const std::string header = "# color images\n# file: 'x'\n# timestamp filename\n";
  const fs::path dir = HandWritten("bad", header + "1.0 rgb/1.png\n2.0x rgb/2.png\n",
                                   header + "1.0 depth/1.png\n");
  const auto read = [&] { ReadTumSequence(dir.string()); };
  EXPECT_TRUE(test::ThrowsNaming(read, "rgb.txt:5"));
  EXPECT_TRUE(test::ThrowsNaming(read, "2.0x"));
  WriteFile(dir / "rgb.txt", header + "1.0 rgb/1.png extra\n");
  EXPECT_THROW(ReadTumSequence(dir.string()), InvalidInputError);
  WriteFile(dir / "rgb.txt", header + "1.0 rgb/1.png\n");
  WriteFile(dir / "groundtruth.txt", "# gt\n1.0 0 0 0 0 0 0 0\n");
  EXPECT_TRUE(test::ThrowsNaming(read, "groundtruth.txt:2"));
  fs::remove(dir / "groundtruth.txt");
  WriteFile(dir / "camera.txt", "525 525 319.5 239.5 640 480\n");
  EXPECT_TRUE(test::ThrowsNaming(read, "camera.txt:1"));
  fs::remove(dir / "camera.txt");
  EXPECT_THROW(ReadTumSequence(dir.string()), InvalidInputError);  // no intrinsics at all
  TumReadOptions o;
  o.intrinsics = PinholeIntrinsics::FromHorizontalFov(640, 480, 60.0);
  EXPECT_EQ(ReadTumSequence(dir.string(), o).frames.size(), 1u);
  EXPECT_THROW(LoadTumFrame(ReadTumSequence(dir.string(), o), 0), InvalidInputError);  // no PNG
}

// camera.txt: one data line of seven numbers, the image size whole and in range, the intrinsics
// valid, the depth scale positive; each refusal names the file's line and what is wrong.
TEST(TumSequence, ACameraFileThatDoesNotDescribeACameraIsRefusedNamingWhy) {
  TumSequenceText text;
  text.rgb = "1.000 rgb/1.png\n";
  text.depth = "1.000 depth/1.png\n";
  const auto refused = [&](const std::string& camera, const std::string& why) {
    text.camera = camera;
    return test::ThrowsNaming([&] { ParseTumSequence(text, "/seq"); }, why);
  };
  const std::string ok = "525 525 319.5 239.5 640 480 5000\n";
  EXPECT_TRUE(refused("# header\n525 525 319.5 239.5 640.5 480 5000\n",
                      "/seq/camera.txt:2: width must be an integer in [1, 16384]"));
  EXPECT_TRUE(refused("525 525 319.5 239.5 640 0 5000\n", "height must be an integer"));
  EXPECT_TRUE(refused("525 525 319.5 239.5 640 20000 5000\n", "height must be an integer"));
  EXPECT_TRUE(refused("-525 525 319.5 239.5 640 480 5000\n", "fx must be positive and finite"));
  EXPECT_TRUE(refused("525 525 319.5 239.5 640 480 0\n", "depth_scale must be positive"));
  EXPECT_TRUE(refused(ok + ok, "camera.txt:2: more than one data line"));
  EXPECT_TRUE(refused("# only a comment\n", "no data line"));
  text.camera = ok;
  EXPECT_EQ(ParseTumSequence(text, "/seq").intrinsics.height, 480);
}

TEST(TumSequence, WriterRejectsMismatchedFrames) {
  const fs::path dir = FreshDir("writer");
  const auto k = PinholeIntrinsics::FromHorizontalFov(32, 24, 60.0);
  TumSequenceWriter w(dir.string(), k);
  RgbdFrame f;
  f.rgb = cv::Mat(24, 32, CV_8UC3, cv::Scalar(1, 2, 3));
  f.depth = cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.0f));
  f.timestamp = 1.0;
  w.add(f, SE3());
  EXPECT_THROW(w.add(f, SE3()), InvalidInputError);  // same timestamp
  f.timestamp = 2.0;
  f.depth = cv::Mat(10, 10, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_THROW(w.add(f, SE3()), InvalidInputError);
  f.depth = cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.0f));
  f.rgb = cv::Mat(24, 32, CV_8UC1, cv::Scalar(1));
  EXPECT_TRUE(test::ThrowsNaming([&] { w.add(f, SE3()); }, "rgb must be CV_8UC3"));
  for (const double scale : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    EXPECT_TRUE(test::ThrowsNaming([&] { TumSequenceWriter(FreshDir("scale").string(), k, scale); },
                                   "depth_scale must be positive and finite"))
        << scale;
  }
}

TEST(TumSequence, BadReadOptionsNameTheField) {
  using O = TumReadOptions;
  EXPECT_TRUE(test::EachChangeIsRefused<O>({
      {"max_time_difference", [](O& o) { o.max_time_difference = -0.01; }},
      {"max_time_difference", [](O& o) { o.max_time_difference = INFINITY; }},
      {"depth_scale", [](O& o) { o.depth_scale = 0.0; }},
      {"depth_scale", [](O& o) { o.depth_scale = std::nan(""); }},
      {"depth_scale", [](O& o) { o.depth_scale = INFINITY; }},
  }));
}

}  // namespace
}  // namespace moslam
