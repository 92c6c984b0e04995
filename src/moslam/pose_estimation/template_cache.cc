#include "moslam/pose_estimation/template_cache.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <type_traits>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

// The last byte is the format's version: '2' added FeatureConfig::feature_surface_voxel.
constexpr char kMagic[8] = {'M', 'O', 'S', 'L', 'T', 'P', 'L', '2'};
constexpr std::size_t kHistogram = 250;  // pcl::PFHRGBSignature250
constexpr std::size_t kPointBytes = 6 * sizeof(float) + sizeof(std::uint32_t);

class Writer {
 public:
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void bytes(const void* p, std::size_t n) { out_.append(static_cast<const char*>(p), n); }
  void point(const FeaturePoint& p) {
    for (float v : {p.x, p.y, p.z, p.normal_x, p.normal_y, p.normal_z}) put(v);
    put(static_cast<std::uint32_t>(p.rgba));
  }
  std::string& str() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  template <typename T>
  T get(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, in_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }
  std::string_view take(std::size_t n, const char* what) {
    need(n, what);
    const std::string_view s = in_.substr(at_, n);
    at_ += n;
    return s;
  }
  // A count of items of `item_bytes` each that must fit in the bytes left.
  std::size_t count(std::size_t item_bytes, const char* what) {
    const auto n = get<std::uint32_t>(what);
    if (static_cast<std::uint64_t>(n) * item_bytes > in_.size() - at_) {
      throw InvalidInputError(std::string("template cache: ") + what + " count " +
                              std::to_string(n) + " exceeds the file");
    }
    return n;
  }
  // `unit_normal`: the normal must be a unit vector (template points); keypoints are voxel
  // centroids whose normals may cancel, so only finiteness is required of them.
  FeaturePoint point(const char* what, bool unit_normal) {
    FeaturePoint p;
    float v[6];
    for (float& x : v) {
      x = get<float>(what);
      if (!std::isfinite(x)) {
        throw InvalidInputError(std::string("template cache: non-finite value in ") + what);
      }
    }
    p.x = v[0];
    p.y = v[1];
    p.z = v[2];
    p.normal_x = v[3];
    p.normal_y = v[4];
    p.normal_z = v[5];
    p.curvature = 0.0f;
    p.rgba = get<std::uint32_t>(what);
    const float n = p.getNormalVector3fMap().norm();
    if (unit_normal && std::abs(n - 1.0f) > 1e-2f) {
      throw InvalidInputError(std::string("template cache: a normal in ") + what +
                              " is not a unit vector");
    }
    return p;
  }
  std::size_t at() const { return at_; }
  std::size_t left() const { return in_.size() - at_; }

 private:
  void need(std::size_t n, const char* what) const {
    if (n > in_.size() - at_) {
      throw InvalidInputError(std::string("template cache: truncated in ") + what);
    }
  }
  std::string_view in_;
  std::size_t at_ = 0;
};

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
  Writer w;
  for (const FeaturePoint& p : cloud.points) w.point(p);
  return Fnv1a64(w.str().data(), w.str().size());
}

std::uint64_t TemplateFingerprint(const std::string& label, std::uint64_t source_digest,
                                  const FeatureConfig& config) {
  Writer w;
  w.bytes(kMagic, sizeof(kMagic));
  w.put(source_digest);
  w.put(static_cast<std::uint32_t>(label.size()));
  w.bytes(label.data(), label.size());
  w.put(config.voxel_size);
  w.put(config.normal_radius);
  w.put(config.feature_radius);
  w.put(config.feature_surface_voxel);
  w.put(config.keypoint_voxel);
  return Fnv1a64(w.str().data(), w.str().size());
}

std::string EncodeTemplate(const ObjectTemplate& tmpl, std::uint64_t fingerprint) {
  if (!tmpl.cloud || !tmpl.keypoints || !tmpl.features ||
      tmpl.keypoints->size() != tmpl.features->size()) {
    throw InvalidInputError("EncodeTemplate: template '" + tmpl.label + "' is incomplete");
  }
  Writer w;
  w.bytes(kMagic, sizeof(kMagic));
  w.put(fingerprint);
  w.put(static_cast<std::uint32_t>(tmpl.label.size()));
  w.bytes(tmpl.label.data(), tmpl.label.size());
  for (double v : {tmpl.config.voxel_size, tmpl.config.normal_radius, tmpl.config.feature_radius,
                   tmpl.config.feature_surface_voxel, tmpl.config.keypoint_voxel}) {
    w.put(v);
  }
  w.put(static_cast<std::uint32_t>(tmpl.cloud->size()));
  for (const FeaturePoint& p : tmpl.cloud->points) w.point(p);
  w.put(static_cast<std::uint32_t>(tmpl.keypoints->size()));
  for (const FeaturePoint& p : tmpl.keypoints->points) w.point(p);
  for (const auto& f : tmpl.features->points) w.bytes(f.histogram, sizeof(f.histogram));
  const std::uint64_t checksum = Fnv1a64(w.str().data(), w.str().size());
  w.put(checksum);
  return std::move(w.str());
}

ObjectTemplate DecodeTemplate(std::string_view bytes, const std::string& label,
                              std::uint64_t fingerprint, const FeatureConfig& config) {
  if (bytes.size() < sizeof(kMagic) + 2 * sizeof(std::uint64_t)) {
    throw InvalidInputError("template cache: too short to be a template");
  }
  const std::size_t body = bytes.size() - sizeof(std::uint64_t);
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + body, sizeof(stored));
  if (Fnv1a64(bytes.data(), body) != stored) {
    throw InvalidInputError("template cache: checksum mismatch (damaged or partly written)");
  }
  Reader r(bytes.substr(0, body));
  const std::string_view magic = r.take(sizeof(kMagic), "magic");
  if (magic.substr(0, sizeof(kMagic) - 1) == std::string_view(kMagic, sizeof(kMagic) - 1) &&
      magic != std::string_view(kMagic, sizeof(kMagic))) {
    throw InvalidInputError("template cache: written in another format version (by another "
                            "version of moslam)");
  }
  if (magic != std::string_view(kMagic, sizeof(kMagic))) {
    throw InvalidInputError("template cache: not a moslam template (bad magic)");
  }
  if (r.get<std::uint64_t>("fingerprint") != fingerprint) {
    throw InvalidInputError("template cache: built from another model or configuration");
  }
  const std::size_t label_size = r.count(1, "label");
  if (r.take(label_size, "label") != label) {
    throw InvalidInputError("template cache: holds another label than '" + label + "'");
  }
  FeatureConfig stored_config;
  stored_config.voxel_size = r.get<double>("config");
  stored_config.normal_radius = r.get<double>("config");
  stored_config.feature_radius = r.get<double>("config");
  stored_config.feature_surface_voxel = r.get<double>("config");
  stored_config.keypoint_voxel = r.get<double>("config");
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
  for (std::size_t i = 0; i < points; ++i) t.cloud->push_back(r.point("points", true));
  const std::size_t keypoints = r.count(kPointBytes + kHistogram * sizeof(float), "keypoints");
  t.keypoints->reserve(keypoints);
  for (std::size_t i = 0; i < keypoints; ++i) t.keypoints->push_back(r.point("keypoints", false));
  t.features->reserve(keypoints);
  for (std::size_t i = 0; i < keypoints; ++i) {
    pcl::PFHRGBSignature250 f;
    const std::string_view block = r.take(sizeof(f.histogram), "features");
    std::memcpy(f.histogram, block.data(), sizeof(f.histogram));
    for (float h : f.histogram) {
      if (!std::isfinite(h)) throw InvalidInputError("template cache: non-finite feature");
    }
    t.features->push_back(f);
  }
  if (r.left() != 0) throw InvalidInputError("template cache: trailing bytes");
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
  const std::string file = path(label, fingerprint);
  const std::optional<std::string> bytes = ReadWholeFile(file, why_not);
  if (!bytes) return std::nullopt;
  try {
    return DecodeTemplate(*bytes, label, fingerprint, config);
  } catch (const InvalidInputError& e) {
    if (why_not) *why_not = file + ": " + e.what();
    return std::nullopt;
  }
}

void TemplateCache::store(const ObjectTemplate& tmpl, std::uint64_t fingerprint) const {
  WriteWholeFile(path(tmpl.label, fingerprint), EncodeTemplate(tmpl, fingerprint),
                 "TemplateCache");
}

}  // namespace moslam
