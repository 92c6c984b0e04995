#include "moslam/detection/evaluation.h"

#include <algorithm>
#include <numeric>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

void EvaluationOptions::validate() const {
  if (!(iou_threshold > 0.0f && iou_threshold <= 1.0f)) {
    throw InvalidInputError("EvaluationOptions.iou_threshold must be in (0, 1]");
  }
  if (!(confidence_threshold >= 0.0f && confidence_threshold <= 1.0f)) {
    throw InvalidInputError("EvaluationOptions.confidence_threshold must be in [0, 1]");
  }
}

double BoxIou(const cv::Rect2f& a, const cv::Rect2f& b) {
  if (a.width <= 0.0f || a.height <= 0.0f || b.width <= 0.0f || b.height <= 0.0f) return 0.0;
  const double ix = std::max(0.0, std::min<double>(a.x + a.width, b.x + b.width) -
                                      std::max<double>(a.x, b.x));
  const double iy = std::max(0.0, std::min<double>(a.y + a.height, b.y + b.height) -
                                      std::max<double>(a.y, b.y));
  const double inter = ix * iy;
  const double uni = static_cast<double>(a.width) * a.height +
                     static_cast<double>(b.width) * b.height - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

double AveragePrecision(const std::vector<bool>& is_true_positive, int ground_truths) {
  if (ground_truths <= 0) return 0.0;
  const std::size_t n = is_true_positive.size();
  // Precision-recall points after each detection, with the sentinels (0, .) and (., 0).
  std::vector<double> recall(n + 2, 0.0), precision(n + 2, 0.0);
  int tp = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (is_true_positive[i]) ++tp;
    recall[i + 1] = static_cast<double>(tp) / ground_truths;
    precision[i + 1] = static_cast<double>(tp) / static_cast<double>(i + 1);
  }
  recall[n + 1] = recall[n];
  precision[n + 1] = 0.0;
  // Monotone envelope from the right, then the area where recall changes.
  for (std::size_t i = n + 1; i-- > 0;) precision[i] = std::max(precision[i], precision[i + 1]);
  double ap = 0.0;
  for (std::size_t i = 1; i < n + 2; ++i) ap += (recall[i] - recall[i - 1]) * precision[i];
  return ap;
}

DetectionEvaluator::DetectionEvaluator(std::vector<std::string> class_names,
                                       EvaluationOptions options)
    : names_(std::move(class_names)), options_(options) {
  options_.validate();
  if (names_.empty()) throw InvalidInputError("DetectionEvaluator: the class list is empty");
  scored_.resize(names_.size());
  ground_truths_.assign(names_.size(), 0);
  ignored_.assign(names_.size(), 0);
}

void DetectionEvaluator::addFrame(const std::vector<Detection>& detections,
                                  const std::vector<GroundTruthBox>& ground_truth,
                                  const std::vector<GroundTruthBox>& ignore) {
  const int num_classes = static_cast<int>(names_.size());
  for (const Detection& d : detections) {
    if (d.class_id < 0 || d.class_id >= num_classes) {
      throw InvalidInputError("DetectionEvaluator: detection class id " +
                              std::to_string(d.class_id) + " is outside [0, " +
                              std::to_string(num_classes) + ")");
    }
  }
  for (const GroundTruthBox& g : ground_truth) {
    if (g.class_id < 0 || g.class_id >= num_classes) {
      throw InvalidInputError("DetectionEvaluator: ground-truth class id " +
                              std::to_string(g.class_id) + " is outside [0, " +
                              std::to_string(num_classes) + ")");
    }
    ++ground_truths_[static_cast<std::size_t>(g.class_id)];
  }
  for (const GroundTruthBox& g : ignore) {
    if (g.class_id < 0 || g.class_id >= num_classes) {
      throw InvalidInputError("DetectionEvaluator: ignore-box class id " +
                              std::to_string(g.class_id) + " is outside [0, " +
                              std::to_string(num_classes) + ")");
    }
  }
  ignore_boxes_ += static_cast<int>(ignore.size());
  std::vector<std::size_t> order(detections.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return detections[a].confidence > detections[b].confidence;
  });
  std::vector<bool> taken(ground_truth.size(), false);
  for (std::size_t i : order) {
    const Detection& d = detections[i];
    double best_iou = 0.0;
    std::size_t best = ground_truth.size();
    for (std::size_t g = 0; g < ground_truth.size(); ++g) {
      if (taken[g] || ground_truth[g].class_id != d.class_id) continue;
      const double iou = BoxIou(d.box, ground_truth[g].box);
      if (iou > best_iou) {
        best_iou = iou;
        best = g;
      }
    }
    const bool tp = best < ground_truth.size() && best_iou >= options_.iou_threshold;
    if (tp) taken[best] = true;
    if (!tp && std::any_of(ignore.begin(), ignore.end(), [&](const GroundTruthBox& g) {
          return g.class_id == d.class_id && BoxIou(d.box, g.box) >= options_.iou_threshold;
        })) {
      if (d.confidence >= options_.confidence_threshold) {
        ++ignored_[static_cast<std::size_t>(d.class_id)];
      }
      continue;  // on an ignore region: neither a true nor a false positive
    }
    scored_[static_cast<std::size_t>(d.class_id)].push_back({d.confidence, tp});
  }
  ++frames_;
}

DetectionMetrics DetectionEvaluator::compute() const {
  DetectionMetrics m;
  m.frames = frames_;
  m.ignore_boxes = ignore_boxes_;
  double ap_sum = 0.0;
  int ap_classes = 0;
  for (std::size_t c = 0; c < names_.size(); ++c) {
    std::vector<Scored> s = scored_[c];
    std::stable_sort(s.begin(), s.end(),
                     [](const Scored& a, const Scored& b) { return a.confidence > b.confidence; });
    ClassMetrics cm;
    cm.class_id = static_cast<int>(c);
    cm.label = names_[c];
    cm.ground_truths = ground_truths_[c];
    cm.ignored_detections = ignored_[c];
    std::vector<bool> tp_flags;
    tp_flags.reserve(s.size());
    for (const Scored& x : s) {
      tp_flags.push_back(x.true_positive);
      if (x.confidence >= options_.confidence_threshold) {
        (x.true_positive ? cm.true_positives : cm.false_positives) += 1;
      }
    }
    const int detected = cm.true_positives + cm.false_positives;
    cm.precision = detected > 0 ? static_cast<double>(cm.true_positives) / detected : 0.0;
    cm.recall = cm.ground_truths > 0
                    ? static_cast<double>(cm.true_positives) / cm.ground_truths
                    : 0.0;
    cm.average_precision = AveragePrecision(tp_flags, cm.ground_truths);
    if (cm.ground_truths > 0) {
      ap_sum += cm.average_precision;
      ++ap_classes;
    }
    m.ground_truths += cm.ground_truths;
    m.true_positives += cm.true_positives;
    m.false_positives += cm.false_positives;
    m.ignored_detections += cm.ignored_detections;
    m.per_class.push_back(cm);
  }
  const int detected = m.true_positives + m.false_positives;
  m.precision = detected > 0 ? static_cast<double>(m.true_positives) / detected : 0.0;
  m.recall = m.ground_truths > 0 ? static_cast<double>(m.true_positives) / m.ground_truths : 0.0;
  m.mean_average_precision = ap_classes > 0 ? ap_sum / ap_classes : 0.0;
  return m;
}

}  // namespace moslam
