// The profile registry: the built-ins plus files named on the command line and found in the
// user's profile folder, each known by its id; bad files and clashing ids say which file.
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/profile_registry.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing::profile_path;
using testing::read_json;

// A scratch folder removed when the test ends.
class ScratchFolder {
public:
    ScratchFolder() {
        std::string pattern = (fs::temp_directory_path() / "profile-registry-XXXXXX").string();
        if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("cannot make a scratch folder");
        path_ = pattern;
    }
    ~ScratchFolder() {
        std::error_code ignored;
        fs::permissions(path_, fs::perms::owner_all, fs::perm_options::add, ignored);
        fs::remove_all(path_, ignored);
    }
    ScratchFolder(const ScratchFolder&) = delete;
    ScratchFolder& operator=(const ScratchFolder&) = delete;

    // Writes `text` to NAME in the folder and returns its path.
    std::string write(const std::string& name, const std::string& text) const {
        const fs::path file = path_ / name;
        std::ofstream(file, std::ios::binary) << text;
        return file.string();
    }
    std::string path() const { return path_.string(); }

private:
    fs::path path_;
};

// profiles/tc10.json under another id: a profile with no device model of its own.
std::string tc10_as(const std::string& id) {
    auto document = read_json(profile_path("tc10"));
    document["id"] = id;
    return document.dump(2);
}

ProfileRegistry build_ok(const ProfileSources& sources, std::vector<std::string>& warnings) {
    auto registry = ProfileRegistry::build(sources, warnings);
    if (!registry) throw std::runtime_error("registry not built: " + registry.error().message);
    return std::move(registry).value();
}

TEST(ProfileRegistry, BuiltinsAreKnownWithTheirOrigin) {
    const auto registry = ProfileRegistry::builtins();
    ASSERT_TRUE(registry.ok()) << registry.error().message;
    EXPECT_THAT(registry->ids(), ElementsAre("ac20", "rampsoak", "tc10"));
    for (const auto& entry : registry->profiles()) EXPECT_EQ(entry.origin, builtin_origin);
    const auto tc10 = registry->find("tc10");
    ASSERT_TRUE(tc10.ok());
    EXPECT_EQ(tc10->get(), builtin_profile("tc10")->get()) << "the built-in is shared, not loaded again";
}

TEST(ProfileRegistry, AFileNamedOnTheCommandLineIsKnownByItsId) {
    ScratchFolder scratch;
    const std::string file = scratch.write("my-oven.json", tc10_as("oven-x"));
    std::vector<std::string> warnings;
    const auto registry = build_ok({{file}, std::nullopt}, warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_THAT(registry.ids(), ElementsAre("ac20", "oven-x", "rampsoak", "tc10"));
    const auto oven = registry.find("oven-x");
    ASSERT_TRUE(oven.ok()) << oven.error().message;
    EXPECT_EQ((*oven)->id, "oven-x");
    EXPECT_NE((*oven)->find("set_point"), nullptr);
    EXPECT_EQ(registry.profiles()[1].origin, file);
}

TEST(ProfileRegistry, EveryJsonFileOfTheFolderIsLoadedAndOthersAreIgnored) {
    ScratchFolder scratch;
    const std::string first = scratch.write("a.json", tc10_as("oven-a"));
    scratch.write("b.json", tc10_as("oven-b"));
    scratch.write("notes.txt", "not a profile");
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, scratch.path()}, warnings);
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    EXPECT_THAT(registry.ids(), ElementsAre("ac20", "oven-a", "oven-b", "rampsoak", "tc10"));
    EXPECT_EQ(registry.profiles()[1].origin, first);
}

TEST(ProfileRegistry, AnInvalidCommandLineFileIsAnErrorNamingIt) {
    ScratchFolder scratch;
    auto document = read_json(profile_path("tc10"));
    document["id"] = "oven-x";
    document["parameters"][0]["access"] = "sometimes";
    const std::string file = scratch.write("broken.json", document.dump());
    std::vector<std::string> warnings;
    const auto registry = ProfileRegistry::build({{file}, std::nullopt}, warnings);
    ASSERT_FALSE(registry.ok());
    EXPECT_EQ(registry.error().kind, ErrorKind::usage);
    EXPECT_THAT(registry.error().message, HasSubstr(file));
    EXPECT_THAT(registry.error().message, HasSubstr("/parameters/0/access"));
}

TEST(ProfileRegistry, AMissingCommandLineFileIsAnError) {
    std::vector<std::string> warnings;
    const auto registry = ProfileRegistry::build({{"/nonexistent/oven.json"}, std::nullopt}, warnings);
    ASSERT_FALSE(registry.ok());
    EXPECT_THAT(registry.error().message, HasSubstr("/nonexistent/oven.json: cannot open profile"));
}

TEST(ProfileRegistry, AnInvalidFolderFileIsAWarningAndTheOthersStillLoad) {
    ScratchFolder scratch;
    scratch.write("good.json", tc10_as("oven-good"));
    auto document = read_json(profile_path("tc10"));
    document["id"] = "oven-bad";
    document.erase("parameters");
    const std::string bad = scratch.write("bad.json", document.dump());
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, scratch.path()}, warnings);
    ASSERT_EQ(warnings.size(), 1U);
    EXPECT_THAT(warnings[0], HasSubstr(bad));
    EXPECT_TRUE(registry.find("oven-good").ok());

    // Asking for the id only the bad file would have provided points at that file.
    const auto missing = registry.find("oven-bad");
    ASSERT_FALSE(missing.ok());
    EXPECT_THAT(missing.error().message, HasSubstr("unknown device \"oven-bad\""));
    EXPECT_THAT(missing.error().message, HasSubstr("the file " + bad + " that may define it is invalid"));
    // Other unknown ids do not mention it.
    const auto other = registry.find("oven-zzz");
    ASSERT_FALSE(other.ok());
    EXPECT_THAT(other.error().message, ::testing::Not(HasSubstr(bad)));
}

TEST(ProfileRegistry, AFolderFileThatIsNotJsonIsTiedToItsFileName) {
    ScratchFolder scratch;
    const std::string bad = scratch.write("oven-y.json", "{ this is not json");
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, scratch.path()}, warnings);
    ASSERT_EQ(warnings.size(), 1U);
    EXPECT_THAT(registry.find("oven-y").error().message, HasSubstr("the file " + bad + " that may define it is invalid"));
}

TEST(ProfileRegistry, TwoFilesWithOneIdAreAnErrorNamingBoth) {
    ScratchFolder scratch;
    const std::string first = scratch.write("one.json", tc10_as("oven-x"));
    const std::string second = scratch.write("two.json", tc10_as("oven-x"));
    std::vector<std::string> warnings;
    const auto registry = ProfileRegistry::build({{first, second}, std::nullopt}, warnings);
    ASSERT_FALSE(registry.ok());
    EXPECT_THAT(registry.error().message, HasSubstr("\"oven-x\" is defined twice, by " + first + " and by " + second));

    // The same between a command-line file and a folder file.
    ScratchFolder folder;
    folder.write("three.json", tc10_as("oven-x"));
    const auto mixed = ProfileRegistry::build({{first}, folder.path()}, warnings);
    ASSERT_FALSE(mixed.ok());
    EXPECT_THAT(mixed.error().message, HasSubstr(first));
    EXPECT_THAT(mixed.error().message, HasSubstr((fs::path(folder.path()) / "three.json").string()));
}

TEST(ProfileRegistry, AFileNeverReplacesABuiltin) {
    ScratchFolder scratch;
    const std::string copy = scratch.write("tc10.json", read_json(profile_path("tc10")).dump());
    std::vector<std::string> warnings;
    for (const ProfileSources& sources : {ProfileSources{{copy}, std::nullopt}, ProfileSources{{}, scratch.path()}}) {
        const auto registry = ProfileRegistry::build(sources, warnings);
        ASSERT_FALSE(registry.ok());
        EXPECT_THAT(registry.error().message, HasSubstr("\"tc10\" is defined twice, by the built-in profile and by " + copy));
        EXPECT_THAT(registry.error().message, HasSubstr("give one of them another \"id\""));
    }
}

TEST(ProfileRegistry, AnAbsentFolderIsNoProfilesAndNoWarning) {
    ScratchFolder scratch;
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, scratch.path() + "/loopwire/profiles"}, warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(registry.ids().size(), 3U);
}

TEST(ProfileRegistry, AFolderThatCannotBeReadIsAWarning) {
    ScratchFolder scratch;
    // A file where the folder should be fails for everyone, root included.
    const std::string not_a_folder = scratch.write("profiles", "");
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, not_a_folder}, warnings);
    ASSERT_EQ(warnings.size(), 1U);
    EXPECT_THAT(warnings[0], HasSubstr("cannot read the profile folder " + not_a_folder));
    EXPECT_EQ(registry.ids().size(), 3U);
}

TEST(ProfileRegistry, AFolderWithoutPermissionIsAWarning) {
    if (::geteuid() == 0) GTEST_SKIP() << "root reads folders whatever their permissions";
    ScratchFolder scratch;
    const std::string folder = scratch.path() + "/locked";
    fs::create_directory(folder);
    fs::permissions(folder, fs::perms::none);
    std::vector<std::string> warnings;
    const auto registry = build_ok({{}, folder}, warnings);
    fs::permissions(folder, fs::perms::owner_all);
    ASSERT_EQ(warnings.size(), 1U);
    EXPECT_THAT(warnings[0], HasSubstr("cannot read the profile folder " + folder));
}

TEST(ProfileRegistry, TheUserFolderFollowsXdgConfigHomeThenHome) {
    EXPECT_EQ(user_profile_folder("/cfg", "/home/u"), std::optional<std::string>("/cfg/loopwire/profiles"));
    EXPECT_EQ(user_profile_folder("", "/home/u"), std::optional<std::string>("/home/u/.config/loopwire/profiles"));
    EXPECT_EQ(user_profile_folder(nullptr, "/home/u"), std::optional<std::string>("/home/u/.config/loopwire/profiles"));
    EXPECT_EQ(user_profile_folder(nullptr, nullptr), std::nullopt);
}

}  // namespace
}  // namespace loopwire::device
