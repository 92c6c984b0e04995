// An ideal front-end on rendered frames (`moslam simulate --perception visible`): every object
// the rendered frame of a pose shows enough of, within the sensor's depth range, is measured,
// with Gaussian noise as the sampled measurements (sim/sensing.h), and nothing else is. No
// front-end working on these frames could measure an object the frame does not show, nor beat a
// perfect detector and registration of this accuracy; so against the sampled measurements (every
// object in the sampled camera's frustum and range, seen through walls and other objects) and
// against the real front-end (perception/rendered_sensing.h) it splits the map's error into what
// the frames show and what the front-end makes of them.
#pragma once

#include "moslam/render/renderer.h"
#include "moslam/sim/sensing.h"

namespace moslam {

struct VisibleSensingConfig {
  RenderConfig render;
  // An object is measured when at least this share of its silhouette is seen
  // (VisibleObject::visibleFraction: not occluded, inside the image), the population of the
  // perception front-end's acceptance figures (RenderedSensingConfig::min_visible_fraction), and
  // its centre lies in front of the camera no farther than render.max_depth (beyond it the sensor
  // returns no depth to register).
  double min_visible_fraction = 0.3;
  // The measurements' noise and information (NoiseModel::information with this floor); the
  // default is the paper's 5 deg / 0.2 m.
  NoiseModel noise;
  double information_sigma_floor = 1e-3;  // rad and m
  // Each object seen enough is measured with this probability (a front-end accepting that share
  // of the views, at random). 1: all.
  double keep_probability = 1.0;
  int every = 1;  // frames of every `every`-th pose (1: all); the other poses get no measurement
  // The noise and keep draws: a generator per frame, seeded by (seed, robot, pose).
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct VisibleSensingStats {
  int frames = 0;
  int replaced = 0;     // object measurements the poses had before (the sampled ones)
  int seen_enough = 0;  // objects seen enough within the depth range, over the frames
  int measured = 0;     // ... and measured (all of them unless keep_probability < 1)
  double render_ms = 0.0;
};

// Replaces data.measurements[r].detections by the ideal front-end's on the frames of every
// `every`-th pose (SimulationFrameKey: the frames of perception/rendered_sensing.h),
// in the order of the frame's objects; object_id is the world object's. Throws InvalidInputError
// on a bad config or data without measurements.
VisibleSensingStats MeasureVisibleObjects(SimulationData& data, const VisibleSensingConfig& config);

}  // namespace moslam
