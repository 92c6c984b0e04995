// Object templates for registration: a coloured point cloud of one object class in the object
// frame, voxelled, with normals and PFHRGB features computed ONCE per class.
//
// Object frame (sim/world.h): origin at the centre of the object, x forward, z up; metres.
//
// Supplying your own template: a PCD file (pcl::io, ASCII or binary) of pcl::PointXYZRGBNormal
// points in the object frame: fields x y z rgb (or rgba) normal_x normal_y normal_z; normals unit
// and pointing OUT of the object (towards where a camera could see the surface from).
// LoadObjectTemplate voxels it with FeatureConfig::voxel_size and computes the features; a
// coloured, asymmetric or textured model registers far more reliably than a plain symmetric one.
// SaveObjectTemplate writes the voxelled cloud in that format (binary).
#pragma once

#include <memory>
#include <string>

#include "moslam/pose_estimation/features.h"
#include "moslam/render/point_set.h"

namespace moslam {

class TemplateFeatureIndex;  // pose_estimation/feature_index.h

struct ObjectTemplate {
  std::string label;
  FeatureConfig config;      // the parameters the features were computed with
  FeatureCloud::Ptr cloud;     // voxelled (voxel_size), object frame, outward unit normals
  FeatureCloud::Ptr keypoints; // keypoint_voxel centroids of cloud
  PfhrgbCloud::Ptr features;   // features->at(i) describes keypoints->at(i)
  // The k-d tree of `features`, built on first use and shared by copies (set by
  // MakeObjectTemplate, not by the template cache's decoder: ObjectPerception adds it to cached
  // templates; a registration builds its own if it is missing or indexes other features).
  std::shared_ptr<const TemplateFeatureIndex> feature_index;
  std::size_t size() const { return cloud ? cloud->size() : 0; }
};

// A sampled model (render/point_set.h) as a FeatureCloud (rgb from colours_bgr). Throws
// InvalidInputError on mismatched vector sizes.
FeatureCloud ModelCloud(const ColoredPointSet& points, const std::string& label = "model");

// From a sampled model (render/point_set.h). Throws InvalidInputError on an invalid config,
// mismatched vector sizes, non-finite points/normals, or fewer than 10 points after voxelling.
ObjectTemplate MakeObjectTemplate(const std::string& label, const ColoredPointSet& points,
                                  const FeatureConfig& config = {});
ObjectTemplate MakeObjectTemplate(const std::string& label, const FeatureCloud& cloud,
                                  const FeatureConfig& config = {});

// A template whose features were computed elsewhere, e.g. on rendered views of the model
// (perception/view_template.h): `cloud` validated and voxelled as by MakeObjectTemplate (GICP and
// the agreement score use it), `keypoints` (object frame) and `features` taken as they are,
// keypoints[i] <-> features[i]. Throws InvalidInputError on missing or mismatched keypoints and
// features, fewer than 10 keypoints, a non-finite keypoint, or as MakeObjectTemplate.
ObjectTemplate AssembleObjectTemplate(const std::string& label, const FeatureCloud& cloud,
                                      FeatureCloud::Ptr keypoints, PfhrgbCloud::Ptr features,
                                      const FeatureConfig& config);

// Writes tmpl.cloud as a binary PCD. Throws InvalidInputError naming the file if it cannot.
void SaveObjectTemplate(const ObjectTemplate& tmpl, const std::string& path);

// The points of a PCD of the format above, validated but not voxelled (the input of
// MakeObjectTemplate). Throws InvalidInputError as LoadObjectTemplate.
FeatureCloud ReadTemplateCloud(const std::string& path);

// Reads a PCD of the format above. Throws InvalidInputError naming the file and the problem
// (unreadable, missing field, no points, non-finite values).
ObjectTemplate LoadObjectTemplate(const std::string& path, const std::string& label,
                                  const FeatureConfig& config = {});

}  // namespace moslam
