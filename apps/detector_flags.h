// The detector's operating point as flags, shared by `moslam detect` and `moslam perceive`: the
// score threshold, the NMS IoU and kind, and the flip test. The defaults are DetectorConfig's.
#pragma once

#include <CLI/CLI.hpp>

#include "moslam/detection/detector.h"

namespace moslam::cli {

struct DetectorFlags {
  float threshold = DetectorConfig{}.confidence_threshold;
  float nms = DetectorConfig{}.nms_iou_threshold;
  bool agnostic_nms = DetectorConfig{}.class_agnostic_nms;
  bool flip_test = DetectorConfig{}.flip_test;
  void applyTo(DetectorConfig* config) const {
    config->confidence_threshold = threshold;
    config->nms_iou_threshold = nms;
    config->class_agnostic_nms = agnostic_nms;
    config->flip_test = flip_test;
  }
};

// --threshold, --nms, --agnostic-nms / --per-class-nms and --no-flip-test, written into `flags`
// (which must outlive the parse).
inline void AddDetectorFlags(CLI::App* sub, DetectorFlags* flags) {
  sub->add_option("--threshold", flags->threshold, "score threshold (objectness x class prob.)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  sub->add_option("--nms", flags->nms, "NMS IoU threshold")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  sub->add_flag("--agnostic-nms,!--per-class-nms", flags->agnostic_nms,
                "NMS over all boxes whatever their class (the default), or per class "
                "(models/detector/README.md: the two measured)");
  sub->add_flag("!--no-flip-test", flags->flip_test,
                "run the network on the image only (default: on the image and its mirror image, "
                "the two passes' scores averaged)");
}

}  // namespace moslam::cli
