#include "moslam/common/whole_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

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

// A file that opens but whose read(2) fails is said, not returned short: /proc/self/mem read from
// offset 0 fails with EIO (address 0 is never mapped), as a failing disk would.
TEST(WholeFile, AFailedReadIsAReadErrorNamingThePath) {
  const std::string path = "/proc/self/mem";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  std::string why;
  EXPECT_FALSE(ReadWholeFile(path, &why).has_value());
  EXPECT_EQ(why.rfind(path + ": read error", 0), 0u) << why;
  EXPECT_TRUE(test::ThrowsNaming([&] { ReadWholeFileOrThrow(path); }, path + ": read error"));
}

// A folder holding one file, `name`, with `text` in it.
std::filesystem::path FolderWith(const std::filesystem::path& dir, const std::string& name,
                                 const std::string& text) {
  std::filesystem::create_directories(dir);
  WriteWholeFile((dir / name).string(), text, "test");
  return dir;
}

std::vector<std::string> Entries(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// What cannot be read or written is said, naming the path, and a failed write leaves nothing
// behind: a folder read as a file; a file written where a file stands in the way of its folder,
// or where a folder stands.
TEST(WholeFile, ReadAndWriteFailuresNameThePathAndLeaveNothing) {
  const std::filesystem::path dir = test::ScratchDir("failures");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "a_folder");
  std::string why;
  EXPECT_FALSE(ReadWholeFile((dir / "a_folder").string(), &why).has_value());
  EXPECT_EQ(why, (dir / "a_folder").string() + ": is a folder, not a file");
  EXPECT_TRUE(test::ThrowsNaming([&] { ReadWholeFileOrThrow((dir / "a_folder").string()); },
                                 (dir / "a_folder").string()));

  WriteWholeFile((dir / "a_file").string(), "x", "test");
  EXPECT_TRUE(test::ThrowsNaming(
      [&] { WriteWholeFile((dir / "a_file" / "inside.bin").string(), "y", "writer"); },
      "writer: cannot create '" + (dir / "a_file").string() + "'"));
  EXPECT_TRUE(
      test::ThrowsNaming([&] { WriteWholeFile((dir / "a_folder").string(), "z", "writer"); },
                         "writer: cannot rename into '" + (dir / "a_folder").string() + "'"));
  EXPECT_EQ(Entries(dir), (std::vector<std::string>{"a_file", "a_folder"}));
  EXPECT_EQ(ReadWholeFileOrThrow((dir / "a_file").string()), "x");
  // The temporary cannot be written (a folder stands at its name): named, the file unchanged.
  const std::string tmp = (dir / "a_file").string() + ".tmp" + std::to_string(::getpid());
  std::filesystem::create_directory(tmp);
  EXPECT_TRUE(test::ThrowsNaming([&] { WriteWholeFile((dir / "a_file").string(), "w", "writer"); },
                                 "writer: cannot write '" + tmp + "'"));
  EXPECT_EQ(ReadWholeFileOrThrow((dir / "a_file").string()), "x");
  std::filesystem::remove(tmp);
  // Folders: created with their parents, or an error of the library's type naming the one in the
  // way (std::filesystem's own would escape as filesystem_error).
  CreateFolder(dir / "new" / "deeper", "test");
  EXPECT_TRUE(std::filesystem::is_directory(dir / "new" / "deeper"));
  EXPECT_TRUE(test::ThrowsNaming([&] { CreateFolder(dir / "a_file" / "sub", "maker"); },
                                 "maker: cannot create '" + (dir / "a_file" / "sub").string()));
  RemoveAll(dir / "new", "test");
  RemoveAll(dir / "never_there", "test");
  EXPECT_FALSE(std::filesystem::exists(dir / "new"));
  std::filesystem::remove_all(dir);
}

TEST(ReplaceDirectory, PutsTheNewFolderInPlaceOfTheOldAndLeavesNothingElse) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map", "old.g2o", "old");
  FolderWith(dir / "map.tmp", "new.g2o", "new");
  ReplaceDirectory(dir / "map.tmp", dir / "map", "test");
  EXPECT_EQ(Entries(dir), std::vector<std::string>{"map"});
  EXPECT_EQ(Entries(dir / "map"), std::vector<std::string>{"new.g2o"});
  EXPECT_EQ(ReadWholeFileOrThrow((dir / "map" / "new.g2o").string()), "new");
}

TEST(ReplaceDirectory, RenamesWhenThereIsNoOldFolder) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map.tmp", "new.g2o", "new");
  ReplaceDirectory(dir / "map.tmp", dir / "map", "test");
  EXPECT_EQ(Entries(dir), std::vector<std::string>{"map"});
  EXPECT_EQ(Entries(dir / "map"), std::vector<std::string>{"new.g2o"});
}

TEST(ReplaceDirectory, AMissingNewFolderIsAnErrorNamingBothAndTheOldIsKept) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map", "old.g2o", "old");
  EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>(
      [&] { ReplaceDirectory(dir / "map.tmp", dir / "map", "the map 'final'"); },
      "the map 'final': cannot put '" + (dir / "map.tmp").string() + "' in place of '" +
          (dir / "map").string() + "': the new folder does not exist"));
  EXPECT_EQ(Entries(dir / "map"), std::vector<std::string>{"old.g2o"});
}

TEST(ReplaceDirectory, ATargetWhoseParentIsMissingIsAnErrorNamingBothAndTheNewIsKept) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map.tmp", "new.g2o", "new");
  const std::filesystem::path target = dir / "no_such_parent" / "map";
  EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>(
      [&] { ReplaceDirectory(dir / "map.tmp", target, "test"); },
      "test: cannot put '" + (dir / "map.tmp").string() + "' in place of '" + target.string() +
          "': "));
  EXPECT_EQ(Entries(dir / "map.tmp"), std::vector<std::string>{"new.g2o"});
  EXPECT_FALSE(std::filesystem::exists(target));
}

TEST(ReplaceDirectory, TheRenamesOfFilesystemsWithoutExchangeDoTheSame) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map", "old.g2o", "old");
  FolderWith(dir / "map.old", "older.g2o", "a crash's leftover");
  FolderWith(dir / "map.tmp", "new.g2o", "new");
  whole_file_detail::ReplaceDirectoryByRenames(dir / "map.tmp", dir / "map", "test");
  EXPECT_EQ(Entries(dir), std::vector<std::string>{"map"});
  EXPECT_EQ(Entries(dir / "map"), std::vector<std::string>{"new.g2o"});
}

TEST(ReplaceDirectory, TheRenamesPutTheOldFolderBackWhenTheNewCannotBeMoved) {
  const std::filesystem::path dir = test::ScratchDir();
  FolderWith(dir / "map", "old.g2o", "old");
  EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>(
      [&] { whole_file_detail::ReplaceDirectoryByRenames(dir / "map.tmp", dir / "map", "test"); },
      "test: cannot put '" + (dir / "map.tmp").string() + "'"));
  EXPECT_EQ(Entries(dir), std::vector<std::string>{"map"});
  EXPECT_EQ(Entries(dir / "map"), std::vector<std::string>{"old.g2o"});
}

}  // namespace
}  // namespace moslam
