// The shared benchmark datasets as the tests find them (not part of the library): below
// MOSLAM_DATASETS_DIR, which CMake defines for the test targets (../shared/datasets by default).
#pragma once

#include <string>

namespace moslam::test {

// A distributed-mapper blocks_world folder (0.g2o .. N-1.g2o) of `robots` robots: 2, 4, 9, 16,
// 25, 36 or 49.
inline std::string BlocksWorldFolder(int robots) {
  return std::string(MOSLAM_DATASETS_DIR) +
         "/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/"
         "blocks_world/" +
         std::to_string(robots) + "robots";
}

}  // namespace moslam::test
