// Little-endian bytes: the one writer and the one reader behind every byte format of the project
// (the DGS and rendezvous messages on the wire, the robots' journals, the perception and template
// caches). The writer appends to a std::string or a std::vector<std::uint8_t>; the reader checks
// every read against the bytes left and throws InvalidInputError naming the format, the field and
// the offset. Values are read as stored; the caller validates what they mean (finite, in range),
// and may report that through fail() with the same offset.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/fnv.h"

namespace moslam {

// Bytes a base-128 varint of `v` takes (7 bits a byte, low groups first).
inline std::size_t VarintSize(std::uint64_t v) {
  std::size_t n = 1;
  while (v >= 0x80) {
    v >>= 7;
    ++n;
  }
  return n;
}

// A varint of a 64-bit value takes at most 10 bytes; the formats here cap it lower.
inline constexpr std::size_t kMaxVarintBytes = 10;

template <class Bytes>
class BasicByteWriter {
  static_assert(sizeof(typename Bytes::value_type) == 1, "a byte container");

 public:
  BasicByteWriter() = default;
  // Reserves `capacity` bytes: an encoder that knows its size up front allocates once.
  explicit BasicByteWriter(std::size_t capacity) { out_.reserve(capacity); }

  BasicByteWriter& u8(std::uint8_t v) { return put(v); }
  BasicByteWriter& u16(std::uint16_t v) { return put(v); }
  BasicByteWriter& u32(std::uint32_t v) { return put(v); }
  BasicByteWriter& i32(std::int32_t v) { return put(static_cast<std::uint32_t>(v)); }
  BasicByteWriter& u64(std::uint64_t v) { return put(v); }
  BasicByteWriter& f32(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    return put(bits);
  }
  BasicByteWriter& f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    return put(bits);
  }
  BasicByteWriter& varint(std::uint64_t v) {
    while (v >= 0x80) {
      out_.push_back(static_cast<typename Bytes::value_type>((v & 0x7Fu) | 0x80u));
      v >>= 7;
    }
    out_.push_back(static_cast<typename Bytes::value_type>(v));
    return *this;
  }
  BasicByteWriter& bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const typename Bytes::value_type*>(data);
    out_.insert(out_.end(), p, p + n);
    return *this;
  }
  BasicByteWriter& bytes(std::string_view s) { return bytes(s.data(), s.size()); }
  // A u32 length, then the bytes.
  BasicByteWriter& sized(const std::vector<std::uint8_t>& v) {
    u32(static_cast<std::uint32_t>(v.size()));
    return bytes(v.data(), v.size());
  }
  // Appends the checksum the project's file formats end with: FNV-1a 64 of every byte so far
  // (SealedBody checks it).
  BasicByteWriter& seal() { return u64(Fnv1a64(out_.data(), out_.size())); }

  std::size_t size() const { return out_.size(); }
  const Bytes& data() const { return out_; }
  Bytes take() { return std::move(out_); }

 private:
  template <class U>
  BasicByteWriter& put(U v) {
    static_assert(std::is_unsigned_v<U>);
    typename Bytes::value_type le[sizeof(U)];
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      le[i] = static_cast<typename Bytes::value_type>((v >> (8 * i)) & 0xFFu);
    }
    out_.insert(out_.end(), le, le + sizeof(U));  // one capacity check, not one a byte
    return *this;
  }
  Bytes out_;
};

// Files (caches) are strings; messages and journal records are byte vectors.
using ByteWriter = BasicByteWriter<std::string>;
using WireWriter = BasicByteWriter<std::vector<std::uint8_t>>;

class ByteReader {
 public:
  // `format` names the bytes in every error ("perception cache file", "DGS message"). The bytes
  // must outlive the reader.
  ByteReader(std::string_view in, std::string format) : in_(in), format_(std::move(format)) {}
  ByteReader(const std::vector<std::uint8_t>& in, std::string format)
      : ByteReader(std::string_view(reinterpret_cast<const char*>(in.data()), in.size()),
                   std::move(format)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InvalidInputError(format_ + ": " + what + " (at byte " + std::to_string(at_) + " of " +
                            std::to_string(in_.size()) + ")");
  }
  std::uint8_t u8(const char* field) { return get<std::uint8_t>(field); }
  std::uint16_t u16(const char* field) { return get<std::uint16_t>(field); }
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
  // A varint of at most `max_bytes` bytes (kMaxVarintBytes at most), in its one canonical form (no
  // trailing zero group), so that every value has exactly one encoding and a decoded message
  // re-encodes to its bytes.
  std::uint64_t varint(const char* field, std::size_t max_bytes = kMaxVarintBytes) {
    if (max_bytes > kMaxVarintBytes) max_bytes = kMaxVarintBytes;  // 64 bits at most
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < max_bytes; ++i) {
      const std::uint8_t byte = u8(field);
      const std::uint64_t group = byte & 0x7Fu;
      if (i == 9 && group > 1) fail(std::string("varint beyond 64 bits in ") + field);
      v |= group << (7 * i);
      if ((byte & 0x80u) == 0) {
        if (i > 0 && byte == 0) fail(std::string("non-canonical varint in ") + field);
        return v;
      }
    }
    fail("varint longer than " + std::to_string(max_bytes) + " bytes in " + field);
  }
  std::string_view take(std::size_t n, const char* field) {
    need(n, field);
    const std::string_view s = in_.substr(at_, n);
    at_ += n;
    return s;
  }
  // What BasicByteWriter::sized wrote: a u32 length, then that many bytes.
  std::vector<std::uint8_t> sized(const char* field) {
    const std::string_view s = take(u32(field), field);
    return {s.begin(), s.end()};
  }
  // A u32 count of items of at least `min_item_bytes` each, which must fit in the bytes left (a
  // damaged count cannot make the caller allocate gigabytes).
  std::uint32_t count(std::size_t min_item_bytes, const char* field) {
    const std::uint32_t n = u32(field);
    if (static_cast<std::uint64_t>(n) * min_item_bytes > left()) {
      fail("truncated: " + std::string(field) + " count " + std::to_string(n) +
           " exceeds the bytes left");
    }
    return n;
  }
  // Throws unless `n` bytes are left.
  void need(std::size_t n, const char* field) const {
    if (n > left()) fail(std::string("truncated in ") + field);
  }
  std::size_t at() const { return at_; }
  std::size_t left() const { return in_.size() - at_; }
  bool atEnd() const { return left() == 0; }
  // Throws if any byte is left.
  void finish() const {
    if (left() != 0) fail(std::to_string(left()) + " trailing bytes");
  }

 private:
  template <class U>
  U get(const char* field) {
    need(sizeof(U), field);
    U v = 0;
    for (std::size_t i = 0; i < sizeof(U); ++i) {
      v = static_cast<U>(v | (static_cast<U>(static_cast<unsigned char>(in_[at_ + i])) << (8 * i)));
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
