// Refusal messages name the field, the value and the allowed range.
#include "sim_core/common/input_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tests/support/refusal.h"

namespace costume::sim {
namespace {

using test::RefusalOf;

TEST(RequirePositive, NamesFieldValueAndRange) {
  const std::string message = RefusalOf([] { RequirePositive("material.density", -2.5, "kg/m²"); });
  EXPECT_NE(message.find("material.density"), std::string::npos);
  EXPECT_NE(message.find("-2.5 kg/m²"), std::string::npos);
  EXPECT_NE(message.find("> 0"), std::string::npos);
}

TEST(RequirePositive, RefusesZeroNanAndInfinity) {
  for (double bad : {0.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(RequirePositive("x", bad, ""), InputError);
  }
  EXPECT_NO_THROW(RequirePositive("x", 1e-300, ""));
}

TEST(RequireInRange, QuotesBothBounds) {
  const std::string message = RefusalOf([] { RequireInRange("solver.tolerance", 2, 0, 1, ""); });
  EXPECT_NE(message.find("solver.tolerance = 2"), std::string::npos);
  EXPECT_NE(message.find("allowed 0 to 1"), std::string::npos);
}

TEST(RequirePositiveAtMost, RefusesZeroAndAboveTheBoundQuotingIt) {
  const std::string message =
      RefusalOf([] { RequirePositiveAtMost("material.density", 150, 100, "kg/m²"); });
  EXPECT_NE(message.find("material.density = 150 kg/m²"), std::string::npos) << message;
  EXPECT_NE(message.find("above 0 up to 100 kg/m²"), std::string::npos) << message;
  for (double bad : {0.0, -1.0, 100.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(RequirePositiveAtMost("x", bad, 100, ""), InputError) << bad;
  }
  EXPECT_NO_THROW(RequirePositiveAtMost("x", 1e-300, 100, ""));
  EXPECT_NO_THROW(RequirePositiveAtMost("x", 100, 100, ""));
}

TEST(FormatValue, SpellsOutNonFiniteValues) {
  EXPECT_EQ(FormatValue(std::nan("")), "nan");
  EXPECT_EQ(FormatValue(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(FormatValue(0.1), "0.1");
}

TEST(QuoteForMessage, EscapesControlAndNonUtf8BytesAndKeepsUtf8) {
  EXPECT_EQ(QuoteForMessage("1.\xb4" "97"), "1.\\xb497");  // a stray continuation byte
  EXPECT_EQ(QuoteForMessage("\x10.18909"), "\\x10.18909");
  EXPECT_EQ(QuoteForMessage("a\x7f\tb"), "a\\x7f\\x09b");
  EXPECT_EQ(QuoteForMessage("d\xc3\xa9t\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"),
            "d\xc3\xa9t\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");  // é, €, an emoji
  EXPECT_EQ(QuoteForMessage("\xc2\x85"), "\\xc2\\x85");              // C1 control NEL
  EXPECT_EQ(QuoteForMessage("\xc0\xaf"), "\\xc0\\xaf");              // overlong '/'
  EXPECT_EQ(QuoteForMessage("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // a surrogate
  EXPECT_EQ(QuoteForMessage("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");  // > U+10FFFF
  EXPECT_EQ(QuoteForMessage("a\xe2\x82"), "a\\xe2\\x82");            // cut at the end
}

TEST(QuoteForMessage, CutsAfterMaxBytesNeverInsideACharacter) {
  EXPECT_EQ(QuoteForMessage(std::string(40, 'a')), std::string(40, 'a'));
  EXPECT_EQ(QuoteForMessage(std::string(41, 'a')), std::string(40, 'a') + "…");
  // é is two bytes: the 40th byte would split it, so it goes whole into the "…".
  EXPECT_EQ(QuoteForMessage(std::string(39, 'a') + "\xc3\xa9"), std::string(39, 'a') + "…");
  EXPECT_EQ(QuoteForMessage("abc\x01", 3), "abc…");
  EXPECT_EQ(QuoteForMessage(""), "");
}

}  // namespace
}  // namespace costume::sim
