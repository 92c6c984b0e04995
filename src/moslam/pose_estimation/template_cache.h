// Built object templates on disk, so that a robot computes a class's PFHRGB features once, not at
// every start (0.3-2.5 s per class on this machine kind).
//
// A cache entry is keyed by a FINGERPRINT of everything the template is built from: a digest of
// its source (the input point cloud, CloudDigest, or whatever the caller builds that cloud from
// deterministically, e.g. a model mesh and its sampling parameters: sampling a model with
// visibility costs as much as the features), the label and the FeatureConfig (FNV-1a 64 over
// their bytes, TemplateFingerprint). A different model, sampling or feature parameter gives
// another fingerprint and therefore another file: a stale entry is never used.
//
// File format (little-endian; one file <dir>/<label>-<fingerprint hex>.tpl):
//   magic "MOSLTPL2" | u64 fingerprint | u32 label length | label bytes
//   | 5 x f64 FeatureConfig (voxel_size, normal_radius, feature_radius, feature_surface_voxel,
//     keypoint_voxel)
//   | u32 cloud points     | points: 6 x f32 (x y z nx ny nz) + u32 rgba each
//   | u32 keypoints        | keypoints: as points
//   | features: keypoints x 250 x f32 (PFHRGB)
//   | u64 FNV-1a 64 of every byte before it.
// Decoding validates every field (sizes against the bytes left, finite values, unit normals of
// the points,
// the checksum, the label, fingerprint and FeatureConfig the caller expects) and throws
// InvalidInputError naming the first problem; TemplateCache::load turns that into a miss with the
// reason, and the caller rebuilds the template (a damaged file loses nothing).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "moslam/common/fnv.h"
#include "moslam/pose_estimation/object_template.h"

namespace moslam {

// Digest of a cloud's points (x y z, normal, rgba, in order).
std::uint64_t CloudDigest(const FeatureCloud& cloud);

// The cache key: the source digest, the label and the config.
std::uint64_t TemplateFingerprint(const std::string& label, std::uint64_t source_digest,
                                  const FeatureConfig& config);

// The bytes of the format above.
std::string EncodeTemplate(const ObjectTemplate& tmpl, std::uint64_t fingerprint);

// Parses and validates `bytes`; throws InvalidInputError on any mismatch or damage.
ObjectTemplate DecodeTemplate(std::string_view bytes, const std::string& label,
                              std::uint64_t fingerprint, const FeatureConfig& config);

class TemplateCache {
 public:
  // `dir` is created on the first store(). Throws InvalidInputError if dir is empty.
  explicit TemplateCache(std::string dir);

  // The cached template, or nullopt: no entry (`why_not` left empty), or an unusable one
  // (`why_not` says why: damaged, stale, unreadable).
  std::optional<ObjectTemplate> load(const std::string& label, std::uint64_t fingerprint,
                                     const FeatureConfig& config,
                                     std::string* why_not = nullptr) const;
  // Writes the entry (a temporary file renamed into place, so readers never see half a file).
  // Throws InvalidInputError naming the path when it cannot.
  void store(const ObjectTemplate& tmpl, std::uint64_t fingerprint) const;

  std::string path(const std::string& label, std::uint64_t fingerprint) const;
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

}  // namespace moslam
