#include "moslam/detection/yolo_dataset.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <locale>
#include <opencv2/imgcodecs.hpp>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {
namespace fs = std::filesystem;

fs::path MakeDataset(const std::string& name) {
  const fs::path root = test::ScratchDir(name);
  fs::create_directories(root / "images");
  fs::create_directories(root / "labels");
  std::ofstream(root / "classes.txt") << "chair\ntable\n";
  const cv::Mat img(20, 40, CV_8UC3, cv::Scalar::all(0));
  cv::imwrite((root / "images" / "b.png").string(), img);
  cv::imwrite((root / "images" / "a.png").string(), img);
  std::ofstream(root / "labels" / "a.txt") << "1 0.5 0.25 0.5 0.5\n\n0 0.1 0.1 0.2 0.2\n";
  return root;
}

TEST(YoloDataset, ReadsImagesLabelsAndClasses) {
  const fs::path root = MakeDataset("moslam_yolo_ok");
  const YoloDataset data = ReadYoloDataset(root.string());
  EXPECT_EQ(data.class_names, (std::vector<std::string>{"chair", "table"}));
  ASSERT_EQ(data.samples.size(), 2u);
  EXPECT_EQ(fs::path(data.samples[0].image_path).filename(), "a.png");
  ASSERT_EQ(data.samples[0].labels.size(), 2u);
  EXPECT_TRUE(data.samples[1].labels.empty());  // b has no label file: no objects
  const GroundTruthBox g = data.samples[0].labels[0].toPixels(40, 20);
  EXPECT_EQ(g.class_id, 1);
  EXPECT_FLOAT_EQ(g.box.x, 10.0f);
  EXPECT_FLOAT_EQ(g.box.y, 0.0f);
  EXPECT_FLOAT_EQ(g.box.width, 20.0f);
  EXPECT_FLOAT_EQ(g.box.height, 10.0f);
}

TEST(YoloDataset, ReadsIgnoreBoxesWhenTheFolderExists) {
  const fs::path root = MakeDataset("moslam_yolo_ignore");
  EXPECT_FALSE(ReadYoloDataset(root.string()).has_ignore);
  fs::create_directories(root / "ignore");
  std::ofstream(root / "ignore" / "b.txt") << "0 0.5 0.5 0.25 0.5\n";
  const YoloDataset data = ReadYoloDataset(root.string());
  EXPECT_TRUE(data.has_ignore);
  ASSERT_EQ(data.samples.size(), 2u);
  EXPECT_TRUE(data.samples[0].ignore.empty());  // a has no ignore file
  EXPECT_EQ(data.samples[0].labels.size(), 2u);
  ASSERT_EQ(data.samples[1].ignore.size(), 1u);
  EXPECT_TRUE(data.samples[1].labels.empty());
  const GroundTruthBox g = data.samples[1].ignore[0].toPixels(40, 20);
  EXPECT_EQ(g.class_id, 0);
  EXPECT_FLOAT_EQ(g.box.x, 15.0f);
  EXPECT_FLOAT_EQ(g.box.width, 10.0f);
  // A malformed ignore file is an error naming it.
  std::ofstream(root / "ignore" / "b.txt") << "0 0.5 0.5 0.25\n";
  EXPECT_TRUE(test::ThrowsNaming([&] { ReadYoloDataset(root.string()); }, "ignore/b.txt:1:"));
}

TEST(YoloDataset, MalformedLabelNamesFileAndLine) {
  const fs::path root = MakeDataset("moslam_yolo_bad");
  const std::string label = (root / "labels" / "a.txt").string();
  auto expect_error = [&](const std::string& content, const std::string& what) {
    std::ofstream(label) << content;
    const auto read = [&] { ReadYoloDataset(root.string()); };
    EXPECT_TRUE(test::ThrowsNaming(read, "a.txt:2:")) << content;
    EXPECT_TRUE(test::ThrowsNaming(read, what)) << content;
  };
  expect_error("0 0.5 0.5 0.1 0.1\n0 0.5 0.5 0.1\n", "expected");
  expect_error("0 0.5 0.5 0.1 0.1\n2 0.5 0.5 0.1 0.1\n", "class id");
  expect_error("0 0.5 0.5 0.1 0.1\n0 1.5 0.5 0.1 0.1\n", "[0, 1]");
  expect_error("0 0.5 0.5 0.1 0.1\n0 0.5 0.5 0.0 0.1\n", "positive");
  expect_error("0 0.5 0.5 0.1 0.1\n0 0.5 0.5 0.1 0.1 7\n", "expected");
}

TEST(YoloDataset, ParsesALabelFilesText) {
  const std::vector<YoloLabel> labels =
      ParseYoloLabels("1 0.5 0.25 0.1 0.2\n\n0 1 1 1 1\n", "x.txt", 2);
  ASSERT_EQ(labels.size(), 2u);
  EXPECT_EQ(labels[0].class_id, 1);
  EXPECT_FLOAT_EQ(labels[0].cy, 0.25f);
  EXPECT_EQ(labels[1].class_id, 0);
  EXPECT_TRUE(test::ThrowsNaming(
      [] { ParseYoloLabels("0 0.5 0.5 0.1 0.1\n0 0.5 nan 0.1 0.1\n", "x.txt", 2); }, "x.txt:2:"));
}

// A process whose global locale writes numbers with a decimal comma (an application embedding
// moslam may set one): label files, written as "0.5", read the same.
struct CommaDecimal : std::numpunct<char> {
  char do_decimal_point() const override { return ','; }
};

TEST(YoloDataset, LabelsReadTheSameUnderALocaleWithADecimalComma) {
  const std::locale before = std::locale::global(std::locale(std::locale::classic(),
                                                             new CommaDecimal));
  std::vector<YoloLabel> labels;
  std::string error;
  try {
    labels = ParseYoloLabels("1 0.5 0.25 0.1 0.2\n", "x.txt", 2);
  } catch (const InvalidInputError& e) {
    error = e.what();
  }
  std::locale::global(before);
  ASSERT_EQ(labels.size(), 1u) << error;
  EXPECT_FLOAT_EQ(labels[0].cx, 0.5f);
  EXPECT_FLOAT_EQ(labels[0].h, 0.2f);
}

TEST(YoloDataset, MissingPartsAreTypedErrors) {
  EXPECT_THROW(ReadYoloDataset("/nonexistent/moslam/dataset"), InvalidInputError);
  const fs::path root = MakeDataset("moslam_yolo_missing");
  fs::remove(root / "classes.txt");
  EXPECT_THROW(ReadYoloDataset(root.string()), InvalidInputError);
  const fs::path root2 = MakeDataset("moslam_yolo_empty");
  for (const auto& e : fs::directory_iterator(root2 / "images")) fs::remove(e.path());
  EXPECT_THROW(ReadYoloDataset(root2.string()), InvalidInputError);
}

}  // namespace
}  // namespace moslam
