// The words file readers use in their errors (common/json_checks.hpp).
#include <gtest/gtest.h>

#include "common/json_checks.hpp"

namespace loopwire {
namespace {

TEST(JsonPointer, EscapesTildeAndSlashAsRfc6901Asks) {
    EXPECT_EQ(json_pointer("", "units"), "/units");
    EXPECT_EQ(json_pointer(json_pointer("/units", "3"), "saved"), "/units/3/saved");
    EXPECT_EQ(json_pointer("/parameters", "a/b~c"), "/parameters/a~1b~0c");
    EXPECT_EQ(json_pointer("/raw", std::size_t{2}), "/raw/2");
}

TEST(JsonWord, OnlyIntegersZeroTo65535AreWords) {
    EXPECT_EQ(json_word(nlohmann::json(0)), 0);
    EXPECT_EQ(json_word(nlohmann::json(65535)), 65535);
    for (const auto& value : {nlohmann::json(65536), nlohmann::json(-1), nlohmann::json(1.0), nlohmann::json("1"),
                              nlohmann::json::array({1}), nlohmann::json(nullptr)}) {
        EXPECT_FALSE(json_word(value)) << value.dump();
    }
}

TEST(DescribeJson, SaysWhatWasFoundAndShortensLongTexts) {
    EXPECT_EQ(describe_json(nlohmann::json("150")), "a string \"150\"");
    EXPECT_EQ(describe_json(nlohmann::json(1.5)), "the number 1.5");
    EXPECT_EQ(describe_json(nlohmann::json::array({150.0})), "an array [150.0]");
    EXPECT_EQ(describe_json(nlohmann::json::object()), "an object");
    EXPECT_EQ(describe_json(nlohmann::json(std::string(100, 'x'))).size(), std::string("a string ").size() + 40 + 3);
    // Invalid UTF-8 is described, not thrown on.
    EXPECT_NO_THROW(describe_json(nlohmann::json(std::string("\xff\xfe"))));
}

// Counted on the text without recursion, brackets in strings (escaped quotes too) left out, so
// that a reader refuses a document nested too deep before anything recursive touches it.
TEST(JsonNesting, CountsArraysAndObjectsOutsideStrings) {
    EXPECT_EQ(json_nesting_depth("150"), 0u);
    EXPECT_EQ(json_nesting_depth(R"({"a": [1, {"b": []}], "c": {}})"), 4u);
    EXPECT_EQ(json_nesting_depth(R"({"text": "[[[[{{{{ \" [[[["})"), 1u);
    EXPECT_FALSE(json_nesting_problem(std::string(64, '[') + std::string(64, ']')));
    const std::string deep = std::string(100000, '[') + std::string(100000, ']');
    EXPECT_EQ(json_nesting_problem(deep), "nests arrays and objects 100000 levels deep (at most 64)");
}

}  // namespace
}  // namespace loopwire
