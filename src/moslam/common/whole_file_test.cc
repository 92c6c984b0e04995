#include "moslam/common/whole_file.h"

#include <gtest/gtest.h>

#include <string>

#include "moslam/common/scratch_dir_testing.h"

namespace moslam {
namespace {

TEST(WholeFile, ReadsWhatWasWrittenAndNamesAMissingFile) {
  const std::string path = (test::ScratchDir() / "bytes.bin").string();
  const std::string bytes("a\0b\nc", 5);
  WriteWholeFile(path, bytes, "test");
  EXPECT_EQ(ReadWholeFileOrThrow(path), bytes);
  const std::string missing = (test::ScratchDir("empty") / "missing.txt").string();
  try {
    ReadWholeFileOrThrow(missing);
    FAIL() << "no throw";
  } catch (const InvalidInputError& e) {
    EXPECT_EQ(std::string(e.what()), missing + ": no such file");
  }
}

}  // namespace
}  // namespace moslam
