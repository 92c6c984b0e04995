// Datasets in the YOLO text layout (what `moslam render --format yolo` writes and what
// training/train_detector.py reads):
//   DIR/classes.txt        one class name per line, line i = class id i
//   DIR/images/NAME.png    images (also .jpg/.jpeg/.bmp)
//   DIR/labels/NAME.txt    one object per line: `class_id cx cy w h`, the box centre and size
//                          as fractions of the image width and height, in [0, 1]; a missing or
//                          empty label file means an image without objects.
//   DIR/ignore/NAME.txt    optional, same format: visible objects that are deliberately not
//                          labelled (too small, mostly outside the image), for evaluation as
//                          ignore regions (detection/evaluation.h). Written by
//                          `moslam render --format yolo`; other YOLO datasets simply lack it.
#pragma once

#include <string>
#include <vector>

#include "moslam/detection/evaluation.h"

namespace moslam {

struct YoloLabel {
  int class_id = -1;
  float cx = 0.0f, cy = 0.0f, w = 0.0f, h = 0.0f;  // fractions of the image size

  // Pixel box (top-left corner, size) in an image of the given size.
  GroundTruthBox toPixels(int image_width, int image_height) const;
};

struct YoloSample {
  std::string image_path;
  std::string label_path;  // may not exist (no objects)
  std::vector<YoloLabel> labels;
  std::vector<YoloLabel> ignore;  // from DIR/ignore/NAME.txt when it exists
};

struct YoloDataset {
  std::vector<std::string> class_names;
  std::vector<YoloSample> samples;  // sorted by image file name
  bool has_ignore = false;          // DIR/ignore/ exists
};

// Reads one label file. Throws InvalidInputError naming the file and line for a malformed line
// (not five fields, a class id outside [0, num_classes), a value outside [0, 1], a non-positive
// size).
std::vector<YoloLabel> ReadYoloLabels(const std::string& path, int num_classes);
// The same on a label file's text; `path` names it in the messages.
std::vector<YoloLabel> ParseYoloLabels(const std::string& text, const std::string& path,
                                       int num_classes);

// Reads DIR (layout above). Throws InvalidInputError if DIR, classes.txt or images/ is missing,
// images/ holds no image, or a label or ignore file is malformed.
YoloDataset ReadYoloDataset(const std::string& dir);

}  // namespace moslam
