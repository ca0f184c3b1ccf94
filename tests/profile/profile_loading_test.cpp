// Loading profiles: the three real ones pass the schema and the checks beyond it; broken ones
// are refused with the file, the JSON pointer of the offending value and what is wrong.
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/profile.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::profile_ids;
using testing::profile_path;
using testing::read_json;
using Json = nlohmann::json;

const std::string origin = "broken/tc10.json";

Json tc10_document() { return read_json(profile_path("tc10")); }

// The error message of loading `document`; fails the test if it loads.
std::string load_error(const Json& document) {
    const auto loaded = load_profile_text(document.dump(2), origin);
    EXPECT_FALSE(loaded.ok()) << "a broken profile was accepted";
    if (loaded.ok()) return {};
    EXPECT_EQ(loaded.error().kind, ErrorKind::usage);
    return loaded.error().message;
}

std::string load_error_of_text(const std::string& text) {
    const auto loaded = load_profile_text(text, "broken.json");
    EXPECT_FALSE(loaded.ok()) << "broken JSON was accepted";
    return loaded.ok() ? std::string() : loaded.error().message;
}

TEST(ProfileLoading, EveryRealProfileFileValidates) {
    for (const std::string& id : profile_ids) {
        const auto loaded = load_profile_file(profile_path(id));
        ASSERT_TRUE(loaded.ok()) << loaded.error().message;
        EXPECT_EQ(loaded->id, id);
        EXPECT_FALSE(loaded->parameters.empty());
    }
}

TEST(ProfileLoading, BuiltinProfilesAreTheFilesInTheRepository) {
    EXPECT_EQ(builtin_profile_ids(), profile_ids);
    for (const std::string& id : profile_ids) {
        const auto builtin = builtin_profile(id);
        ASSERT_TRUE(builtin.ok()) << builtin.error().message;
        const auto from_file = load_profile_file(profile_path(id));
        ASSERT_TRUE(from_file.ok());
        ASSERT_EQ((*builtin)->parameters.size(), from_file->parameters.size()) << id << ": rebuild to re-embed";
        for (std::size_t i = 0; i < from_file->parameters.size(); ++i) {
            EXPECT_EQ((*builtin)->parameters[i].name, from_file->parameters[i].name);
            EXPECT_EQ((*builtin)->parameters[i].address, from_file->parameters[i].address);
        }
    }
}

TEST(ProfileLoading, BuiltinProfileIsLoadedOnceAndShared) {
    const auto first = builtin_profile("tc10");
    const auto second = builtin_profile("tc10");
    ASSERT_TRUE(first.ok() && second.ok());
    EXPECT_EQ(first->get(), second->get());
}

TEST(ProfileLoading, BuiltinProfilesCanBeFetchedFromManyThreadsAtOnce) {
    std::vector<const Profile*> seen(8, nullptr);
    std::vector<std::thread> threads;
    for (std::size_t i = 0; i < seen.size(); ++i) {
        threads.emplace_back([&seen, i] {
            const auto profile = builtin_profile(profile_ids[i % profile_ids.size()]);
            if (profile.ok()) seen[i] = profile->get();
        });
    }
    for (std::thread& thread : threads) thread.join();
    for (std::size_t i = 0; i < seen.size(); ++i) {
        ASSERT_NE(seen[i], nullptr);
        EXPECT_EQ(seen[i], seen[i % profile_ids.size()]);
    }
}

TEST(ProfileLoading, UnknownBuiltinIdListsTheKnownOnes) {
    const auto missing = builtin_profile("ac30");
    ASSERT_FALSE(missing.ok());
    EXPECT_EQ(missing.error().kind, ErrorKind::usage);
    EXPECT_THAT(missing.error().message, HasSubstr("\"ac30\""));
    EXPECT_THAT(missing.error().message, HasSubstr("ac20, rampsoak, tc10"));
}

TEST(ProfileLoading, MissingFileIsNamed) {
    const auto loaded = load_profile_file("/nonexistent/profile.json");
    ASSERT_FALSE(loaded.ok());
    EXPECT_THAT(loaded.error().message, HasSubstr("/nonexistent/profile.json: cannot open profile"));
}

// A FIFO given as a profile (--profile) is refused before it is opened: opening it would wait
// for a writer. Were it opened, this test would hang until ctest's timeout.
TEST(ProfileLoading, AFifoIsRefusedWithoutWaitingForAWriter) {
    const auto fifo = std::filesystem::temp_directory_path() / ("loopwire-profile-fifo-" + std::to_string(::getpid()) + ".json");
    std::filesystem::remove(fifo);
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const auto loaded = load_profile_file(fifo.string());
    std::filesystem::remove(fifo);
    ASSERT_FALSE(loaded.ok());
    EXPECT_THAT(loaded.error().message, HasSubstr("cannot open profile"));
    EXPECT_THAT(loaded.error().message, HasSubstr("is a FIFO (named pipe), not a regular file"));
}

TEST(ProfileLoading, WrongTypeNamesPointerExpectationAndFinding) {
    Json document = tc10_document();
    document["parameters"][12]["address"] = "12";
    EXPECT_THAT(load_error(document),
                HasSubstr("broken/tc10.json: /parameters/12/address: must be integer (found string \"12\")"));
}

TEST(ProfileLoading, MissingRequiredFieldIsNamed) {
    Json document = tc10_document();
    document["parameters"][3].erase("source");
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /parameters/3: missing required property \"source\""));
}

TEST(ProfileLoading, MissingTopLevelFieldPointsAtTheRoot) {
    Json document = tc10_document();
    document.erase("limits");
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /: missing required property \"limits\""));
}

TEST(ProfileLoading, BadEnumValueListsTheAllowedValues) {
    Json document = tc10_document();
    document["parameters"][12]["access"] = "x";
    EXPECT_THAT(load_error(document),
                HasSubstr("broken/tc10.json: /parameters/12/access: must be one of r, w, rw (found \"x\")"));
}

TEST(ProfileLoading, OneOfFailureNamesEachAlternative) {
    Json document = tc10_document();
    document["parameters"][0]["decimals"] = 7;
    const std::string message = load_error(document);
    EXPECT_THAT(message, HasSubstr("broken/tc10.json: /parameters/0/decimals: must be integer 0..4, or object with "
                                   "parameter (found number 7)"));
    EXPECT_EQ(message.find('\n'), std::string::npos) << "one problem, one line: " << message;
}

TEST(ProfileLoading, UnknownPropertyIsNamedWithTheAllowedOnes) {
    Json document = tc10_document();
    document["parameters"][2]["decimal"] = 1;
    const std::string message = load_error(document);
    EXPECT_THAT(message, HasSubstr("broken/tc10.json: /parameters/2: unknown property \"decimal\" (allowed: "));
    EXPECT_THAT(message, HasSubstr("decimals"));
}

TEST(ProfileLoading, PatternViolationShowsThePattern) {
    Json document = tc10_document();
    document["parameters"][4]["name"] = "Output Power";
    EXPECT_THAT(load_error(document),
                HasSubstr("/parameters/4/name: must match ^[a-z][a-z0-9_]*$ (found \"Output Power\")"));
}

TEST(ProfileLoading, NumberOutOfRangeShowsTheLimit) {
    Json document = tc10_document();
    document["parameters"][4]["address"] = 70000;
    EXPECT_THAT(load_error(document), HasSubstr("/parameters/4/address: must be at most 65535 (found 70000)"));
}

TEST(ProfileLoading, EveryProblemIsReportedOnItsOwnLine) {
    Json document = tc10_document();
    document["parameters"][1]["access"] = "x";
    document["parameters"][2]["type"] = "float";
    const std::string message = load_error(document);
    EXPECT_THAT(message, HasSubstr("broken/tc10.json: /parameters/1/access: must be one of r, w, rw"));
    EXPECT_THAT(message, HasSubstr("\nbroken/tc10.json: /parameters/2/type: must be one of int16, uint16, enum, "
                                   "bitfield, bool (found \"float\")"));
}

TEST(ProfileLoading, DuplicateNameIsRefused) {
    Json document = tc10_document();
    const std::string taken = document["parameters"][4]["name"];
    document["parameters"][5]["name"] = taken;
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /parameters/5/name: duplicate name \"" + taken +
                                                "\" (also /parameters/4)"));
}

// "all" reads every readable parameter (loopwire read ... all): a mnemonic so called would be read
// alone instead.
TEST(ProfileLoading, AllIsReservedForNamesMnemonicsAndGroups) {
    Json document = tc10_document();
    document["parameters"][3]["mnemonic"] = "ALL";
    document["parameters"][4]["name"] = "all";
    const std::string message = load_error(document);
    EXPECT_THAT(message, HasSubstr("broken/tc10.json: /parameters/3/mnemonic: \"ALL\" is reserved: `loopwire read ... all`"));
    EXPECT_THAT(message, HasSubstr("broken/tc10.json: /parameters/4/name: \"all\" is reserved"));
}

TEST(ProfileLoading, DuplicateAddressWithoutNotesIsRefused) {
    Json document = tc10_document();
    document["parameters"][5]["address"] = document["parameters"][4]["address"];
    document["parameters"][4].erase("note");
    document["parameters"][5]["note"] = "printed twice";
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /parameters/5/address: holding 5 is also the "
                                                "address of /parameters/4 (active_set_point_var)"));
}

TEST(ProfileLoading, DuplicateAddressNotedOnBothEntriesIsAccepted) {
    Json document = tc10_document();
    document["parameters"][5]["address"] = document["parameters"][4]["address"];
    document["parameters"][4]["note"] = "Manual prints this word twice (test).";
    document["parameters"][5]["note"] = "Manual prints this word twice (test).";
    const auto loaded = load_profile_text(document.dump(), origin);
    EXPECT_TRUE(loaded.ok()) << loaded.error().message;
}

TEST(ProfileLoading, DanglingDecimalsReferenceIsRefused) {
    Json document = tc10_document();
    document["parameters"][0]["decimals"] = Json{{"parameter", "no_such_parameter"}};
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /parameters/0/decimals/parameter: no parameter "
                                                "named \"no_such_parameter\""));
}

TEST(ProfileLoading, DanglingRangeIdentificationAndSelectorReferencesAreRefused) {
    Json document = read_json(profile_path("ac20"));
    document["parameters"][0]["range"]["max"] = Json{{"parameter", "set_point_top"}};
    document["identification"]["match"][0]["parameter"] = "trade_mark";
    document["addressing"]["alternatives"][0]["selected_by"]["parameter"] = "protocol";
    const std::string message = load_error(document);
    EXPECT_THAT(message, HasSubstr("/parameters/0/range/max/parameter: no parameter named \"set_point_top\""));
    EXPECT_THAT(message, HasSubstr("/identification/match/0/parameter: no parameter named \"trade_mark\""));
    EXPECT_THAT(message, HasSubstr("/addressing/alternatives/0/selected_by/parameter: no parameter named \"protocol\""));
}

TEST(ProfileLoading, AnAliasMustNameAParameterAndBeAWord) {
    Json document = tc10_document();
    document["aliases"]["PV"] = "process_variable";
    EXPECT_THAT(load_error(document), HasSubstr("broken/tc10.json: /aliases/PV: no parameter named \"process_variable\""));
    Json spaced = tc10_document();
    spaced["aliases"]["the pv"] = "measured_value";
    EXPECT_THAT(load_error(spaced), HasSubstr("broken/tc10.json: /aliases/the pv: an alias is one word as people type it"));
}

TEST(ProfileLoading, SelfReferenceIsRefused) {
    Json document = tc10_document();
    document["parameters"][0]["decimals"] = Json{{"parameter", document["parameters"][0]["name"]}};
    EXPECT_THAT(load_error(document), HasSubstr("/parameters/0/decimals/parameter: \"measured_value\" refers to itself"));
}

TEST(ProfileLoading, UnknownWriteModeIsRefused) {
    Json document = tc10_document();
    document["parameters"][3]["write_modes"] = Json::array({"manual"});
    EXPECT_THAT(load_error(document), HasSubstr("/parameters/3/write_modes/0: no mode named \"manual\" in /modes"));
}

TEST(ProfileLoading, BoolWordIsRefused) {
    Json document = tc10_document();
    document["parameters"][3]["type"] = "bool";
    EXPECT_THAT(load_error(document), HasSubstr("/parameters/3/type: bool entries belong in coils or discrete, not holding"));
}

TEST(ProfileLoading, UnparsableJsonNamesLineAndColumn) {
    const std::string text = "{\n  \"id\": \"x\",\n  \"title\" \"y\"\n}\n";
    const std::string message = load_error_of_text(text);
    EXPECT_THAT(message, HasSubstr("broken.json: line 3, column"));
    EXPECT_THAT(message, HasSubstr("not valid JSON"));
}

TEST(ProfileLoading, UnparsableRealProfileNamesTheLine) {
    std::string text;
    ASSERT_TRUE(testing::read_text(profile_path("rampsoak"), text));
    // Drop the comma after the "title" member: the next line is where the parser stops.
    const auto title = text.find("\"title\"");
    const auto comma = text.find(",\n", title);
    ASSERT_NE(comma, std::string::npos);
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(comma), '\n') + 1;
    text.erase(comma, 1);
    EXPECT_THAT(load_error_of_text(text), HasSubstr("broken.json: line " + std::to_string(line) + ", column"));
}

TEST(ProfileLoading, DuplicateKeyIsRefusedWithItsPointer) {
    std::string text = tc10_document().dump(1);
    const std::string marker = "\"name\": \"output_power\",";
    const auto at = text.find(marker);
    ASSERT_NE(at, std::string::npos);
    text.insert(at, "\"note\": \"one\", \"note\": \"two\", ");
    const std::string message = load_error_of_text(text);
    EXPECT_THAT(message, HasSubstr("broken.json: /parameters/3: duplicate key \"note\""));
}

TEST(ProfileLoading, ValidProfileGivesNoSpuriousProblems) {
    const auto loaded = load_profile_text(tc10_document().dump(), origin);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    EXPECT_THAT(loaded->title, Not(HasSubstr("broken")));
}

}  // namespace
}  // namespace loopwire::device
