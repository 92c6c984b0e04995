#include "moslam/detection/evaluation.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

Detection Det(int class_id, float confidence, cv::Rect2f box) {
  return {class_id, class_id == 0 ? "chair" : "table", confidence, box};
}

TEST(BoxIou, HandComputedCases) {
  EXPECT_DOUBLE_EQ(BoxIou({0, 0, 10, 10}, {0, 0, 10, 10}), 1.0);
  EXPECT_NEAR(BoxIou({1, 0, 10, 10}, {0, 0, 10, 10}), 90.0 / 110.0, 1e-12);
  EXPECT_DOUBLE_EQ(BoxIou({0, 0, 10, 10}, {0, 0, 10, 20}), 0.5);
  EXPECT_DOUBLE_EQ(BoxIou({0, 0, 10, 10}, {10, 0, 10, 10}), 0.0);  // touching
  EXPECT_DOUBLE_EQ(BoxIou({0, 0, 0, 10}, {0, 0, 10, 10}), 0.0);    // empty
}

TEST(AveragePrecision, AllPointInterpolation) {
  // TP, FP, TP out of 2: precision 1, 1/2, 2/3 at recall 1/2, 1/2, 1; the envelope gives
  // 1/2 * 1 + 1/2 * 2/3.
  EXPECT_NEAR(AveragePrecision({true, false, true}, 2), 0.5 + 1.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(AveragePrecision({true, true}, 2), 1.0);
  EXPECT_DOUBLE_EQ(AveragePrecision({true, true}, 4), 0.5);  // half the objects never found
  // FP first: precision 0 then 1/2 at recall 1: the envelope is 1/2 everywhere.
  EXPECT_DOUBLE_EQ(AveragePrecision({false, true}, 1), 0.5);
  EXPECT_DOUBLE_EQ(AveragePrecision({false, false}, 3), 0.0);
  EXPECT_DOUBLE_EQ(AveragePrecision({}, 3), 0.0);
  EXPECT_DOUBLE_EQ(AveragePrecision({true}, 0), 0.0);
}

TEST(DetectionEvaluator, GreedyMatchingPrecisionRecallAndMap) {
  DetectionEvaluator eval({"chair", "table"});
  const std::vector<GroundTruthBox> gt = {
      {0, {0, 0, 10, 10}}, {0, {20, 0, 10, 10}}, {1, {40, 0, 10, 10}}};
  const std::vector<Detection> dets = {
      Det(0, 0.8f, {0, 0, 10, 10}),   // duplicate of the first: FP (the 0.9 one came first)
      Det(0, 0.9f, {1, 0, 10, 10}),   // IoU 0.82 with gt 0: TP
      Det(0, 0.2f, {20, 0, 10, 10}),  // TP, but below the 0.3 threshold: only in the AP
      Det(1, 0.7f, {0, 0, 10, 10}),   // a table on a chair: FP
      Det(1, 0.6f, {40, 5, 10, 10}),  // IoU 1/3 with the table: FP
  };
  eval.addFrame(dets, gt);
  const DetectionMetrics m = eval.compute();
  EXPECT_EQ(m.frames, 1);
  ASSERT_EQ(m.per_class.size(), 2u);
  const ClassMetrics& chair = m.per_class[0];
  EXPECT_EQ(chair.label, "chair");
  EXPECT_EQ(chair.ground_truths, 2);
  EXPECT_EQ(chair.true_positives, 1);
  EXPECT_EQ(chair.false_positives, 1);
  EXPECT_DOUBLE_EQ(chair.precision, 0.5);
  EXPECT_DOUBLE_EQ(chair.recall, 0.5);
  EXPECT_NEAR(chair.average_precision, 0.5 + 1.0 / 3.0, 1e-12);
  const ClassMetrics& table = m.per_class[1];
  EXPECT_EQ(table.ground_truths, 1);
  EXPECT_EQ(table.true_positives, 0);
  EXPECT_EQ(table.false_positives, 2);
  EXPECT_DOUBLE_EQ(table.precision, 0.0);
  EXPECT_DOUBLE_EQ(table.recall, 0.0);
  EXPECT_DOUBLE_EQ(table.average_precision, 0.0);
  EXPECT_EQ(m.ground_truths, 3);
  EXPECT_EQ(m.true_positives, 1);
  EXPECT_EQ(m.false_positives, 3);
  EXPECT_DOUBLE_EQ(m.precision, 0.25);
  EXPECT_NEAR(m.recall, 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(m.mean_average_precision, (0.5 + 1.0 / 3.0) / 2.0, 1e-12);
}

TEST(DetectionEvaluator, FramesAreMatchedSeparatelyAndIouThresholdIsInclusive) {
  DetectionEvaluator eval({"chair", "table"});
  // IoU exactly 0.5 matches.
  eval.addFrame({Det(0, 0.9f, {0, 0, 10, 10})}, {{0, {0, 0, 10, 20}}});
  // The same box in another frame has no object to match.
  eval.addFrame({Det(0, 0.95f, {0, 0, 10, 10})}, {});
  // A class with no ground truth and no detection does not enter the mAP.
  const DetectionMetrics m = eval.compute();
  EXPECT_EQ(m.frames, 2);
  EXPECT_EQ(m.per_class[0].true_positives, 1);
  EXPECT_EQ(m.per_class[0].false_positives, 1);
  EXPECT_DOUBLE_EQ(m.per_class[0].recall, 1.0);
  // Order 0.95 FP, 0.9 TP: AP = 1/2.
  EXPECT_DOUBLE_EQ(m.per_class[0].average_precision, 0.5);
  EXPECT_DOUBLE_EQ(m.mean_average_precision, 0.5);
}

TEST(DetectionEvaluator, DetectionOnAnIgnoreBoxIsDroppedElsewhereStillAFalsePositive) {
  const std::vector<GroundTruthBox> gt = {{0, {0, 0, 10, 10}}};
  const std::vector<GroundTruthBox> ignore = {{0, {50, 0, 10, 10}}};
  const std::vector<Detection> dets = {
      Det(0, 0.95f, {51, 0, 10, 10}),  // on the ignore box (IoU 0.82): dropped
      Det(0, 0.9f, {0, 0, 10, 10}),    // TP
      Det(0, 0.7f, {100, 0, 10, 10}),  // on nothing: FP
      Det(0, 0.1f, {50, 0, 10, 10}),   // below the threshold, on the ignore box: not in the AP
      Det(1, 0.8f, {50, 0, 10, 10}),   // a table on the ignored chair: other class, FP
      Det(0, 0.6f, {55, 0, 10, 10}),   // IoU 1/3 with the ignore box: FP
  };
  DetectionEvaluator strict({"chair", "table"});
  strict.addFrame(dets, gt);
  DetectionEvaluator with_ignore({"chair", "table"});
  with_ignore.addFrame(dets, gt, ignore);

  const DetectionMetrics s = strict.compute();
  EXPECT_EQ(s.per_class[0].true_positives, 1);
  EXPECT_EQ(s.per_class[0].false_positives, 3);
  EXPECT_EQ(s.per_class[0].ignored_detections, 0);
  EXPECT_EQ(s.ignore_boxes, 0);
  // 0.95 FP, 0.9 TP, ...: AP 1/2.
  EXPECT_DOUBLE_EQ(s.per_class[0].average_precision, 0.5);

  const DetectionMetrics m = with_ignore.compute();
  EXPECT_EQ(m.ignore_boxes, 1);
  const ClassMetrics& chair = m.per_class[0];
  EXPECT_EQ(chair.ground_truths, 1);  // the ignore box is not an object to find
  EXPECT_EQ(chair.true_positives, 1);
  EXPECT_EQ(chair.false_positives, 2);
  EXPECT_EQ(chair.ignored_detections, 1);  // the 0.1 one is below the threshold
  EXPECT_NEAR(chair.precision, 1.0 / 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(chair.recall, 1.0);
  // 0.9 TP first: AP 1.
  EXPECT_DOUBLE_EQ(chair.average_precision, 1.0);
  EXPECT_EQ(m.per_class[1].false_positives, 1);
  EXPECT_EQ(m.per_class[1].ignored_detections, 0);
  EXPECT_EQ(m.true_positives, 1);
  EXPECT_EQ(m.false_positives, 3);
  EXPECT_EQ(m.ignored_detections, 1);
  EXPECT_DOUBLE_EQ(m.precision, 0.25);
}

TEST(DetectionEvaluator, GroundTruthMatchTakesPrecedenceOverAnIgnoreBox) {
  DetectionEvaluator eval({"chair"});
  // An ignore box on the same spot as a labelled chair: the detection is the chair's TP.
  eval.addFrame({Det(0, 0.9f, {0, 0, 10, 10})}, {{0, {0, 0, 10, 10}}}, {{0, {0, 0, 10, 10}}});
  // An ignore box alone with no detection is no miss.
  eval.addFrame({}, {}, {{0, {0, 0, 10, 10}}});
  const DetectionMetrics m = eval.compute();
  EXPECT_EQ(m.ignore_boxes, 2);
  EXPECT_EQ(m.ground_truths, 1);
  EXPECT_EQ(m.true_positives, 1);
  EXPECT_EQ(m.false_positives, 0);
  EXPECT_EQ(m.ignored_detections, 0);
  EXPECT_DOUBLE_EQ(m.recall, 1.0);
  EXPECT_DOUBLE_EQ(m.mean_average_precision, 1.0);
}

TEST(DetectionEvaluator, RejectsBadInput) {
  EvaluationOptions bad;
  bad.iou_threshold = 0.0f;
  EXPECT_THROW(DetectionEvaluator({"chair"}, bad), InvalidInputError);
  bad = {};
  bad.confidence_threshold = 2.0f;
  EXPECT_THROW(DetectionEvaluator({"chair"}, bad), InvalidInputError);
  EXPECT_THROW(DetectionEvaluator({}), InvalidInputError);
  DetectionEvaluator eval({"chair"});
  EXPECT_THROW(eval.addFrame({Det(1, 0.9f, {0, 0, 1, 1})}, {}), InvalidInputError);
  EXPECT_THROW(eval.addFrame({}, {{-1, {0, 0, 1, 1}}}), InvalidInputError);
  EXPECT_THROW(eval.addFrame({}, {}, {{1, {0, 0, 1, 1}}}), InvalidInputError);
}

}  // namespace
}  // namespace moslam
