// RFC 8785 (JCS): the RFC's own test vectors (Appendix B numbers, §3.2.2 example, §3.2.3
// sorting) against safestate::safety::jcs. The differential test against PyPI's rfc8785 on
// random JSON is tests/integration/test_safety_config.py.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "safestate/safety/jcs.hpp"
#include "safestate/safety/safety_config.hpp"

using namespace safestate::safety;

namespace {
std::string from_bits(std::uint64_t bits) {
  return jcs::number_to_string(std::bit_cast<double>(bits)).value_or("<none>");
}
}  // namespace

TEST(Jcs, AppendixBNumbers) {
  const std::vector<std::pair<std::uint64_t, const char*>> vectors = {
      {0x0000000000000000ULL, "0"},
      {0x8000000000000000ULL, "0"},
      {0x0000000000000001ULL, "5e-324"},
      {0x8000000000000001ULL, "-5e-324"},
      {0x7fefffffffffffffULL, "1.7976931348623157e+308"},
      {0xffefffffffffffffULL, "-1.7976931348623157e+308"},
      {0x4340000000000000ULL, "9007199254740992"},
      {0xc340000000000000ULL, "-9007199254740992"},
      {0x4430000000000000ULL, "295147905179352830000"},
      {0x44b52d02c7e14af5ULL, "9.999999999999997e+22"},
      {0x44b52d02c7e14af6ULL, "1e+23"},
      {0x44b52d02c7e14af7ULL, "1.0000000000000001e+23"},
      {0x444b1ae4d6e2ef4eULL, "999999999999999700000"},
      {0x444b1ae4d6e2ef4fULL, "999999999999999900000"},
      {0x444b1ae4d6e2ef50ULL, "1e+21"},
      {0x3eb0c6f7a0b5ed8cULL, "9.999999999999997e-7"},
      {0x3eb0c6f7a0b5ed8dULL, "0.000001"},
      {0x41b3de4355555553ULL, "333333333.3333332"},
      {0x41b3de4355555554ULL, "333333333.33333325"},
      {0x41b3de4355555555ULL, "333333333.3333333"},
      {0x41b3de4355555556ULL, "333333333.3333334"},
      {0x41b3de4355555557ULL, "333333333.33333343"},
      {0xbecbf647612f3696ULL, "-0.0000033333333333333333"},
      {0x43143ff3c1cb0959ULL, "1424953923781206.2"},
  };
  for (const auto& [bits, expected] : vectors) {
    EXPECT_EQ(from_bits(bits), expected) << std::hex << bits;
  }
}

TEST(Jcs, NanAndInfinityAreRefused) {
  EXPECT_FALSE(jcs::number_to_string(std::bit_cast<double>(0x7fffffffffffffffULL)).has_value());
  EXPECT_FALSE(jcs::number_to_string(std::bit_cast<double>(0x7ff0000000000000ULL)).has_value());
  EXPECT_FALSE(jcs::number_to_string(-INFINITY).has_value());
  EXPECT_FALSE(jcs::canonicalize(nlohmann::json::array({1.0, NAN})).has_value());
}

TEST(Jcs, SmallIntegersAndFractions) {
  EXPECT_EQ(jcs::number_to_string(1.0), "1");
  EXPECT_EQ(jcs::number_to_string(-1.5), "-1.5");
  EXPECT_EQ(jcs::number_to_string(100.0), "100");
  EXPECT_EQ(jcs::number_to_string(1e21), "1e+21");
  EXPECT_EQ(jcs::number_to_string(1e20), "100000000000000000000");
  EXPECT_EQ(jcs::number_to_string(1e-7), "1e-7");
  EXPECT_EQ(jcs::number_to_string(1.5e-7), "1.5e-7");
  EXPECT_EQ(jcs::number_to_string(0.1), "0.1");
}

TEST(Jcs, Section322Example) {
  const std::string input = R"({
  "numbers": [333333333.33333329, 1E30, 4.50, 2e-3, 0.000000000000000000000000001],
  "string": "\u20ac$\u000F\u000aA'\u0042\u0022\u005c\\\"\/",
  "literals": [null, true, false]
})";
  std::vector<Error> errors;
  const auto c = canonical_json(input, errors);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(*c, "{\"literals\":[null,true,false],\"numbers\":[333333333.3333333,1e+30,4.5,0.002,1e-27],"
                "\"string\":\"\xE2\x82\xAC$\\u000f\\nA'B\\\"\\\\\\\\\\\"/\"}");
}

TEST(Jcs, Section323SortingByUtf16CodeUnits) {
  const std::string input =
      R"({"\u20ac":"Euro Sign","\r":"Carriage Return","\ufb33":"Hebrew Letter Dalet With Dagesh","1":"One",)"
      R"("\ud83d\ude00":"Emoji: Grinning Face","\u0080":"Control","\u00f6":"Latin Small Letter O With Diaeresis"})";
  std::vector<Error> errors;
  const auto c = canonical_json(input, errors);
  ASSERT_TRUE(c.has_value());
  // \r, 1, U+0080, U+00F6, U+20AC, U+1F600 (surrogates D83D DE00), U+FB33: UTF-8 byte
  // order would put U+1F600 last.
  EXPECT_EQ(*c, "{\"\\r\":\"Carriage Return\",\"1\":\"One\",\"\xC2\x80\":\"Control\","
                "\"\xC3\xB6\":\"Latin Small Letter O With Diaeresis\",\"\xE2\x82\xAC\":\"Euro Sign\","
                "\"\xF0\x9F\x98\x80\":\"Emoji: Grinning Face\",\"\xEF\xAC\xB3\":\"Hebrew Letter Dalet With Dagesh\"}");
}

TEST(Jcs, StringEscapes) {
  nlohmann::json s = std::string("a\x01\x1f\x7f/\b\t\n\f\r\"\\z");
  EXPECT_EQ(jcs::canonicalize(s), "\"a\\u0001\\u001f\x7f/\\b\\t\\n\\f\\r\\\"\\\\z\"");
}

TEST(Jcs, IntegersBeyond2To53BecomeDoubles) {
  std::vector<Error> errors;
  EXPECT_EQ(canonical_json("[9007199254740993, -9007199254740993, 18446744073709551615, 1e400000000000000000000]",
                           errors),
            std::nullopt);  // the last one overflows a double: refused
  errors.clear();
  EXPECT_EQ(canonical_json("[9007199254740993, -9007199254740993, 18446744073709551615, 123456789012345678901234]",
                           errors),
            "[9007199254740992,-9007199254740992,18446744073709552000,1.2345678901234569e+23]");  // as Python float()
  EXPECT_TRUE(errors.empty());
}

TEST(Jcs, WhitespaceOrderAndSpellingDoNotChangeTheForm) {
  std::vector<Error> errors;
  const auto a = canonical_json(R"({"b": [1.0, 2E1, -0], "a": {"y": true, "x": "\u0041"}})", errors);
  const auto b = canonical_json("{\"a\":{\"x\":\"A\",\"y\":true},\n\t\"b\":[1,20,0]}", errors);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(*a, *b);
  EXPECT_EQ(*a, R"({"a":{"x":"A","y":true},"b":[1,20,0]})");
}

TEST(Jcs, DuplicateKeysAndDeepNestingAreRefused) {
  std::vector<Error> errors;
  EXPECT_FALSE(canonical_json(R"({"a": 1, "b": {"c": 1, "c": 2}})", errors).has_value());
  ASSERT_EQ(errors.size(), 1U);
  EXPECT_EQ(errors[0].text(), "b.c: duplicate key (a key may appear once in an object)");
  errors.clear();
  EXPECT_FALSE(canonical_json(std::string(100000, '[') + std::string(100000, ']'), errors).has_value());
  ASSERT_EQ(errors.size(), 1U);
  EXPECT_NE(errors[0].message.find("nested deeper than 16"), std::string::npos) << errors[0].text();
}

TEST(Checksum, Sha256OfKnownText) {
  // FIPS 180-2 example: SHA-256("abc").
  EXPECT_EQ(sha256_hex("abc"), "BA7816BF8F01CFEA414140DE5DAE2223B00361A396177A9CB410FF61F20015AD");
  EXPECT_EQ(checksum_text("abc"), "BA7816BF");
  EXPECT_EQ(checksum_value("abc"), 0xBA7816BFU);
}
