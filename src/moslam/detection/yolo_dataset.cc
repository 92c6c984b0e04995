#include "moslam/detection/yolo_dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "moslam/common/errors.h"
#include "moslam/common/number_text.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace fs = std::filesystem;

GroundTruthBox YoloLabel::toPixels(int image_width, int image_height) const {
  const float W = static_cast<float>(image_width), H = static_cast<float>(image_height);
  return {class_id, cv::Rect2f((cx - 0.5f * w) * W, (cy - 0.5f * h) * H, w * W, h * H)};
}

std::vector<YoloLabel> ReadYoloLabels(const std::string& path, int num_classes) {
  return ParseYoloLabels(ReadWholeFileOrThrow(path), path, num_classes);
}

std::vector<YoloLabel> ParseYoloLabels(const std::string& text, const std::string& path,
                                       int num_classes) {
  std::istringstream in(text);
  std::vector<YoloLabel> labels;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r\n") == std::string::npos) continue;
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    std::istringstream s(line);
    std::vector<std::string> tokens;
    for (std::string token; s >> token;) tokens.push_back(token);
    double id = 0.0;
    YoloLabel l;
    const bool numbers =
        tokens.size() == 5 && ParseNumberToken(tokens[0], id) == NumberStatus::kOk &&
        ParseNumberToken(tokens[1], l.cx) == NumberStatus::kOk &&
        ParseNumberToken(tokens[2], l.cy) == NumberStatus::kOk &&
        ParseNumberToken(tokens[3], l.w) == NumberStatus::kOk &&
        ParseNumberToken(tokens[4], l.h) == NumberStatus::kOk;
    if (!numbers) {
      throw InvalidInputError(where + "expected 'class_id cx cy w h', got '" + line + "'");
    }
    if (id != std::floor(id) || id < 0.0 || id >= num_classes) {
      throw InvalidInputError(where + "class id " + std::to_string(id) + " is not in [0, " +
                              std::to_string(num_classes) + ")");
    }
    l.class_id = static_cast<int>(id);
    for (float v : {l.cx, l.cy, l.w, l.h}) {
      if (!(v >= 0.0f && v <= 1.0f)) {
        throw InvalidInputError(where + "box values must be fractions in [0, 1], got '" + line +
                                "'");
      }
    }
    if (l.w <= 0.0f || l.h <= 0.0f) {
      throw InvalidInputError(where + "box width and height must be positive");
    }
    labels.push_back(l);
  }
  return labels;
}

YoloDataset ReadYoloDataset(const std::string& dir) {
  const fs::path root(dir);
  if (!fs::is_directory(root)) throw InvalidInputError("dataset folder '" + dir + "' not found");
  const fs::path classes = root / "classes.txt";
  const fs::path images = root / "images";
  if (!fs::is_regular_file(classes)) {
    throw InvalidInputError("dataset '" + dir + "' has no classes.txt");
  }
  if (!fs::is_directory(images)) throw InvalidInputError("dataset '" + dir + "' has no images/");
  YoloDataset data;
  data.class_names = ReadClassNames(classes.string());
  const int num_classes = static_cast<int>(data.class_names.size());
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(images)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp") {
      files.push_back(entry.path());
    }
  }
  if (files.empty()) throw InvalidInputError("dataset '" + dir + "': images/ holds no image");
  std::sort(files.begin(), files.end());
  data.has_ignore = fs::is_directory(root / "ignore");
  for (const fs::path& f : files) {
    YoloSample s;
    s.image_path = f.string();
    s.label_path = (root / "labels" / f.stem()).string() + ".txt";
    if (fs::exists(s.label_path)) s.labels = ReadYoloLabels(s.label_path, num_classes);
    const std::string ignore_path = (root / "ignore" / f.stem()).string() + ".txt";
    if (data.has_ignore && fs::exists(ignore_path)) {
      s.ignore = ReadYoloLabels(ignore_path, num_classes);
    }
    data.samples.push_back(std::move(s));
  }
  return data;
}

}  // namespace moslam
