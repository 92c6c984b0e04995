#include "moslam/common/number_text.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <string>

namespace moslam {
namespace {

TEST(NumberText, AWholeTokenInTheCLocalesSyntax) {
  double d = -1.0;
  EXPECT_EQ(ParseNumberToken("0.5", d), NumberStatus::kOk);
  EXPECT_EQ(d, 0.5);
  EXPECT_EQ(ParseNumberToken("+2.5e-3", d), NumberStatus::kOk);
  EXPECT_EQ(d, 2.5e-3);
  EXPECT_EQ(ParseNumberToken("-7", d), NumberStatus::kOk);
  EXPECT_EQ(d, -7.0);
  float f = 0.0f;
  EXPECT_EQ(ParseNumberToken("0.1", f), NumberStatus::kOk);
  EXPECT_EQ(f, 0.1f);  // read as a float, not a double rounded twice
  int i = 0;
  EXPECT_EQ(ParseNumberToken("+42", i), NumberStatus::kOk);
  EXPECT_EQ(i, 42);
}

TEST(NumberText, EverythingElseIsRefusedAndLeavesTheValue) {
  double d = 3.0;
  for (const char* bad : {"", "+", "-", "0,5", " 1", "1 ", "1.5abc", "0x1p3", "++1", "+-1", "e5"}) {
    EXPECT_EQ(ParseNumberToken(bad, d), NumberStatus::kNotANumber) << "'" << bad << "'";
  }
  EXPECT_EQ(ParseNumberToken("1e400", d), NumberStatus::kOutOfRange);
  for (const char* bad : {"nan", "inf", "-inf", "+nan"}) {
    EXPECT_EQ(ParseNumberToken(bad, d), NumberStatus::kNotFinite) << bad;
  }
  EXPECT_EQ(d, 3.0);
  int i = 5;
  EXPECT_EQ(ParseNumberToken("2.5", i), NumberStatus::kNotANumber);
  EXPECT_EQ(ParseNumberToken("99999999999", i), NumberStatus::kOutOfRange);
  EXPECT_EQ(i, 5);
  float f = 1.0f;
  EXPECT_EQ(ParseNumberToken("1e39", f), NumberStatus::kOutOfRange);
  EXPECT_EQ(NumberStatusReason(NumberStatus::kNotANumber, "a double"), "is not a number");
  EXPECT_EQ(NumberStatusReason(NumberStatus::kOutOfRange, "a float"),
            "is out of the range of a float");
  EXPECT_NE(NumberStatusReason(NumberStatus::kNotFinite, "a double").find("NaN and Inf"),
            std::string::npos);
}

}  // namespace
}  // namespace moslam
