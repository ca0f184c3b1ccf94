// A peer's text on its way into a log line or a JSON document (common/peer_text.hpp).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "common/peer_text.hpp"

namespace loopwire {
namespace {

TEST(QuotedExcerpt, PrintableTextIsQuotedAsItIs) {
    EXPECT_EQ(quoted_excerpt("150"), "\"150\"");
    EXPECT_EQ(quoted_excerpt(""), "\"\"");
    EXPECT_EQ(quoted_excerpt("say \"on\" \\ off"), "\"say \\\"on\\\" \\\\ off\"");
}

TEST(QuotedExcerpt, EveryOtherByteIsEscapedSoNoLineCanBeSplitOrATerminalRewritten) {
    EXPECT_EQ(quoted_excerpt("\xff"), "\"\\xff\"");
    EXPECT_EQ(quoted_excerpt(std::string("a\nb\rc\x1b[2J\0d", 11)), "\"a\\x0ab\\x0dc\\x1b[2J\\x00d\"");
    EXPECT_EQ(quoted_excerpt("\xc2\xb0"), "\"\\xc2\\xb0\"");
    EXPECT_EQ(quoted_excerpt("\x7f"), "\"\\x7f\"");
}

TEST(QuotedExcerpt, LongTextIsCutAndSaysHowLongItWas) {
    const std::string payload(200 * 1024, 'a');
    const std::string excerpt = quoted_excerpt(payload);
    EXPECT_EQ(excerpt, "\"" + std::string(64, 'a') + "\"\u2026 (204800 bytes)");
    EXPECT_EQ(quoted_excerpt("abcdef", 3), "\"abc\"\u2026 (6 bytes)");
    EXPECT_EQ(quoted_excerpt("abc", 3), "\"abc\"");
    // Escaping cannot make a cut line long again: four characters a byte at most.
    EXPECT_LT(quoted_excerpt(std::string(100000, '\x01')).size(), 64u * 4 + 40);
}

TEST(WithoutControlBytes, OnlyControlBytesAreEscaped) {
    EXPECT_EQ(without_control_bytes("Ofen \xc2\xb0" "C \"quoted\""), "Ofen \xc2\xb0" "C \"quoted\"");
    EXPECT_EQ(without_control_bytes("a\x1b[2J\nb\x7f"), "a\\x1b[2J\\x0ab\\x7f");
}

TEST(PrintableExcerpt, EscapesLikeQuotedExcerptWithoutTheQuotes) {
    EXPECT_EQ(printable_excerpt("\"abc\" is not a number"), "\"abc\" is not a number");
    EXPECT_EQ(printable_excerpt("x\xffy", 2), "x\\xff\u2026 (3 bytes)");
}

TEST(JsonText, InvalidUtf8IsReplacedNotThrown) {
    const nlohmann::json document{{"ok", false}, {"value", "\xff"}};
    EXPECT_THROW((void)document.dump(), nlohmann::json::type_error);
    std::string text;
    ASSERT_NO_THROW(text = json_text(document));
    const auto back = nlohmann::json::parse(text);
    EXPECT_EQ(back.at("value"), "\xef\xbf\xbd");  // U+FFFD
    const nlohmann::ordered_json ordered{{"error", std::string("a\0b", 3)}};
    EXPECT_EQ(json_text(ordered), "{\"error\":\"a\\u0000b\"}");
}

}  // namespace
}  // namespace loopwire
