// Test-only: a benchmark file of the shared datasets with wrong loop closures added, as
// `moslam spoil <file> --fraction F --seed S` writes it, beside the clean file it came from.
// Needs moslam_io and moslam_robust, and the MOSLAM_DATASETS_DIR every test target defines.
#pragma once

#include <cstdint>
#include <string>

#include "moslam/io/g2o.h"
#include "moslam/robust/spoil.h"

namespace moslam::test {

struct SpoiledDataset {
  Dataset clean;
  SpoiledGraph spoiled;
};

// `name` below MOSLAM_DATASETS_DIR/pgo (e.g. "CSAIL.g2o"); a 2D file's wrong factors are planar.
inline SpoiledDataset SpoilPgoFile(const std::string& name, double fraction,
                                   std::uint32_t seed = 1) {
  SpoiledDataset out;
  out.clean = ReadG2oFile(std::string(MOSLAM_DATASETS_DIR) + "/pgo/" + name);
  SpoilOptions spoil;
  spoil.fraction = fraction;
  spoil.seed = seed;
  spoil.planar = out.clean.planar;
  out.spoiled = SpoilSeparators(out.clean.graph, spoil);
  return out;
}

}  // namespace moslam::test
