// An append-only file of records, the persistent state of a robot process: every record is
// written whole and flushed to the operating system before append() returns, so a process that
// is killed (SIGKILL included) loses nothing it appended. Layout, little-endian:
//
//   per record: u32 payload length | u32 CRC-32 (IEEE) of the payload | payload
//
// Open() reads the records of an existing file up to the first torn or corrupt record (a crash
// in the middle of a write), cuts the file there and appends after it.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace moslam {

inline constexpr std::uint32_t kMaxJournalRecord = 256u << 20;

std::uint32_t Crc32(const std::uint8_t* data, std::size_t size);

class Journal {
 public:
  // Opens (creating if missing) `path`. Throws moslam::Error when it cannot be read or written.
  explicit Journal(const std::string& path);
  ~Journal();
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;

  // The records found when the file was opened (torn tail excluded).
  const std::vector<std::vector<std::uint8_t>>& records() const { return records_; }
  // Bytes cut from the end of the file at open (a torn last record).
  std::int64_t truncatedBytes() const { return truncated_; }
  // Throws moslam::Error on a write failure or a record larger than kMaxJournalRecord.
  void append(const std::vector<std::uint8_t>& payload);
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::vector<std::vector<std::uint8_t>> records_;
  std::int64_t truncated_ = 0;
};

}  // namespace moslam
