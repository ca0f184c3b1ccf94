// Spot checks against the manuals: for each listed entry, the profile agrees on table, address,
// mnemonic, access and decimals, and the manual line it was transcribed from is really in the
// manual and carries the address. The manuals sit in shared/manuals beside the repository, where
// CI has them; a plain clone has none, so these tests skip there, saying where they looked.
// LOOPWIRE_MANUALS_DIR in the environment points them at another folder.
#include <cstdlib>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;
using testing::profile_ids;
using testing::profile_path;
using testing::read_json;
using Json = nlohmann::json;

// The folder given in the environment, else the one beside the repository.
std::string manuals_dir() {
    const char* from_environment = std::getenv("LOOPWIRE_MANUALS_DIR");
    return from_environment != nullptr && *from_environment != '\0' ? from_environment : LOOPWIRE_MANUALS_DIR;
}

// Why the manual checks cannot run here, or "" when they can.
std::string why_no_manuals(const std::string& dir) {
    if (std::filesystem::is_directory(dir)) return "";
    return "manuals not found at " + dir +
           ": a plain clone has no ../shared; CI runs these (or set LOOPWIRE_MANUALS_DIR to the folder)";
}

std::string access_of(const Parameter& parameter) {
    return std::string(parameter.readable ? "r" : "") + (parameter.writable ? "w" : "");
}

// Every run of digits in the line, as a number ("000" is 0, as the rampsoak map prints it).
std::vector<long> decimal_numbers(const std::string& line) {
    std::vector<long> numbers;
    std::string digits;
    for (const char c : line + ' ') {
        if (c >= '0' && c <= '9') {
            digits += c;
            continue;
        }
        if (!digits.empty() && digits.size() <= 9) numbers.push_back(std::stol(digits));
        digits.clear();
    }
    return numbers;
}

const Json* profile_entry(const Json& document, const std::string& name) {
    for (const Json& entry : document.at("parameters")) {
        if (entry.at("name") == name) return &entry;
    }
    return nullptr;
}

void expect_entry_matches(const Profile& profile, const Json& document, const Json& check) {
    const std::string name = check.at("name");
    const Parameter* parameter = profile.find(name);
    ASSERT_NE(parameter, nullptr) << profile.id << ": no parameter " << name;
    EXPECT_EQ(table_name(parameter->table), check.at("table")) << name;
    EXPECT_EQ(parameter->address, check.at("address").get<int>()) << name;
    EXPECT_EQ(parameter->mnemonic, check.at("mnemonic").is_null() ? "" : check.at("mnemonic").get<std::string>()) << name;
    EXPECT_EQ(access_of(*parameter), check.at("access")) << name;
    const Json& decimals = check.at("decimals");
    if (decimals.is_null()) {
        EXPECT_EQ(std::get<int>(parameter->decimals), 0) << name;
    } else if (decimals.is_object()) {
        EXPECT_EQ(std::get<std::string>(parameter->decimals), decimals.at("parameter")) << name;
    } else {
        EXPECT_EQ(std::get<int>(parameter->decimals), decimals.get<int>()) << name;
    }
    // Also exactly as written in the profile (null = no "decimals" member), note included.
    const Json* entry = profile_entry(document, name);
    ASSERT_NE(entry, nullptr);
    EXPECT_EQ(entry->contains("decimals") ? entry->at("decimals") : Json(), decimals) << name;
}

void expect_line_in_manual(const std::string& manual, const Json& check) {
    const std::string name = check.at("name");
    const std::string line = check.at("manual_line");
    EXPECT_NE(manual.find(line), std::string::npos) << name << ": manual_line is not in the manual: " << line;
    const auto numbers = decimal_numbers(line);
    const long address = check.at("address").get<long>();
    EXPECT_NE(std::find(numbers.begin(), numbers.end(), address), numbers.end())
        << name << ": manual_line does not contain address " << address << ": " << line;
}

TEST(SpotChecks, ManualsFolderHoldsEveryProfilesManual) {
    const std::string dir = manuals_dir();
    if (const std::string why = why_no_manuals(dir); !why.empty()) GTEST_SKIP() << why;
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        EXPECT_TRUE(std::filesystem::is_regular_file(dir + "/" + profile->manual_file))
            << id << ": its manual " << profile->manual_file << " is not in " << dir;
    }
}

TEST(SpotChecks, EveryEntryAgreesWithProfileAndManual) {
    const std::string dir = manuals_dir();
    if (const std::string why = why_no_manuals(dir); !why.empty()) GTEST_SKIP() << why;
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        const std::string manual_path = dir + "/" + profile->manual_file;
        std::string manual;
        ASSERT_TRUE(testing::read_text(manual_path, manual))
            << "cannot read the " << id << " manual " << manual_path
            << ": the folder is there, so its manual must be too";
        const Json document = read_json(profile_path(id));
        const Json checks = read_json(std::string(LOOPWIRE_SPOT_CHECK_DIR) + "/" + id + ".json");
        ASSERT_TRUE(checks.is_array());
        EXPECT_GE(checks.size(), 40u) << id;
        for (const Json& check : checks) {
            expect_entry_matches(*profile, document, check);
            expect_line_in_manual(manual, check);
        }
    }
}

}  // namespace
}  // namespace loopwire::device
