#include "moslam/pose_estimation/object_template.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <exception>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/pose_estimation/feature_index.h"

namespace moslam {
namespace {

constexpr std::size_t kMinTemplatePoints = 10;

bool FinitePoint(const FeaturePoint& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
         std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z);
}

// The validated, voxelled template cloud (MakeObjectTemplate, AssembleObjectTemplate).
FeatureCloud::Ptr TemplateCloud(const std::string& label, const FeatureCloud& cloud,
                                const FeatureConfig& config) {
  config.validate();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const FeaturePoint& p = cloud[i];
    if (!FinitePoint(p)) {
      throw InvalidInputError("MakeObjectTemplate(" + label + "): point " + std::to_string(i) +
                              " has a non-finite coordinate or normal");
    }
    const double n = Eigen::Vector3d(p.normal_x, p.normal_y, p.normal_z).norm();
    if (std::abs(n - 1.0) > 1e-2) {
      throw InvalidInputError("MakeObjectTemplate(" + label + "): normal " + std::to_string(i) +
                              " is not a unit vector (norm " + std::to_string(n) + ")");
    }
  }
  FeatureCloud::Ptr voxelled = pose_detail::VoxelDownsample(cloud, config.voxel_size, true);
  if (voxelled->size() < kMinTemplatePoints) {
    throw InvalidInputError("MakeObjectTemplate(" + label + "): only " +
                            std::to_string(voxelled->size()) +
                            " points after voxelling; need at least 10");
  }
  return voxelled;
}

}  // namespace

ObjectTemplate MakeObjectTemplate(const std::string& label, const FeatureCloud& cloud,
                                  const FeatureConfig& config) {
  ObjectTemplate t;
  t.label = label;
  t.config = config;
  t.cloud = TemplateCloud(label, cloud, config);
  t.keypoints = pose_detail::Keypoints(*t.cloud, config.keypoint_voxel);
  t.features = pose_detail::ComputePfhrgb(t.cloud, t.keypoints, config);
  if (t.keypoints->size() < kMinTemplatePoints) {
    throw InvalidInputError("MakeObjectTemplate(" + label +
                            "): fewer than 10 keypoints have finite PFHRGB features");
  }
  t.feature_index = std::make_shared<const TemplateFeatureIndex>(t.features);
  return t;
}

ObjectTemplate AssembleObjectTemplate(const std::string& label, const FeatureCloud& cloud,
                                      FeatureCloud::Ptr keypoints, PfhrgbCloud::Ptr features,
                                      const FeatureConfig& config) {
  if (!keypoints || !features || keypoints->size() != features->size()) {
    throw InvalidInputError("AssembleObjectTemplate(" + label +
                            "): keypoints and features missing or of different sizes");
  }
  if (keypoints->size() < kMinTemplatePoints) {
    throw InvalidInputError("AssembleObjectTemplate(" + label + "): " +
                            std::to_string(keypoints->size()) +
                            " keypoints with features; need at least 10");
  }
  for (std::size_t i = 0; i < keypoints->size(); ++i) {
    if (!FinitePoint(keypoints->points[i])) {
      throw InvalidInputError("AssembleObjectTemplate(" + label + "): keypoint " +
                              std::to_string(i) + " has a non-finite coordinate or normal");
    }
  }
  ObjectTemplate t;
  t.label = label;
  t.config = config;
  t.cloud = TemplateCloud(label, cloud, config);
  t.keypoints = std::move(keypoints);
  t.features = std::move(features);
  t.feature_index = std::make_shared<const TemplateFeatureIndex>(t.features);
  return t;
}

FeatureCloud ModelCloud(const ColoredPointSet& points, const std::string& label) {
  if (points.normals.size() != points.points.size() ||
      points.colours_bgr.size() != points.points.size()) {
    throw InvalidInputError("MakeObjectTemplate(" + label +
                            "): points, normals and colours_bgr must have the same size");
  }
  FeatureCloud cloud;
  cloud.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    FeaturePoint p;
    p.x = static_cast<float>(points.points[i].x());
    p.y = static_cast<float>(points.points[i].y());
    p.z = static_cast<float>(points.points[i].z());
    p.normal_x = static_cast<float>(points.normals[i].x());
    p.normal_y = static_cast<float>(points.normals[i].y());
    p.normal_z = static_cast<float>(points.normals[i].z());
    p.b = points.colours_bgr[i][0];
    p.g = points.colours_bgr[i][1];
    p.r = points.colours_bgr[i][2];
    p.a = 255;
    p.curvature = 0.0f;
    cloud.push_back(p);
  }
  return cloud;
}

ObjectTemplate MakeObjectTemplate(const std::string& label, const ColoredPointSet& points,
                                  const FeatureConfig& config) {
  return MakeObjectTemplate(label, ModelCloud(points, label), config);
}

void SaveObjectTemplate(const ObjectTemplate& tmpl, const std::string& path) {
  if (!tmpl.cloud || tmpl.cloud->empty()) {
    throw InvalidInputError("SaveObjectTemplate(" + path + "): the template has no points");
  }
  int rc = -1;
  try {
    rc = pcl::io::savePCDFileBinary(path, *tmpl.cloud);
  } catch (const std::exception& e) {
    throw InvalidInputError("SaveObjectTemplate(" + path + "): " + e.what());
  }
  if (rc != 0) throw InvalidInputError("SaveObjectTemplate(" + path + "): cannot write the file");
}

FeatureCloud ReadTemplateCloud(const std::string& path) {
  pcl::PCLPointCloud2 blob;
  int rc = -1;
  try {
    pcl::PCDReader reader;
    rc = reader.read(path, blob);
  } catch (const std::exception& e) {
    throw InvalidInputError(path + ": not a readable PCD file: " + e.what());
  }
  if (rc < 0) throw InvalidInputError(path + ": not a readable PCD file (missing or malformed)");
  for (const char* field : {"x", "y", "z", "normal_x", "normal_y", "normal_z"}) {
    if (pcl::getFieldIndex(blob, field) < 0) {
      throw InvalidInputError(path + ": PCD header lacks the field '" + field +
                              "' (need x y z rgb normal_x normal_y normal_z)");
    }
  }
  if (pcl::getFieldIndex(blob, "rgb") < 0 && pcl::getFieldIndex(blob, "rgba") < 0) {
    throw InvalidInputError(path + ": PCD header lacks the field 'rgb' (or 'rgba')");
  }
  // Checked before the conversion, which indexes the first point of the cloud it fills (undefined
  // behaviour for none, found by scripts/sanitize.sh) and reads width x height points of data
  // (PCL's reader already refuses ASCII and binary files shorter than their header says: test
  // ObjectTemplate.RefusesPcdFilesNamingWhatIsWrong; the second check is for what it lets by).
  const std::size_t points = static_cast<std::size_t>(blob.width) * blob.height;
  if (points == 0) throw InvalidInputError(path + ": the PCD file holds no points");
  if (blob.data.size() / points < blob.point_step) {
    throw InvalidInputError(path + ": the PCD file holds less data than its " +
                            std::to_string(points) + " points need");
  }
  FeatureCloud cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!FinitePoint(cloud[i])) {
      throw InvalidInputError(path + ": point " + std::to_string(i) +
                              " has a non-finite coordinate or normal");
    }
  }
  return cloud;
}

ObjectTemplate LoadObjectTemplate(const std::string& path, const std::string& label,
                                  const FeatureConfig& config) {
  const FeatureCloud cloud = ReadTemplateCloud(path);
  try {
    return MakeObjectTemplate(label, cloud, config);
  } catch (const InvalidInputError& e) {
    throw InvalidInputError(path + ": " + e.what());
  }
}

}  // namespace moslam
