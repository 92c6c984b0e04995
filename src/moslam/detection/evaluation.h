// Detection metrics against ground-truth boxes: precision and recall at a confidence
// threshold, average precision per class (all-point interpolated, PASCAL VOC 2010+ style) and
// mAP at one IoU threshold (0.5: "mAP@0.5").
//
// Matching (per frame and class): detections in decreasing confidence each take the unmatched
// ground-truth box of their class with the highest IoU, if that IoU is >= iou_threshold (true
// positive); otherwise they are false positives. Each ground-truth box is matched at most once,
// so duplicates of one object count as false positives. Boxes are in pixels (any consistent
// unit); IoU is area(intersection) / area(union).
//
// Ignore regions (optional, PASCAL VOC `difficult` / COCO `iscrowd` style): boxes of objects that
// are visible but deliberately not labelled (e.g. too small or mostly outside the image; see
// DIR/ignore/ in detection/yolo_dataset.h). A detection that matches no ground-truth box but
// overlaps an ignore box of its class with IoU >= iou_threshold is dropped: neither a true nor a
// false positive, in precision, recall and AP alike. Ground-truth matching comes first, so an
// ignore box never takes a detection a ground-truth box would take; one ignore box may absorb
// several detections (as in VOC and COCO); ignore boxes never count as misses. Without ignore
// boxes the metrics are the strict ones.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "moslam/detection/detector.h"

namespace moslam {

struct GroundTruthBox {
  int class_id = -1;
  cv::Rect2f box;
};

struct EvaluationOptions {
  float iou_threshold = 0.5f;         // a detection matches a ground-truth box at IoU >= this
  float confidence_threshold = 0.3f;  // precision / recall count detections with score >= this
  // Throws InvalidInputError naming the bad field (thresholds outside [0, 1], iou 0).
  void validate() const;
};

struct ClassMetrics {
  int class_id = -1;
  std::string label;
  int ground_truths = 0;
  // At confidence >= confidence_threshold:
  int true_positives = 0;
  int false_positives = 0;
  int ignored_detections = 0;  // dropped on an ignore box (neither tp nor fp)
  double precision = 0.0;  // tp / (tp + fp); 0 when there is no detection
  double recall = 0.0;     // tp / ground_truths; 0 when there is no ground truth
  // Over all detections given (whatever their confidence); 0 when there is no ground truth.
  double average_precision = 0.0;
};

struct DetectionMetrics {
  int frames = 0;
  std::vector<ClassMetrics> per_class;  // one per class, in class-id order
  // Over all classes at confidence >= confidence_threshold (micro average).
  int ground_truths = 0;
  int true_positives = 0;
  int false_positives = 0;
  int ignored_detections = 0;
  int ignore_boxes = 0;  // given to addFrame, all frames
  double precision = 0.0;
  double recall = 0.0;
  // Mean of average_precision over the classes that have at least one ground-truth box.
  double mean_average_precision = 0.0;
};

// IoU of two boxes; 0 when either is empty.
double BoxIou(const cv::Rect2f& a, const cv::Rect2f& b);

// All-point interpolated average precision of detections sorted by decreasing confidence, with
// is_true_positive[i] for each, out of `ground_truths` objects: the area under the precision-
// recall curve after making precision monotonically non-increasing. 0 if ground_truths is 0.
double AveragePrecision(const std::vector<bool>& is_true_positive, int ground_truths);

// Accumulates frames, then computes the metrics. Detections below the threshold may (and for
// a fair AP should) be given: they only enter the AP.
class DetectionEvaluator {
 public:
  // Throws InvalidInputError for bad options or an empty class list.
  DetectionEvaluator(std::vector<std::string> class_names, EvaluationOptions options = {});

  // One frame, with optional ignore boxes (see above). Throws InvalidInputError if a class id is
  // outside [0, number of classes).
  void addFrame(const std::vector<Detection>& detections,
                const std::vector<GroundTruthBox>& ground_truth,
                const std::vector<GroundTruthBox>& ignore = {});

  DetectionMetrics compute() const;

 private:
  struct Scored {
    float confidence;
    bool true_positive;
  };
  std::vector<std::string> names_;
  EvaluationOptions options_;
  int frames_ = 0;
  std::vector<std::vector<Scored>> scored_;  // per class
  std::vector<int> ground_truths_;           // per class
  std::vector<int> ignored_;                 // per class, at confidence >= threshold
  int ignore_boxes_ = 0;
};

}  // namespace moslam
