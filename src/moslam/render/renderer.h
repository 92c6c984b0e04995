// A deterministic CPU z-buffer renderer of organized RGB-D frames of a simulated World, with
// per-pixel ground truth (object instance ids, visible 2D boxes, object poses).
//
// Scene: every object of the world drawn with its class model (render/object_models.h) at its
// pose; a tiled floor at z = 0 (world frame, z up); optionally walls along the world's rooms
// (sim/world.h), 2.5 m high, with a door gap wherever a navigation edge crosses a room side.
// Shading is Lambert (ambient + diffuse) with one directional light; colours are procedural.
//
// Camera: camera = body * BodyFromCamera() (render/rgbd.h: optical frame z forward, x right,
// y down, at the body origin looking along body x). Pixel centres are at integer (u, v).
// Depth is z in the camera frame (metres); pixels whose true depth lies outside
// [min_depth, max_depth] have no return (0) but keep their colour and instance id.
//
// Noise (seeded by RenderConfig::seed and the frame key passed to render(), so the same pair
// gives identical bytes on every run):
//   depth:  z + N(0, sigma(z)^2) per pixel, sigma(z) = a + b (z - z0)^2 (AxialDepthNoise, whose
//           defaults a = 0.0012 m, b = 0.0019 1/m, z0 = 0.4 m are the axial noise of a Kinect
//           measured by Nguyen, Izadi and Lovell, 3DIMPVT 2012). The noisy depth is rounded to the
//           1/5000 m quantisation of TUM depth files when quantize_depth is set.
//   colour: N(0, colour_noise_sigma^2) added per channel (8-bit units), saturated.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/render/object_models.h"
#include "moslam/render/rgbd.h"
#include "moslam/sim/world.h"

namespace moslam {

// Colours of the room (floor tiles, walls) and the light; varied per world for detector
// training (RandomSceneStyle).
struct SceneStyle {
  cv::Vec3b floor_a_bgr{150, 175, 195};
  cv::Vec3b floor_b_bgr{120, 145, 170};
  double floor_tile_m = 0.5;
  cv::Vec3b wall_bgr{215, 225, 230};
  cv::Vec3b background_bgr{90, 80, 70};  // pixels that see nothing (beyond the scene)
  Vector3 light_direction{0.35, 0.25, 1.0};  // world frame, towards the light (normalised)
  double ambient = 0.45;
  double diffuse = 0.6;
};

// A random style (floor and wall colours, tile size, light direction) drawn from `seed`.
SceneStyle RandomSceneStyle(unsigned seed);

struct RenderConfig {
  PinholeIntrinsics intrinsics = PinholeIntrinsics::FromHorizontalFov(320, 240, 60.0);
  double min_depth = 0.4;  // m; nearer surfaces have no depth return
  double max_depth = 8.0;  // m; farther surfaces have no depth return
  bool draw_floor = true;
  bool draw_walls = true;
  double wall_height = 2.5;  // m
  double door_width = 1.0;   // m, gap in a wall where a navigation edge crosses it
  SceneStyle style;
  // Depth noise N(0, sigma(z)^2), sigma from depth_noise_model (render/rgbd.h).
  bool depth_noise = true;
  AxialDepthNoise depth_noise_model;
  bool quantize_depth = true;       // round depth to 1/5000 m (TUM PNG units)
  double colour_noise_sigma = 2.0;  // 8-bit units; 0 = none
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// Ground truth of one object seen in a frame.
struct VisibleObject {
  int id = 0;                // ObjectInstance::id
  std::string label;
  cv::Rect box;              // tight box of its visible pixels (x, y, width, height)
  int visible_pixels = 0;    // pixels where it is the nearest surface
  SE3 camera_T_object;       // pose of the object in the camera optical frame
  // Pixels of the image its own surfaces cover, whatever is in front of them (its silhouette
  // cut by the image border): visible_pixels / silhouette_pixels is the share not occluded.
  int silhouette_pixels = 0;
  // Share of the object's projected extent box (the 2D box of its 8 extent corners) that lies
  // inside the image: 1 = not cut by the border; 0 when a corner is behind the camera.
  double in_image_fraction = 0.0;
  // The share of the object's silhouette seen in the frame: not occluded (visible over
  // silhouette pixels) times inside the image (in_image_fraction), in [0, 1]. The usual occlusion
  // and truncation measure of detection benchmarks (KITTI, amodal COCO), of the projection, not
  // of the 3D surface; 0 when a corner of its extent is behind the camera.
  double visibleFraction() const;
};

struct RenderedFrame {
  RgbdFrame rgbd;
  cv::Mat instance_ids;  // CV_32SC1: id of the object seen at each pixel, -1 floor/walls/nothing
  std::vector<VisibleObject> objects;  // objects with at least one visible pixel, by id
  SE3 world_T_camera;
};

// The frame key (Renderer::render) of robot `robot`'s pose `pose` in a simulation: the frames the
// front-end perceives (perception/rendered_sensing.h) and the ideal front-end measures
// (render/visible_sensing.h) are the same frames by this key.
inline std::uint64_t SimulationFrameKey(int robot, std::size_t pose) {
  return static_cast<std::uint64_t>(robot) * 1000000u + pose;
}

class Renderer {
 public:
  // Builds the class models and the walls once. Throws InvalidInputError on a bad config or
  // an invalid world (ValidateWorld).
  Renderer(const World& world, const RenderConfig& config);

  // The frame seen from body pose world_T_body. frame_key selects the noise (with
  // config.seed); timestamp is copied into the frame.
  RenderedFrame render(const SE3& world_T_body, std::uint64_t frame_key = 0,
                       double timestamp = 0.0) const;

  const RenderConfig& config() const { return config_; }
  const World& world() const { return world_; }
  // The model used for a class label (nullptr when the world has no such class).
  const Mesh* model(const std::string& label) const;

 private:
  struct Item {
    const Mesh* mesh;
    SE3 world_T_local;
    int object_index;  // into world_.objects, -1 for walls
  };
  struct Raster;        // one frame's z-buffer (renderer.cc)
  struct ObjectPixels;  // what the shading found of each world object
  // The items' triangles into the raster (culled, clipped to the near plane, z-buffered).
  void rasterizeItems(const SE3& camera_T_world, Raster& raster) const;
  // Colour (before the sensor's noise), depth and instance ids of every pixel of the raster.
  ObjectPixels shade(const Raster& raster, const SE3& world_T_camera, cv::Mat& colour,
                     cv::Mat& depth, cv::Mat& instance_ids) const;
  // The ground truth of every world object with visible pixels, by id.
  std::vector<VisibleObject> objectsSeen(const ObjectPixels& seen, const SE3& camera_T_world) const;

  World world_;
  RenderConfig config_;
  std::vector<std::string> model_labels_;
  std::vector<Mesh> models_;
  Mesh walls_;
  std::vector<Item> items_;
};

}  // namespace moslam
