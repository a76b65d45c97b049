// The outside-string boundary: invalid UTF-8 becomes U+FFFD, one per maximal invalid subpart
// (Unicode 15, Sect. 3.9, Table 3-8's examples), valid text passes unchanged.
#include "core/utf8.hpp"

#include <gtest/gtest.h>

namespace feedloop {
namespace {

const std::string kFffd = "\xEF\xBF\xBD";

TEST(Utf8, ValidTextIsUnchanged) {
  for (const std::string s : {"", "hello",
                              "Gr\xC3\xBC\xC3\x9F"
                              "e",
                              "\xE2\x82\xAC 5", "\xF0\x9F\x96\xA8 ok", "\xF4\x8F\xBF\xBF"}) {
    EXPECT_TRUE(is_valid_utf8(s)) << s;
    EXPECT_EQ(valid_utf8(s), s);
  }
}

TEST(Utf8, InvalidBytesBecomeOneReplacementPerMaximalSubpart) {
  EXPECT_FALSE(is_valid_utf8("caf\xE9"));  // Latin-1
  EXPECT_EQ(valid_utf8("caf\xE9"), "caf" + kFffd);
  EXPECT_EQ(valid_utf8("\xFF\xFE"), kFffd + kFffd);                          // never valid bytes
  EXPECT_EQ(valid_utf8("\xC0\xAF"), kFffd + kFffd);                          // overlong '/'
  EXPECT_EQ(valid_utf8("\xED\xA0\x80"), kFffd + kFffd + kFffd);              // a surrogate
  EXPECT_EQ(valid_utf8("\xF4\x90\x80\x80"), kFffd + kFffd + kFffd + kFffd);  // > U+10FFFF
  EXPECT_EQ(valid_utf8("a\xE2\x82z"), "a" + kFffd + "z");  // truncated: one U+FFFD
  EXPECT_EQ(valid_utf8("\xF0\x9F\x96"), kFffd);            // truncated at the end
  // Table 3-8 of the Unicode standard: 61 F1 80 80 E1 80 C2 62 80 63 80 BF 64
  EXPECT_EQ(valid_utf8("\x61\xF1\x80\x80\xE1\x80\xC2\x62\x80\x63\x80\xBF\x64"),
            "a" + kFffd + kFffd + kFffd + "b" + kFffd + "c" + kFffd + kFffd + "d");
  for (const std::string s : {"caf\xE9", "\xFF", "\xED\xA0\x80", "\x61\xF1\x80\x80\xE1\x80\xC2"})
    EXPECT_TRUE(is_valid_utf8(valid_utf8(s)));
}

TEST(Utf8, AssignReusesStorage) {
  std::string out;
  out.reserve(64);
  const char* before = out.data();
  assign_valid_utf8(out, "M117 \xE9t\xE9");
  EXPECT_EQ(out, "M117 " + kFffd + "t" + kFffd);
  EXPECT_EQ(out.data(), before);
}

}  // namespace
}  // namespace feedloop
