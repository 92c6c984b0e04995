#include "moslam/common/byte_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace moslam {
namespace {

// The message of the InvalidInputError `read` throws ("" if it throws none).
template <class Read>
std::string ErrorOf(Read read) {
  try {
    read();
  } catch (const InvalidInputError& e) {
    return e.what();
  }
  return "";
}

template <class Bytes>
Bytes EveryField() {
  BasicByteWriter<Bytes> w;
  w.u8(0xAB).u16(0xBEEF).u32(0xDEADBEEFu).i32(-7).u64(0x0123456789ABCDEFull);
  w.f32(-1.5f).f64(std::numeric_limits<double>::denorm_min()).varint(0).varint(300);
  w.varint(std::numeric_limits<std::uint64_t>::max()).bytes("xyz").sized({1, 2, 3});
  return w.take();
}

template <class Bytes>
void ExpectEveryField(const Bytes& bytes) {
  ByteReader r(bytes, "test bytes");
  EXPECT_EQ(r.u8("a"), 0xAB);
  EXPECT_EQ(r.u16("b"), 0xBEEF);
  EXPECT_EQ(r.u32("c"), 0xDEADBEEFu);
  EXPECT_EQ(r.i32("d"), -7);
  EXPECT_EQ(r.u64("e"), 0x0123456789ABCDEFull);
  EXPECT_EQ(r.f32("f"), -1.5f);
  EXPECT_EQ(r.f64("g"), std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(r.varint("h"), 0u);
  EXPECT_EQ(r.varint("i"), 300u);
  EXPECT_EQ(r.varint("j"), std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(r.take(3, "k"), "xyz");
  EXPECT_EQ(r.sized("l"), (std::vector<std::uint8_t>{1, 2, 3}));
  EXPECT_TRUE(r.atEnd());
  r.finish();
}

TEST(ByteIo, EveryFieldRoundTripsThroughStringsAndByteVectors) {
  const std::string s = EveryField<std::string>();
  const std::vector<std::uint8_t> v = EveryField<std::vector<std::uint8_t>>();
  ASSERT_EQ(s.size(), v.size());
  EXPECT_EQ(s, std::string(v.begin(), v.end()));
  ExpectEveryField(s);
  ExpectEveryField(v);
}

TEST(ByteIo, LittleEndianLayoutAndVarintSizes) {
  WireWriter w(16);
  w.u16(0x0102).u32(0x03040506u).varint(300);
  EXPECT_EQ(w.data(), (std::vector<std::uint8_t>{0x02, 0x01, 0x06, 0x05, 0x04, 0x03, 0xAC, 0x02}));
  EXPECT_EQ(VarintSize(0), 1u);
  EXPECT_EQ(VarintSize(127), 1u);
  EXPECT_EQ(VarintSize(128), 2u);
  EXPECT_EQ(VarintSize(std::numeric_limits<std::uint64_t>::max()), kMaxVarintBytes);
}

TEST(ByteIo, ErrorsNameTheFormatTheFieldAndTheOffset) {
  const std::vector<std::uint8_t> three{1, 2, 3};
  EXPECT_EQ(ErrorOf([&] {
              ByteReader r(three, "demo message");
              r.u16("header");
              r.u16("robot");
            }),
            "demo message: truncated in robot (at byte 2 of 3)");
  EXPECT_EQ(ErrorOf([&] { ByteReader(three, "demo message").finish(); }),
            "demo message: 3 trailing bytes (at byte 0 of 3)");
  // A count the bytes left cannot hold is refused before anyone allocates for it.
  WireWriter w;
  w.u32(1000).u64(0);
  EXPECT_EQ(ErrorOf([&] { ByteReader(w.data(), "demo").count(8, "pair"); }),
            "demo: truncated: pair count 1000 exceeds the bytes left (at byte 4 of 12)");
  WireWriter sized;
  sized.u32(5).u8(0);
  EXPECT_NE(ErrorOf([&] { ByteReader(sized.data(), "demo").sized("blob"); }).find("truncated"),
            std::string::npos);
}

TEST(ByteIo, VarintsHaveOneEncodingAndABoundedLength) {
  auto read = [](std::vector<std::uint8_t> bytes, std::size_t max_bytes) {
    return ErrorOf([&] { ByteReader(bytes, "v").varint("key", max_bytes); });
  };
  EXPECT_EQ(read({0x05}, 10), "");
  EXPECT_NE(read({0x85, 0x00}, 10).find("non-canonical"), std::string::npos);
  EXPECT_NE(read({0x80, 0x80, 0x01}, 2).find("longer than 2 bytes"), std::string::npos);
  std::vector<std::uint8_t> beyond(9, 0xFF);
  beyond.push_back(0x02);  // the tenth group may hold only the 64th bit
  EXPECT_NE(read(beyond, 10).find("beyond 64 bits"), std::string::npos);
  EXPECT_NE(read({0x80}, 10).find("truncated in key"), std::string::npos);
  std::vector<std::uint8_t> eleven(10, 0x80);
  eleven.push_back(0x01);  // a longer cap than 64 bits allow is read as 10 bytes
  EXPECT_NE(read(eleven, 11).find("longer than 10 bytes"), std::string::npos);
}

TEST(ByteIo, SealedBodyRefusesADamagedOrShortFile) {
  ByteWriter w;
  w.bytes("payload").seal();
  std::string sealed = w.take();
  EXPECT_EQ(SealedBody(sealed, 7, "cache"), "payload");
  EXPECT_NE(ErrorOf([&] { SealedBody(sealed, 8, "cache"); }).find("too short"), std::string::npos);
  sealed[0] = 'P';
  EXPECT_NE(ErrorOf([&] { SealedBody(sealed, 7, "cache"); }).find("checksum mismatch"),
            std::string::npos);
}

}  // namespace
}  // namespace moslam
