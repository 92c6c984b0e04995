// Whole files: read at once (the caches on disk, the text files a user hands the library), and
// the caches (the template cache, the perception cache) written so that a reader never sees half
// of one (the bytes go to a temporary file beside
// the target, renamed into place: atomic on one filesystem).
#pragma once

#include <unistd.h>

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

// The file's bytes, or nullopt: no such file (`why_not` left empty), or one that cannot be read
// (`why_not` names it and says why).
inline std::optional<std::string> ReadWholeFile(const std::string& path,
                                                std::string* why_not = nullptr) {
  if (why_not) why_not->clear();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (why_not) *why_not = path + ": cannot be opened";
    return std::nullopt;
  }
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
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

// Writes `bytes` to `path`, creating its folder. Throws InvalidInputError, prefixed with `who`,
// naming the path when it cannot; the target is then unchanged.
inline void WriteWholeFile(const std::string& path, std::string_view bytes,
                           const std::string& who) {
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (!dir.empty()) {
    std::filesystem::create_directories(dir, ec);
    if (ec) throw InvalidInputError(who + ": cannot create '" + dir.string() + "': " + ec.message());
  }
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

}  // namespace moslam
