// Little-endian bytes for the project's file formats: a writer that appends to a string, and a
// reader over a string_view that checks every read against the bytes left and throws
// InvalidInputError naming the format, the field and the offset. Values are read as stored; the
// caller validates what they mean (finite, in range).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"

namespace moslam {

class ByteWriter {
 public:
  void u32(std::uint32_t v) { put(v); }
  void i32(std::int32_t v) { put(static_cast<std::uint32_t>(v)); }
  void u64(std::uint64_t v) { put(v); }
  void f32(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    put(bits);
  }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    put(bits);
  }
  void bytes(std::string_view s) { out_.append(s); }
  // Appends the checksum the project's file formats end with: FNV-1a 64 of every byte so far
  // (SealedBody checks it).
  void seal() { u64(Fnv1a64(out_.data(), out_.size())); }
  const std::string& str() const { return out_; }
  std::string take() { return std::move(out_); }

 private:
  template <class U>
  void put(U v) {
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      out_.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
    }
  }
  std::string out_;
};

class ByteReader {
 public:
  // `format` names the bytes in every error ("perception cache file").
  ByteReader(std::string_view in, std::string format) : in_(in), format_(std::move(format)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InvalidInputError(format_ + ": " + what + " (at byte " + std::to_string(at_) + " of " +
                            std::to_string(in_.size()) + ")");
  }
  std::uint32_t u32(const char* field) { return get<std::uint32_t>(field); }
  std::int32_t i32(const char* field) { return static_cast<std::int32_t>(u32(field)); }
  std::uint64_t u64(const char* field) { return get<std::uint64_t>(field); }
  float f32(const char* field) {
    const std::uint32_t bits = u32(field);
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  double f64(const char* field) {
    const std::uint64_t bits = u64(field);
    double v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  std::string_view take(std::size_t n, const char* field) {
    need(n, field);
    const std::string_view s = in_.substr(at_, n);
    at_ += n;
    return s;
  }
  // A u32 count of items of at least `min_item_bytes` each, which must fit in the bytes left (a
  // damaged count cannot make the caller allocate gigabytes).
  std::uint32_t count(std::size_t min_item_bytes, const char* field) {
    const std::uint32_t n = u32(field);
    if (static_cast<std::uint64_t>(n) * min_item_bytes > left()) {
      fail(std::string(field) + " count " + std::to_string(n) + " exceeds the bytes left");
    }
    return n;
  }
  std::size_t at() const { return at_; }
  std::size_t left() const { return in_.size() - at_; }
  // Throws if any byte is left.
  void finish() const {
    if (left() != 0) fail(std::to_string(left()) + " trailing bytes");
  }

 private:
  void need(std::size_t n, const char* field) const {
    if (n > left()) fail(std::string("truncated in ") + field);
  }
  template <class U>
  U get(const char* field) {
    need(sizeof(U), field);
    U v = 0;
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      v |= static_cast<U>(static_cast<unsigned char>(in_[at_ + i])) << (8 * i);
    }
    at_ += sizeof(U);
    return v;
  }

  std::string_view in_;
  std::string format_;
  std::size_t at_ = 0;
};

// The bytes before the checksum ByteWriter::seal() appended, after checking it. Throws
// InvalidInputError naming `format` if fewer than `min_body` bytes precede the checksum, or if it
// does not match (a damaged or partly written file).
inline std::string_view SealedBody(std::string_view bytes, std::size_t min_body,
                                   const std::string& format) {
  const ByteReader whole(bytes, format);
  if (bytes.size() < min_body + sizeof(std::uint64_t)) whole.fail("too short");
  const std::string_view body = bytes.substr(0, bytes.size() - sizeof(std::uint64_t));
  if (ByteReader(bytes.substr(body.size()), format).u64("checksum") !=
      Fnv1a64(body.data(), body.size())) {
    whole.fail("checksum mismatch (damaged or partly written)");
  }
  return body;
}

}  // namespace moslam
