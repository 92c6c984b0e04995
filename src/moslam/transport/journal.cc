#include "moslam/transport/journal.h"

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

std::array<std::uint32_t, 256> MakeCrcTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}

std::uint32_t ReadU32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 |
         std::uint32_t{p[3]} << 24;
}

void PutU32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

}  // namespace

std::uint32_t Crc32(const std::uint8_t* data, std::size_t size) {
  static const std::array<std::uint32_t, 256> table = MakeCrcTable();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < size; ++i) c = table[(c ^ data[i]) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

Journal::Journal(const std::string& path) : path_(path) {
  std::string why;
  std::optional<std::string> text = ReadWholeFile(path_, &why);
  if (!text && !why.empty()) throw Error("journal " + why);
  const std::string bytes = text ? std::move(*text) : std::string();
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  std::size_t good = 0;
  while (bytes.size() - good >= 8) {
    const std::uint32_t length = ReadU32(data + good);
    const std::uint32_t crc = ReadU32(data + good + 4);
    if (length > kMaxJournalRecord || bytes.size() - good - 8 < length) break;
    const std::uint8_t* payload = data + good + 8;
    if (Crc32(payload, length) != crc) break;
    records_.emplace_back(payload, payload + length);
    good += 8 + length;
  }
  truncated_ = static_cast<std::int64_t>(bytes.size() - good);
  if (truncated_ > 0) {
    std::error_code ec;
    std::filesystem::resize_file(path_, good, ec);
    if (ec) throw Error("journal " + path_ + ": cannot cut its torn tail (" + ec.message() + ")");
  }
  file_ = std::fopen(path_.c_str(), "ab");
  if (!file_) {
    throw Error("journal " + path_ + ": cannot be opened for writing (" +
                std::strerror(errno) + ")");
  }
}

Journal::~Journal() {
  if (file_) std::fclose(file_);
}

void Journal::append(const std::vector<std::uint8_t>& payload) {
  if (payload.size() > kMaxJournalRecord) {
    throw Error("journal " + path_ + ": record of " + std::to_string(payload.size()) +
                " bytes is too large");
  }
  std::vector<std::uint8_t> record(8 + payload.size());
  PutU32(record.data(), static_cast<std::uint32_t>(payload.size()));
  PutU32(record.data() + 4, Crc32(payload.data(), payload.size()));
  std::copy(payload.begin(), payload.end(), record.begin() + 8);
  if (std::fwrite(record.data(), 1, record.size(), file_) != record.size() ||
      std::fflush(file_) != 0) {
    throw Error("journal " + path_ + ": write failed (" + std::strerror(errno) + ")");
  }
}

}  // namespace moslam
