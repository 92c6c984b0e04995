#include "moslam/pose_estimation/template_cache.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"
#include "moslam/pose_estimation/test_shapes.h"

namespace moslam {
namespace {

struct Built {
  FeatureCloud cloud;
  ObjectTemplate tmpl;
  std::uint64_t key = 0;
};

const Built& TestBuilt() {
  static const Built b = [] {
    Built out;
    out.cloud = ModelCloud(test::MakeTestObject(0.01), "test_chair");
    out.tmpl = MakeObjectTemplate("test_chair", out.cloud);
    out.key = TemplateFingerprint("test_chair", CloudDigest(out.cloud), FeatureConfig{});
    return out;
  }();
  return b;
}

void ExpectSameTemplate(const ObjectTemplate& a, const ObjectTemplate& b) {
  ASSERT_EQ(a.cloud->size(), b.cloud->size());
  ASSERT_EQ(a.keypoints->size(), b.keypoints->size());
  ASSERT_EQ(a.features->size(), b.features->size());
  for (std::size_t i = 0; i < a.cloud->size(); ++i) {
    EXPECT_EQ((*a.cloud)[i].getVector3fMap(), (*b.cloud)[i].getVector3fMap());
    EXPECT_EQ((*a.cloud)[i].getNormalVector3fMap(), (*b.cloud)[i].getNormalVector3fMap());
    EXPECT_EQ((*a.cloud)[i].rgba, (*b.cloud)[i].rgba);
  }
  for (std::size_t i = 0; i < a.features->size(); ++i) {
    for (int h = 0; h < 250; ++h) {
      ASSERT_EQ((*a.features)[i].histogram[h], (*b.features)[i].histogram[h]);
    }
  }
  EXPECT_EQ(a.label, b.label);
  EXPECT_TRUE(a.config == b.config);
}

TEST(TemplateCache, RoundTripIsExact) {
  const Built& b = TestBuilt();
  const std::string bytes = EncodeTemplate(b.tmpl, b.key);
  ExpectSameTemplate(DecodeTemplate(bytes, "test_chair", b.key, FeatureConfig{}), b.tmpl);
}

TEST(TemplateCache, FingerprintFollowsTheModelAndTheConfig) {
  const Built& b = TestBuilt();
  FeatureCloud moved = b.cloud;
  moved[3].x += 1e-4f;
  const std::uint64_t digest = CloudDigest(b.cloud);
  EXPECT_NE(TemplateFingerprint("test_chair", CloudDigest(moved), FeatureConfig{}), b.key);
  FeatureConfig other;
  other.feature_radius += 0.01;
  EXPECT_NE(TemplateFingerprint("test_chair", digest, other), b.key);
  other = FeatureConfig{};
  other.feature_surface_voxel = 0.0;
  EXPECT_NE(TemplateFingerprint("test_chair", digest, other), b.key);
  EXPECT_NE(TemplateFingerprint("sofa", digest, FeatureConfig{}), b.key);
  EXPECT_EQ(TemplateFingerprint("test_chair", digest, FeatureConfig{}), b.key);
}

TEST(TemplateCache, DamagedOrForeignBytesAreRejectedWithAReason) {
  const Built& b = TestBuilt();
  const std::string good = EncodeTemplate(b.tmpl, b.key);
  auto expect_error = [&](const std::string& bytes, const std::string& label, std::uint64_t key,
                          const FeatureConfig& config, const std::string& why) {
    EXPECT_TRUE(test::ThrowsNaming([&] { DecodeTemplate(bytes, label, key, config); }, why));
  };
  expect_error(good.substr(0, good.size() / 2), "test_chair", b.key, {}, "checksum");
  std::string flipped = good;
  flipped[good.size() / 3] ^= 0x10;
  expect_error(flipped, "test_chair", b.key, {}, "checksum");
  expect_error("", "test_chair", b.key, {}, "too short");
  expect_error(good, "test_chair", b.key + 1, {}, "another model");
  FeatureConfig other;
  other.keypoint_voxel = 0.05;
  expect_error(good, "test_chair", b.key, other, "another FeatureConfig");
  // A label that does not match what the caller asked for.
  ObjectTemplate renamed = b.tmpl;
  renamed.label = "sofa";
  expect_error(EncodeTemplate(renamed, b.key), "test_chair", b.key, {}, "another label");
  // A file of an earlier format version (its checksum recomputed: only the version differs).
  std::string older = good.substr(0, good.size() - sizeof(std::uint64_t));
  older[7] = '1';
  const std::uint64_t sum = Fnv1a64(older.data(), older.size());
  older.append(reinterpret_cast<const char*>(&sum), sizeof(sum));
  expect_error(older, "test_chair", b.key, {}, "another format version");
}

TEST(TemplateCache, StoresLoadsAndReportsUnusableEntries) {
  const Built& b = TestBuilt();
  const std::filesystem::path dir = test::ScratchDir();
  const TemplateCache cache((dir / "nested").string());
  std::string why;
  why = "stale";
  EXPECT_FALSE(cache.load("test_chair", b.key, {}, &why));
  EXPECT_TRUE(why.empty()) << why;  // no entry is not a problem to report
  cache.store(b.tmpl, b.key);
  const auto loaded = cache.load("test_chair", b.key, {}, &why);
  ASSERT_TRUE(loaded) << why;
  ExpectSameTemplate(*loaded, b.tmpl);
  // A damaged file is a miss with its reason, never an exception or a wrong template.
  {
    std::ofstream out(cache.path("test_chair", b.key), std::ios::binary | std::ios::trunc);
    out << "MOSLTPL2 but nothing else";
  }
  EXPECT_FALSE(cache.load("test_chair", b.key, {}, &why));
  EXPECT_NE(why.find("checksum"), std::string::npos) << why;
  // Labels with path characters stay inside the folder.
  EXPECT_EQ(std::filesystem::path(cache.path("../evil/x", 1)).parent_path(),
            std::filesystem::path(cache.dir()));
  std::filesystem::remove_all(dir);
  EXPECT_THROW(TemplateCache(""), InvalidInputError);
}

}  // namespace
}  // namespace moslam
