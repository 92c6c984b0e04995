// Rendered datasets of the simulated scenarios: the camera views along the robots' trajectories
// and their export as a detector training set in the YOLO layout (what torch users expect).
//
// YOLO layout written by ExportYoloDataset into DIR:
//   DIR/images/NNNNNN.png   colour frames (8-bit BGR PNG), N = frame index, 6 digits
//   DIR/labels/NNNNNN.txt   one line per labelled object: "class_id cx cy w h", the box of its
//                           visible pixels normalised by the image width/height (all in [0, 1]);
//                           an empty file when no object qualifies
//   DIR/ignore/NNNNNN.txt   same line format: every visible object of a standard class that is
//                           NOT labelled (too few visible pixels or mostly outside the image),
//                           with the box of its visible pixels; an empty file when there is none.
//                           Evaluators use them as "ignore" regions (PASCAL VOC `difficult`,
//                           COCO `iscrowd`): a detection on such an object is neither a true nor a
//                           false positive (detection/evaluation.h). Training ignores this folder.
//   DIR/classes.txt         the class labels, one per line, line i = class_id i
//                           (the order of StandardObjectClasses())
//   DIR/frames_NNNNNN-MMMMMM.json  what made each frame of one export run (scenario, seed,
//                           robot, step, world_T_camera, every visible object's pose and box)
// An object is labelled when it has at least min_visible_pixels visible pixels and at least
// min_in_image_fraction of its projected extent box inside the image (not mostly cut by the
// border). Objects whose label is not a standard class are never labelled.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/render/renderer.h"
#include "moslam/sim/world.h"

namespace moslam {

struct ScenarioViewsConfig {
  std::string scenario = "chairs25";  // chairs25 | house | generated (sim/world.h)
  int num_robots = 2;
  int poses_per_robot = 100;
  unsigned seed = 1;  // world (chairs' yaws, generated layout), trajectories and jitter
  // Views per robot: 0 = every pose; otherwise this many poses evenly spread over the trajectory.
  int frames_per_robot = 0;
  // Viewpoint variety: uniform jitter of the body's yaw, pitch and height around each pose.
  double yaw_jitter_deg = 0.0;
  double pitch_jitter_deg = 0.0;
  double height_jitter_m = 0.0;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct View {
  int robot = 0;
  int step = 0;        // pose index on the robot's trajectory (time step)
  SE3 world_T_body;    // jittered when the config asks for it
};

struct ScenarioViews {
  ScenarioViewsConfig config;  // what made them
  World world;
  std::vector<View> views;  // robot-major: all views of robot 0 by step, then robot 1, ...
};

ScenarioViews MakeScenarioViews(const ScenarioViewsConfig& config);

struct YoloLabelConfig {
  int min_visible_pixels = 150;
  double min_in_image_fraction = 0.5;
  // ExportYoloDataset skips views with fewer labelled objects (0 = keep every view; 1 drops the
  // views of bare walls and floor).
  int min_labels_per_frame = 0;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// The label lines of one frame ("class_id cx cy w h", 6 decimals), class ids from `classes`.
std::vector<std::string> YoloLabelLines(const RenderedFrame& frame,
                                        const std::vector<ObjectClass>& classes,
                                        const YoloLabelConfig& config);

// The ignore lines of one frame: the standard-class objects YoloLabelLines leaves out, same format.
std::vector<std::string> YoloIgnoreLines(const RenderedFrame& frame,
                                         const std::vector<ObjectClass>& classes,
                                         const YoloLabelConfig& config);

struct YoloExportSummary {
  int frames = 0;          // written
  int skipped_frames = 0;  // views with fewer than min_labels_per_frame labels
  int labels = 0;
  int ignored = 0;  // lines written to DIR/ignore/
  std::vector<int> labels_per_class;  // indexed like StandardObjectClasses()
  double render_seconds = 0.0;        // time inside Renderer::render
  double total_seconds = 0.0;
};

// Renders every view and writes the kept ones as frames first_index, first_index + 1, ... into
// `dir` (created when missing; existing files of the same indices are overwritten). `progress(done, total)` is
// called after each frame when given. Throws moslam::Error when a file cannot be written.
YoloExportSummary ExportYoloDataset(const Renderer& renderer, const ScenarioViews& views,
                                    const std::string& dir, int first_index,
                                    const YoloLabelConfig& labels,
                                    const std::function<void(int, int)>& progress = {});

}  // namespace moslam
