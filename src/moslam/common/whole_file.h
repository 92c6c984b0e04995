// Whole files: read at once (the caches on disk, the text files a user hands the library), and
// the caches (the template cache, the perception cache) written so that a reader never sees half
// of one (the bytes go to a temporary file beside
// the target, renamed into place: atomic on one filesystem); folders written whole (a robot's
// map) put in place of their last version, in one step where the filesystem can (ReplaceDirectory).
#pragma once

#include <fcntl.h>  // AT_FDCWD
#include <stdio.h>  // renameat2, RENAME_EXCHANGE (glibc >= 2.28, _GNU_SOURCE as g++ defines it)
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

// The file's bytes, or nullopt: no such file (`why_not` left empty), or one that cannot be read,
// a folder among them (`why_not` names it and says why).
inline std::optional<std::string> ReadWholeFile(const std::string& path,
                                                std::string* why_not = nullptr) {
  if (why_not) why_not->clear();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  if (std::filesystem::is_directory(path, ec)) {
    if (why_not) *why_not = path + ": is a folder, not a file";
    return std::nullopt;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (why_not) *why_not = path + ": cannot be opened";
    return std::nullopt;
  }
  std::string bytes;
  try {  // libstdc++'s filebuf throws from a failed read(2) (EIO, EISDIR) rather than set badbit
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  } catch (const std::ios_base::failure& e) {
    if (why_not) *why_not = path + ": read error: " + e.what();
    return std::nullopt;
  }
  if (in.bad()) {
    if (why_not) *why_not = path + ": read error";
    return std::nullopt;
  }
  return bytes;
}

// The file's bytes; InvalidInputError naming the file when it is missing or cannot be read (the
// text files a user hands the library: worlds, sequences, labels).
inline std::string ReadWholeFileOrThrow(const std::string& path) {
  std::string why;
  std::optional<std::string> bytes = ReadWholeFile(path, &why);
  if (!bytes) throw InvalidInputError(why.empty() ? path + ": no such file" : why);
  return std::move(*bytes);
}

// The file decoded by `decode(bytes)`, or nullopt: no such file (`why_not` left empty), one that
// cannot be read, or bytes `decode` refuses with InvalidInputError (`why_not` names the file and
// says why). A cache's miss: the caller computes the value again.
template <typename Decode>
auto ReadDecodedFile(const std::string& path, std::string* why_not, Decode&& decode)
    -> std::optional<decltype(decode(std::string()))> {
  const std::optional<std::string> bytes = ReadWholeFile(path, why_not);
  if (!bytes) return std::nullopt;
  try {
    return decode(*bytes);
  } catch (const InvalidInputError& e) {
    if (why_not) *why_not = path + ": " + e.what();
    return std::nullopt;
  }
}

// Creates the folder `dir` and its parents (nothing when they exist). Throws InvalidInputError,
// prefixed with `who`, naming the folder and why when it cannot (a file in the way, no right),
// where std::filesystem would throw its own filesystem_error.
inline void CreateFolder(const std::filesystem::path& dir, const std::string& who) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InvalidInputError(who + ": cannot create '" + dir.string() + "': " + ec.message());
}

// Removes `path` and all it holds (nothing when it does not exist). Throws Error, prefixed with
// `who`, naming it and why when it cannot.
inline void RemoveAll(const std::filesystem::path& path, const std::string& who) {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
  if (ec) throw Error(who + ": cannot remove '" + path.string() + "': " + ec.message());
}

// Writes `bytes` to `path`, creating its folder. Throws InvalidInputError, prefixed with `who`,
// naming the path when it cannot; the target is then unchanged.
inline void WriteWholeFile(const std::string& path, std::string_view bytes,
                           const std::string& who) {
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (!dir.empty()) CreateFolder(dir, who);
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::filesystem::remove(tmp, ec);
      throw InvalidInputError(who + ": cannot write '" + tmp + "'");
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw InvalidInputError(who + ": cannot rename into '" + path + "'");
  }
}

// Folders written whole (a robot's map: its g2o and TUM files) put in place of the last version.
// `staged` is the new folder, complete; `target` the one it replaces (or nothing yet).

namespace whole_file_detail {

inline std::string DescribeReplace(const std::string& who, const std::filesystem::path& staged,
                                   const std::filesystem::path& target) {
  return who + ": cannot put '" + staged.string() + "' in place of '" + target.string() + "'";
}

// The portable way: the old folder renamed aside to `target`.old, the new one renamed into place,
// the old one removed. Between the two renames `target` is absent, but a crash there leaves both
// folders on disk (the old one as .old). When the second rename fails the old folder is put back.
inline void ReplaceDirectoryByRenames(const std::filesystem::path& staged,
                                      const std::filesystem::path& target, const std::string& who) {
  std::error_code ec;
  const std::filesystem::path aside = target.string() + ".old";
  std::filesystem::remove_all(aside, ec);
  std::filesystem::rename(target, aside, ec);
  if (ec) throw InvalidInputError(DescribeReplace(who, staged, target) + ": " + ec.message());
  std::filesystem::rename(staged, target, ec);
  if (ec) {
    const std::string why = ec.message();
    std::error_code back;
    std::filesystem::rename(aside, target, back);
    throw InvalidInputError(DescribeReplace(who, staged, target) + ": " + why +
                            (back ? " (the old folder is left at '" + aside.string() + "')" : ""));
  }
  std::filesystem::remove_all(aside, ec);  // a leftover is removed by the next replacement
}

}  // namespace whole_file_detail

// Puts the folder `staged` in place of `target`, so that a reader of `target` finds the old
// version or the new one, whole, never a mix. When `target` exists, Linux's
// renameat2(RENAME_EXCHANGE) swaps the two folders in one step (`target` is never absent, a crash
// keeps one complete version in place) and the old one, now at `staged`, is removed; on a
// filesystem that cannot exchange, whole_file_detail::ReplaceDirectoryByRenames. Throws
// InvalidInputError, prefixed with `who` and naming both paths, when `staged` is not a folder or a
// rename fails; `target` is then unchanged, unless the fallback could not put the old folder back
// (the message then says where it is).
inline void ReplaceDirectory(const std::filesystem::path& staged,
                             const std::filesystem::path& target, const std::string& who) {
  std::error_code ec;
  if (!std::filesystem::is_directory(staged, ec)) {
    throw InvalidInputError(whole_file_detail::DescribeReplace(who, staged, target) +
                            ": the new folder does not exist");
  }
  if (!std::filesystem::exists(target, ec)) {
    std::filesystem::rename(staged, target, ec);
    if (ec) {
      throw InvalidInputError(whole_file_detail::DescribeReplace(who, staged, target) + ": " +
                              ec.message());
    }
    return;
  }
  if (::renameat2(AT_FDCWD, staged.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) == 0) {
    std::filesystem::remove_all(staged, ec);  // the old version; a leftover is harmless
    return;
  }
  const int err = errno;
  if (err == EINVAL || err == ENOSYS || err == ENOTSUP) {  // no exchange on this filesystem
    whole_file_detail::ReplaceDirectoryByRenames(staged, target, who);
    return;
  }
  throw InvalidInputError(whole_file_detail::DescribeReplace(who, staged, target) + ": " +
                          std::strerror(err));
}

}  // namespace moslam
