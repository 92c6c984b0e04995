#include "moslam/graph/key.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

TEST(Key, DecodesDistributedMapperSymbols) {
  // 'a' = 97: 97 << 56 = 6989586621679009792 (blocks_world/2robots/0.g2o).
  const Key k = DecodeSymbol(6989586621679009793ULL, KeyScheme::kPosesOnly);
  EXPECT_EQ(k, Key::Pose(0, 1));
  EXPECT_EQ(DecodeSymbol(7061644215716937730ULL, KeyScheme::kPosesOnly), Key::Pose(1, 2));  // 'b'
}

TEST(Key, PlainIntegersArePosesOfRobotZero) {
  EXPECT_EQ(DecodeSymbol(42, KeyScheme::kPosesOnly), Key::Pose(0, 42));
  EXPECT_EQ(DecodeSymbol(42, KeyScheme::kWithObjects), Key::Pose(0, 42));
}

TEST(Key, UpperCaseMeansRobotsAbove26OrObjectsBySchemeOnly) {
  const std::uint64_t raw = (std::uint64_t('C') << 56) | 7;
  EXPECT_EQ(DecodeSymbol(raw, KeyScheme::kPosesOnly), Key::Pose(28, 7));
  EXPECT_EQ(DecodeSymbol(raw, KeyScheme::kWithObjects), Key::Object(2, 7));
}

TEST(Key, RoundTripsUnderBothSchemes) {
  for (int r = 0; r < kMaxRobots; ++r) {
    const Key k = Key::Pose(r, 123456789);
    EXPECT_EQ(DecodeSymbol(EncodeSymbol(k, KeyScheme::kPosesOnly), KeyScheme::kPosesOnly), k);
  }
  for (int r = 0; r < kMaxRobotsWithObjects; ++r) {
    for (const Key& k : {Key::Pose(r, 5), Key::Object(r, kMaxKeyIndex)}) {
      EXPECT_EQ(DecodeSymbol(EncodeSymbol(k, KeyScheme::kWithObjects), KeyScheme::kWithObjects),
                k);
    }
  }
}

TEST(Key, RejectsWhatHasNoEncoding) {
  EXPECT_THROW(EncodeSymbol(Key::Pose(52, 0), KeyScheme::kPosesOnly), InvalidInputError);
  EXPECT_THROW(EncodeSymbol(Key::Pose(26, 0), KeyScheme::kWithObjects), InvalidInputError);
  EXPECT_THROW(EncodeSymbol(Key::Object(0, 0), KeyScheme::kPosesOnly), InvalidInputError);
  EXPECT_THROW(EncodeSymbol(Key::Pose(0, kMaxKeyIndex + 1), KeyScheme::kPosesOnly),
               InvalidInputError);
  EXPECT_THROW(DecodeSymbol(std::uint64_t('#') << 56, KeyScheme::kPosesOnly), InvalidInputError);
}

TEST(Key, OrderAndPrinting) {
  EXPECT_LT(Key::Pose(0, 9), Key::Object(0, 0));
  EXPECT_LT(Key::Object(0, 9), Key::Pose(1, 0));
  EXPECT_EQ(ToString(Key::Pose(1, 12)), "b12");
  EXPECT_EQ(ToString(Key::Object(1, 3)), "B3");
}

}  // namespace
}  // namespace moslam
