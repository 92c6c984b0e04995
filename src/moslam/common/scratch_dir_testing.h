// Test-only: a fresh folder for the running test under the build tree,
// <build>/test_scratch/<Suite>.<Test>[/<name>], emptied when asked for. Under the build tree, not
// /tmp: two checkouts' suites running at once (a clone's CI beside a build) never share one, and a
// rerun replaces the last run's instead of leaving another beside it. Needs GoogleTest and the
// MOSLAM_BINARY_DIR every test target defines (cmake/MoslamTargets.cmake).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace moslam::test {

inline std::filesystem::path ScratchDir(const std::string& name = {}) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::filesystem::path dir = std::filesystem::path(MOSLAM_BINARY_DIR) / "test_scratch" /
                              (std::string(info->test_suite_name()) + "." + info->name());
  if (!name.empty()) dir /= name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace moslam::test
