#include "moslam/detection/detector.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {

// testdata/make_tiny_models.py documents the two models and their constant outputs.
const std::string kTestData = MOSLAM_DETECTION_TESTDATA_DIR;

DetectorConfig TinyConfig(DetectorOutputFormat format) {
  DetectorConfig c;
  c.format = format;
  c.model_path = kTestData + (format == DetectorOutputFormat::kMoslam   ? "/tiny_moslam.onnx"
                              : format == DetectorOutputFormat::kYolov8 ? "/tiny_yolov8.onnx"
                                                                        : "/tiny_yolov5.onnx");
  c.class_names = {"chair", "table"};
  c.input_width = 8;
  c.input_height = 8;
  c.flip_test = false;  // the decoding tests read one pass; the flip tests turn it on
  c.class_agnostic_nms = false;  // per class: ClassAgnosticNmsSuppressesAcrossClasses turns it on
  return c;
}

// An image of side 8 * k whose quarters have the intensities 255 (top left), 204 (top right),
// 153 (bottom left) and 51 (bottom right): objectness 1.0, 0.8, 0.6, 0.2 in tiny_moslam.onnx.
cv::Mat Quadrants(int k) {
  cv::Mat img(8 * k, 8 * k, CV_8UC3);
  const int h = 4 * k;
  img(cv::Rect(0, 0, h, h)).setTo(cv::Scalar::all(255));
  img(cv::Rect(h, 0, h, h)).setTo(cv::Scalar::all(204));
  img(cv::Rect(0, h, h, h)).setTo(cv::Scalar::all(153));
  img(cv::Rect(h, h, h, h)).setTo(cv::Scalar::all(51));
  return img;
}

void ExpectDetection(const Detection& d, int class_id, const std::string& label, float score,
                     cv::Rect2f box) {
  EXPECT_EQ(d.class_id, class_id);
  EXPECT_EQ(d.label, label);
  EXPECT_NEAR(d.confidence, score, 1e-5f);
  EXPECT_NEAR(d.box.x, box.x, 1e-4f);
  EXPECT_NEAR(d.box.y, box.y, 1e-4f);
  EXPECT_NEAR(d.box.width, box.width, 1e-4f);
  EXPECT_NEAR(d.box.height, box.height, 1e-4f);
}

TEST(DetectorMoslam, DecodesGridThresholdsAndRunsPerClassNms) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.nms_iou_threshold = 0.3f;
  Detector detector(c);
  const auto d = detector.detect(Quadrants(1));
  // Cell (0,1) (score 0.64, IoU 0.6 with cell (0,0)) is suppressed; cell (1,0) overlaps cell
  // (0,0) with IoU 1/3 > 0.3 but is another class; cell (1,1) scores 0.18 < 0.3.
  ASSERT_EQ(d.size(), 2u);
  ExpectDetection(d[0], 0, "chair", 0.9f, {1, 0, 4, 4});
  ExpectDetection(d[1], 1, "table", 0.42f, {1, 2, 4, 4});
}

TEST(DetectorMoslam, ClassAgnosticNmsSuppressesAcrossClasses) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.nms_iou_threshold = 0.3f;
  c.class_agnostic_nms = true;
  Detector detector(c);
  const auto d = detector.detect(Quadrants(1));
  // The table of cell (1,0) overlaps the chair of cell (0,0) with IoU 1/3 > 0.3: suppressed now.
  ASSERT_EQ(d.size(), 1u);
  ExpectDetection(d[0], 0, "chair", 0.9f, {1, 0, 4, 4});
  // Below its IoU the table survives with its own class.
  c.nms_iou_threshold = 0.4f;
  const auto kept = Detector(c).detect(Quadrants(1));
  ASSERT_EQ(kept.size(), 2u);
  ExpectDetection(kept[1], 1, "table", 0.42f, {1, 2, 4, 4});
}

TEST(DetectorMoslam, LooserNmsAndLowerThresholdKeepMore) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.nms_iou_threshold = 0.7f;
  c.confidence_threshold = 0.1f;
  Detector detector(c);
  const auto d = detector.detect(Quadrants(1));
  ASSERT_EQ(d.size(), 4u);
  ExpectDetection(d[0], 0, "chair", 0.9f, {1, 0, 4, 4});
  ExpectDetection(d[1], 0, "chair", 0.64f, {2, 0, 4, 4});
  ExpectDetection(d[2], 1, "table", 0.42f, {1, 2, 4, 4});
  ExpectDetection(d[3], 1, "table", 0.18f, {5, 5, 2, 2});
}

TEST(DetectorMoslam, BoxesAreInInputImagePixels) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.nms_iou_threshold = 0.3f;
  Detector detector(c);
  const auto d = detector.detect(Quadrants(2));  // 16x16, stretched to 8x8
  ASSERT_EQ(d.size(), 2u);
  ExpectDetection(d[0], 0, "chair", 0.9f, {2, 0, 8, 8});
  ExpectDetection(d[1], 1, "table", 0.42f, {2, 4, 8, 8});
  // A black image: objectness 0 everywhere, nothing detected.
  EXPECT_TRUE(detector.detect(cv::Mat::zeros(8, 8, CV_8UC3)).empty());
}

// The detections of the tiny yolov5 and yolov8 fixtures (make_tiny_models.py): box 1 (0.56, IoU
// 0.78 with box 0) suppressed; box 3 scores 0.25 < 0.3.
void ExpectFixtureBoxes(const std::vector<Detection>& d) {
  ASSERT_EQ(d.size(), 2u);
  ExpectDetection(d[0], 0, "chair", 0.81f, {2, 2, 4, 4});
  ExpectDetection(d[1], 1, "table", 0.4f, {1, 5, 2, 2});
}

TEST(DetectorYolov5, DecodesRowsThresholdsAndNms) {
  Detector detector(TinyConfig(DetectorOutputFormat::kYolov5));
  ExpectFixtureBoxes(detector.detect(Quadrants(1)));
}

// YOLOv8 / YOLO11 exports: [1, 4 + C, N], one column per box, no objectness; the fixture holds
// the boxes of tiny_yolov5.onnx with objectness x class probability as class scores, so it must
// give the same detections.
TEST(DetectorYolov8, DecodesColumnsWithoutObjectness) {
  Detector detector(TinyConfig(DetectorOutputFormat::kYolov8));
  ExpectFixtureBoxes(detector.detect(Quadrants(1)));
  // The same file read as yolov5 rows does not fit: a typed error naming the expected shape.
  DetectorConfig rows = TinyConfig(DetectorOutputFormat::kYolov8);
  rows.format = DetectorOutputFormat::kYolov5;
  EXPECT_THROW(Detector{rows}, InvalidInputError);
  // Three classes configured for a two-class model: the column count does not fit either.
  DetectorConfig three = TinyConfig(DetectorOutputFormat::kYolov8);
  three.class_names = {"chair", "table", "sofa"};
  EXPECT_THROW(Detector{three}, InvalidInputError);
}

// Flip test on the yolov5 fixture, whose output does not depend on the image: its boxes in the
// mirror image's pass, mirrored back, land where the image itself shows none, unless centred.
TEST(DetectorFlipTest, PairsTheTwoPassesAndHalvesABoxSeenInOne) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kYolov5);
  c.flip_test = true;
  // The chair box [2, 2, 4, 4] is centred: its mirror is itself, a pair, mean score 0.81. The
  // table box [1, 5, 2, 2] (0.4) mirrors to [5, 5, 2, 2]: no partner in either pass, 0.2 each,
  // below 0.3.
  const auto d = Detector(c).detect(Quadrants(1));
  ASSERT_EQ(d.size(), 1u);
  ExpectDetection(d[0], 0, "chair", 0.81f, {2, 2, 4, 4});
  c.confidence_threshold = 0.15f;
  const auto low = Detector(c).detect(Quadrants(1));
  // Now both halves of the table show, one per pass; box 3 (table 0.25 at [5, 1, 2, 2]) halves to
  // 0.125, still below.
  ASSERT_EQ(low.size(), 3u);
  ExpectDetection(low[0], 0, "chair", 0.81f, {2, 2, 4, 4});
  const bool left_first = low[1].box.x < low[2].box.x;
  ExpectDetection(low[left_first ? 1 : 2], 1, "table", 0.2f, {1, 5, 2, 2});
  ExpectDetection(low[left_first ? 2 : 1], 1, "table", 0.2f, {5, 5, 2, 2});
}

// The two passes of an image and of its mirror image are the same two images: the flip test's
// detections of the mirror image are those of the image mirrored, whatever the network (the tiny
// moslam model's boxes are not mirror-symmetric).
TEST(DetectorFlipTest, TheMirrorImageGivesTheMirroredDetections) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.flip_test = true;
  c.confidence_threshold = 0.1f;
  Detector detector(c);
  const cv::Mat image = Quadrants(2);
  cv::Mat mirrored;
  cv::flip(image, mirrored, 1);
  const auto d = detector.detect(image);
  const auto m = detector.detect(mirrored);
  ASSERT_FALSE(d.empty());
  ASSERT_EQ(d.size(), m.size());
  for (const Detection& x : d) {
    const cv::Rect2f expected(static_cast<float>(image.cols) - x.box.x - x.box.width, x.box.y,
                              x.box.width, x.box.height);
    int found = 0;
    for (const Detection& y : m) {
      found += y.class_id == x.class_id && std::abs(y.confidence - x.confidence) < 1e-5f &&
               std::abs(y.box.x - expected.x) < 1e-3f && std::abs(y.box.y - expected.y) < 1e-3f &&
               std::abs(y.box.width - expected.width) < 1e-3f &&
               std::abs(y.box.height - expected.height) < 1e-3f;
    }
    EXPECT_EQ(found, 1) << x.label << " " << x.confidence << " at " << x.box;
  }
  // The detections above a threshold do not depend on the threshold the detector ran at (the
  // evaluation runs it at 0.01 for the AP and counts precision and recall at 0.3).
  DetectorConfig at = c;
  at.confidence_threshold = 0.3f;
  const auto high = Detector(at).detect(image);
  std::vector<Detection> filtered;
  for (const Detection& x : d) {
    if (x.confidence >= 0.3f) filtered.push_back(x);
  }
  ASSERT_EQ(high.size(), filtered.size());
  for (std::size_t i = 0; i < high.size(); ++i) {
    ExpectDetection(high[i], filtered[i].class_id, filtered[i].label, filtered[i].confidence,
                    filtered[i].box);
  }
  c.flip_match_iou = 0.0f;
  EXPECT_THROW(Detector{c}, InvalidInputError);
  c.flip_match_iou = 1.5f;
  EXPECT_THROW(Detector{c}, InvalidInputError);
}

TEST(DetectorYolov5, StretchAndLetterboxMapBackToTheImage) {
  const cv::Mat wide(8, 16, CV_8UC3, cv::Scalar::all(90));  // 16 wide, 8 high
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kYolov5);
  {
    Detector detector(c);
    const auto d = detector.detect(wide);
    ASSERT_EQ(d.size(), 2u);
    ExpectDetection(d[0], 0, "chair", 0.81f, {4, 2, 8, 4});
    ExpectDetection(d[1], 1, "table", 0.4f, {2, 5, 4, 2});
  }
  c.resize_mode = ResizeMode::kLetterbox;  // scale 0.5, 2 rows of padding above and below
  Detector detector(c);
  const auto d = detector.detect(wide);
  ASSERT_EQ(d.size(), 2u);
  ExpectDetection(d[0], 0, "chair", 0.81f, {4, 0, 8, 8});
  ExpectDetection(d[1], 1, "table", 0.4f, {2, 6, 4, 2});  // (2, 6, 4, 4) clipped at row 8
}

TEST(DetectorConfigTest, ValidateNamesTheBadField) {
  const DetectorConfig good = TinyConfig(DetectorOutputFormat::kMoslam);
  EXPECT_NO_THROW(good.validate());
  auto expect_bad = [&](auto change, const std::string& field) {
    DetectorConfig c = good;
    change(c);
    EXPECT_TRUE(test::ThrowsNaming([&] { c.validate(); }, field));
  };
  expect_bad([](DetectorConfig& c) { c.model_path.clear(); }, "model_path");
  expect_bad([](DetectorConfig& c) { c.class_names.clear(); }, "class_names");
  expect_bad([](DetectorConfig& c) { c.class_names_file = "x.txt"; }, "class_names_file");
  expect_bad([](DetectorConfig& c) { c.class_names[1].clear(); }, "class_names[1]");
  expect_bad([](DetectorConfig& c) { c.class_names[1] = c.class_names[0]; },
             "class_names[1] 'chair' repeats class_names[0]");
  expect_bad([](DetectorConfig& c) { c.input_width = 0; }, "input_width");
  expect_bad([](DetectorConfig& c) { c.input_height = -8; }, "input_height");
  expect_bad([](DetectorConfig& c) { c.confidence_threshold = 1.5f; }, "confidence_threshold");
  expect_bad([](DetectorConfig& c) { c.nms_iou_threshold = -0.1f; }, "nms_iou_threshold");
  expect_bad([](DetectorConfig& c) { c.format = DetectorOutputFormat::kDarknet; },
             "darknet_cfg_path");
  EXPECT_EQ(ParseDetectorOutputFormat("yolov5"), DetectorOutputFormat::kYolov5);
  EXPECT_EQ(ParseDetectorOutputFormat("yolov8"), DetectorOutputFormat::kYolov8);
  EXPECT_EQ(ParseDetectorOutputFormat("yolo11"), DetectorOutputFormat::kYolov8);
  EXPECT_EQ(ToString(ParseDetectorOutputFormat("darknet")), "darknet");
  EXPECT_THROW(ParseDetectorOutputFormat("yolo"), InvalidInputError);
}

TEST(DetectorLoad, ClassNamesFromFile) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.class_names.clear();
  c.class_names_file = kTestData + "/tiny_classes.txt";
  Detector detector(c);
  EXPECT_EQ(detector.classNames(), (std::vector<std::string>{"chair", "table"}));
  c.class_names_file = kTestData + "/no_such_classes.txt";
  EXPECT_THROW(Detector{c}, InvalidInputError);
}

TEST(ClassNames, TrimmedOnePerLineBlankLinesSkipped) {
  EXPECT_EQ(ParseClassNames("chair\r\n\n  \t\n\tdining table  \nsofa", "t.txt"),
            (std::vector<std::string>{"chair", "dining table", "sofa"}));
}

TEST(ClassNames, EmptyRepeatedOrBinaryNamesAreRefusedWithTheirLine) {
  const auto refused = [](const std::string& text, const std::string& expected) {
    return test::ThrowsNaming([&] { ParseClassNames(text, "names.txt"); }, expected);
  };
  EXPECT_TRUE(refused("", "'names.txt' hold no name"));
  EXPECT_TRUE(refused(" \n\r\n\t", "hold no name"));
  EXPECT_TRUE(refused("chair\ntable\n\nchair\n", "line 4: 'chair' repeats line 1"));
  EXPECT_TRUE(
      refused(std::string("chair\nta\0ble\n", 13), "line 2: the name holds control character 0"));
  EXPECT_TRUE(refused("chair\nta\x1b[1mble\n", "line 2: the name holds control character 27"));
}

TEST(DetectorLoad, MissingOrUnreadableModelIsATypedError) {
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.model_path = kTestData + "/no_such_model.onnx";
  try {
    Detector detector(c);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_model.onnx"), std::string::npos);
  }
  c.model_path = (test::ScratchDir() / "not_a_model.onnx").string();
  std::ofstream(c.model_path) << "this is not an ONNX protobuf\n";
  EXPECT_TRUE(test::ThrowsNaming([&] { Detector{c}; }, "(format moslam)"));
  // Darknet: the weights and their cfg file, each named when it cannot be used.
  c = TinyConfig(DetectorOutputFormat::kDarknet);
  c.darknet_cfg_path = kTestData + "/no_such.cfg";
  EXPECT_TRUE(test::ThrowsNaming([&] { Detector{c}; },
                                 "Darknet cfg file '" + c.darknet_cfg_path + "' does not exist"));
  c.darknet_cfg_path = (test::ScratchDir() / "not_a.cfg").string();
  std::ofstream(c.darknet_cfg_path) << "[net]\nwidth=abc\n[no_such_layer]\n";
  EXPECT_TRUE(test::ThrowsNaming([&] { Detector{c}; }, "(format darknet)"));
}

TEST(DetectorLoad, OutputShapeThatDoesNotFitIsATypedError) {
  // Three classes for a 2-class grid: 7 channels, 8 expected.
  DetectorConfig c = TinyConfig(DetectorOutputFormat::kMoslam);
  c.class_names = {"chair", "table", "sofa"};
  try {
    Detector detector(c);
    ADD_FAILURE() << "no exception";
  } catch (const InvalidInputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("[1, 7, 2, 2]"), std::string::npos) << what;
    EXPECT_NE(what.find("[1, 8, Gh, Gw]"), std::string::npos) << what;
  }
  // A yolov5 [1, N, 7] output read as a moslam grid, and the grid read as yolov5 rows.
  DetectorConfig y = TinyConfig(DetectorOutputFormat::kYolov5);
  y.format = DetectorOutputFormat::kMoslam;
  EXPECT_THROW(Detector{y}, InvalidInputError);
  DetectorConfig m = TinyConfig(DetectorOutputFormat::kMoslam);
  m.format = DetectorOutputFormat::kYolov5;
  EXPECT_THROW(Detector{m}, InvalidInputError);
}

TEST(DetectorDetect, RejectsBadImages) {
  Detector detector(TinyConfig(DetectorOutputFormat::kMoslam));
  EXPECT_THROW(detector.detect(cv::Mat()), InvalidInputError);
  EXPECT_THROW(detector.detect(cv::Mat::zeros(8, 8, CV_32FC1)), InvalidInputError);
  EXPECT_NO_THROW(detector.detect(cv::Mat::zeros(8, 8, CV_8UC1)));
}

TEST(DetectorTrainedModel, CommittedModelLoadsWithItsClasses) {
  // models/detector/moslam_yolo.onnx (training/train_detector.py): 13 classes, 320x240 input,
  // a [1, 18, 30, 40] grid. Loading runs it once and checks the output shape.
  DetectorConfig c;
  c.model_path = std::string(MOSLAM_DETECTOR_MODEL_DIR) + "/moslam_yolo.onnx";
  c.class_names_file = std::string(MOSLAM_DETECTOR_MODEL_DIR) + "/classes.txt";
  Detector detector(c);
  ASSERT_EQ(detector.classNames().size(), 13u);
  EXPECT_EQ(detector.classNames().front(), "chair");
  for (const Detection& d : detector.detect(cv::Mat(240, 320, CV_8UC3, cv::Scalar(90, 90, 90)))) {
    EXPECT_GE(d.confidence, 0.3f);
    EXPECT_GE(d.box.x, 0.0f);
    EXPECT_LE(d.box.x + d.box.width, 320.0f + 1e-3f);
  }
  EXPECT_EQ(detector.config().input_width, 320);
  // An input size its layers cannot take: the run at loading fails with the size and the likely
  // cause, not OpenCV's assertion alone.
  c.input_width = 33;
  c.input_height = 17;
  try {
    Detector wrong_size(c);
    ADD_FAILURE() << "no exception";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("failed to run on a 33x17 input (is the configured "
                                         "input size right for this model?)"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace moslam
