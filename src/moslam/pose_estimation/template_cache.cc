#include "moslam/pose_estimation/template_cache.h"

#include <cmath>
#include <filesystem>
#include <sstream>

#include "moslam/common/byte_io.h"
#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

// The last byte is the format's version: '2' added FeatureConfig::feature_surface_voxel.
constexpr char kMagic[8] = {'M', 'O', 'S', 'L', 'T', 'P', 'L', '2'};
constexpr std::size_t kHistogram = 250;  // pcl::PFHRGBSignature250
constexpr std::size_t kPointBytes = 6 * sizeof(float) + sizeof(std::uint32_t);

void PutPoint(ByteWriter& w, const FeaturePoint& p) {
  for (float v : {p.x, p.y, p.z, p.normal_x, p.normal_y, p.normal_z}) w.f32(v);
  w.u32(static_cast<std::uint32_t>(p.rgba));
}

// `unit_normal`: the normal must be a unit vector (template points); keypoints are voxel
// centroids whose normals may cancel, so only finiteness is required of them.
FeaturePoint ReadPoint(ByteReader& r, const char* what, bool unit_normal) {
  float v[6];
  for (float& x : v) {
    x = r.f32(what);
    if (!std::isfinite(x)) r.fail(std::string("non-finite value in ") + what);
  }
  FeaturePoint p;
  p.x = v[0];
  p.y = v[1];
  p.z = v[2];
  p.normal_x = v[3];
  p.normal_y = v[4];
  p.normal_z = v[5];
  p.curvature = 0.0f;
  p.rgba = r.u32(what);
  const float n = p.getNormalVector3fMap().norm();
  if (unit_normal && std::abs(n - 1.0f) > 1e-2f) {
    r.fail(std::string("a normal in ") + what + " is not a unit vector");
  }
  return p;
}

std::string SafeLabel(const std::string& label) {
  std::string s;
  for (char c : label) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '-' || c == '_';
    s.push_back(ok ? c : '_');
  }
  return s.empty() ? std::string("_") : s;
}

}  // namespace

std::uint64_t CloudDigest(const FeatureCloud& cloud) {
  ByteWriter w;
  for (const FeaturePoint& p : cloud.points) PutPoint(w, p);
  return Fnv1a64(w.data().data(), w.size());
}

std::uint64_t TemplateFingerprint(const std::string& label, std::uint64_t source_digest,
                                  const FeatureConfig& config) {
  ByteWriter w;
  w.bytes(std::string_view(kMagic, sizeof(kMagic)));
  w.u64(source_digest);
  w.u32(static_cast<std::uint32_t>(label.size()));
  w.bytes(label);
  for (double v : {config.voxel_size, config.normal_radius, config.feature_radius,
                   config.feature_surface_voxel, config.keypoint_voxel}) {
    w.f64(v);
  }
  return Fnv1a64(w.data().data(), w.size());
}

std::string EncodeTemplate(const ObjectTemplate& tmpl, std::uint64_t fingerprint) {
  if (!tmpl.cloud || !tmpl.keypoints || !tmpl.features ||
      tmpl.keypoints->size() != tmpl.features->size()) {
    throw InvalidInputError("EncodeTemplate: template '" + tmpl.label + "' is incomplete");
  }
  ByteWriter w;
  w.bytes(std::string_view(kMagic, sizeof(kMagic)));
  w.u64(fingerprint);
  w.u32(static_cast<std::uint32_t>(tmpl.label.size()));
  w.bytes(tmpl.label);
  for (double v : {tmpl.config.voxel_size, tmpl.config.normal_radius, tmpl.config.feature_radius,
                   tmpl.config.feature_surface_voxel, tmpl.config.keypoint_voxel}) {
    w.f64(v);
  }
  w.u32(static_cast<std::uint32_t>(tmpl.cloud->size()));
  for (const FeaturePoint& p : tmpl.cloud->points) PutPoint(w, p);
  w.u32(static_cast<std::uint32_t>(tmpl.keypoints->size()));
  for (const FeaturePoint& p : tmpl.keypoints->points) PutPoint(w, p);
  for (const auto& f : tmpl.features->points) {
    for (float h : f.histogram) w.f32(h);
  }
  w.seal();
  return w.take();
}

ObjectTemplate DecodeTemplate(std::string_view bytes, const std::string& label,
                              std::uint64_t fingerprint, const FeatureConfig& config) {
  ByteReader r(SealedBody(bytes, sizeof(kMagic) + sizeof(std::uint64_t), "template cache"),
               "template cache");
  const std::string_view magic = r.take(sizeof(kMagic), "magic");
  if (magic.substr(0, sizeof(kMagic) - 1) == std::string_view(kMagic, sizeof(kMagic) - 1) &&
      magic != std::string_view(kMagic, sizeof(kMagic))) {
    throw InvalidInputError("template cache: written in another format version (by another "
                            "version of moslam)");
  }
  if (magic != std::string_view(kMagic, sizeof(kMagic))) {
    throw InvalidInputError("template cache: not a moslam template (bad magic)");
  }
  if (r.u64("fingerprint") != fingerprint) {
    throw InvalidInputError("template cache: built from another model or configuration");
  }
  const std::size_t label_size = r.count(1, "label");
  if (r.take(label_size, "label") != label) {
    throw InvalidInputError("template cache: holds another label than '" + label + "'");
  }
  FeatureConfig stored_config;
  stored_config.voxel_size = r.f64("config");
  stored_config.normal_radius = r.f64("config");
  stored_config.feature_radius = r.f64("config");
  stored_config.feature_surface_voxel = r.f64("config");
  stored_config.keypoint_voxel = r.f64("config");
  if (!(stored_config == config)) {
    throw InvalidInputError("template cache: built with another FeatureConfig");
  }
  ObjectTemplate t;
  t.label = label;
  t.config = config;
  t.cloud = std::make_shared<FeatureCloud>();
  t.keypoints = std::make_shared<FeatureCloud>();
  t.features = std::make_shared<PfhrgbCloud>();
  const std::size_t points = r.count(kPointBytes, "points");
  t.cloud->reserve(points);
  for (std::size_t i = 0; i < points; ++i) t.cloud->push_back(ReadPoint(r, "points", true));
  const std::size_t keypoints = r.count(kPointBytes + kHistogram * sizeof(float), "keypoints");
  t.keypoints->reserve(keypoints);
  for (std::size_t i = 0; i < keypoints; ++i) t.keypoints->push_back(ReadPoint(r, "keypoints", false));
  t.features->reserve(keypoints);
  for (std::size_t i = 0; i < keypoints; ++i) {
    pcl::PFHRGBSignature250 f;
    for (float& h : f.histogram) {
      h = r.f32("features");
      if (!std::isfinite(h)) r.fail("non-finite feature");
    }
    t.features->push_back(f);
  }
  r.finish();
  if (t.cloud->size() < 10 || t.keypoints->size() < 10) {
    throw InvalidInputError("template cache: fewer than 10 points or keypoints");
  }
  return t;
}

TemplateCache::TemplateCache(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) throw InvalidInputError("TemplateCache: the directory must not be empty");
}

std::string TemplateCache::path(const std::string& label, std::uint64_t fingerprint) const {
  std::ostringstream name;
  name << SafeLabel(label) << '-' << std::hex << fingerprint << ".tpl";
  return (std::filesystem::path(dir_) / name.str()).string();
}

std::optional<ObjectTemplate> TemplateCache::load(const std::string& label,
                                                  std::uint64_t fingerprint,
                                                  const FeatureConfig& config,
                                                  std::string* why_not) const {
  return ReadDecodedFile(path(label, fingerprint), why_not, [&](const std::string& bytes) {
    return DecodeTemplate(bytes, label, fingerprint, config);
  });
}

void TemplateCache::store(const ObjectTemplate& tmpl, std::uint64_t fingerprint) const {
  WriteWholeFile(path(tmpl.label, fingerprint), EncodeTemplate(tmpl, fingerprint),
                 "TemplateCache");
}

}  // namespace moslam
