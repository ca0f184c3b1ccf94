// The `loopwire dump` document (format in app/dump_document.hpp) and its atomic file write.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/atomic_file.hpp"
#include "client/dump_document.hpp"
#include "read_report_of.hpp"

namespace loopwire::app {
namespace {

device::DeviceAddress tc10_at(int unit) { return *device::parse_device_address("tc10@" + std::to_string(unit)); }

using testing::report_of;

TEST(DumpDocument, SelfDescribingHeaderAndOneEntryPerParameter) {
    const auto device = tc10_at(3);
    const auto report = report_of(*device.profile, {{"output_power", 1250}, {"instrument_id", 20}, {"parameter_table_id", 7}});
    auto document = device::dump_document(device, device::DumpHeader{"rtu:/dev/ttyS0", "2026-11-23T09:31:02.123Z", {}}, report);
    ASSERT_TRUE(document);
    const auto& d = *document;
    EXPECT_EQ(d["format"], "loopwire-dump");
    EXPECT_EQ(d["version"], 1);
    EXPECT_EQ(d["profile"], "tc10");
    EXPECT_EQ(d["unit"], 3);
    EXPECT_EQ(d["link"], "rtu:/dev/ttyS0");
    EXPECT_EQ(d["time"], "2026-11-23T09:31:02.123Z");
    EXPECT_FALSE(d.contains("numbering"));
    // TC10 identification report: parameter_table_id and instrument_id, as raw words.
    EXPECT_EQ(d["identification"], (nlohmann::ordered_json{{"parameter_table_id", 7}, {"instrument_id", 20}}));
    const auto& power = d["parameters"]["output_power"];
    EXPECT_EQ(power["value"], 12.5);
    EXPECT_EQ(power["text"], "12.50");  // with the parameter's decimals, as `write` takes it back
    EXPECT_EQ(power["unit"], "%");
    EXPECT_EQ(power["raw"], nlohmann::ordered_json::array({1250}));
    EXPECT_EQ(power["status"], "ok");
    EXPECT_EQ(power["writable"], true);
    EXPECT_EQ(d["parameters"]["instrument_id"]["writable"], false);
}

TEST(DumpDocument, TextOfEveryEntryIsAcceptedBackByTheEncoder) {
    const auto device = tc10_at(3);
    const auto report = report_of(*device.profile, {{"output_power", 0xFF38}, {"alarm_status", 0b101}});
    auto document = device::dump_document(device, device::DumpHeader{"l", "t", {}}, report);
    ASSERT_TRUE(document);
    const auto* power = device.profile->find("output_power");
    auto raw = device::encode_value(*power, (*document)["parameters"]["output_power"]["text"].get<std::string>(), report.raw);
    ASSERT_TRUE(raw) << raw.error().message;
    EXPECT_EQ(*raw, 0xFF38);  // -2.00 %
}

// A parameter the device refused stays in the document, unread, with the refusal: restore
// finds no raw word to write for it.
TEST(DumpDocument, AnUnreadParameterIsKeptWithTheReason) {
    const auto device = tc10_at(3);
    auto report = report_of(*device.profile, {{"output_power", 1}});
    report.readings.push_back(device::ParameterReading{device.profile->find("alarm_status"), std::nullopt, "exception 2 (illegal data address)"});
    auto document = device::dump_document(device, device::DumpHeader{"l", "t", {}}, report);
    ASSERT_TRUE(document);
    const auto& unread = (*document)["parameters"]["alarm_status"];
    EXPECT_TRUE(unread["value"].is_null());
    EXPECT_TRUE(unread["text"].is_null());
    EXPECT_TRUE(unread["raw"].empty());
    EXPECT_EQ(unread["status"], "unread");
    EXPECT_EQ(unread["error"], "exception 2 (illegal data address)");
    EXPECT_EQ((*document)["parameters"]["output_power"]["status"], "ok");
}

TEST(DumpDocument, DumpsEveryReadableParameterHiddenOnesIncluded) {
    const auto profile = *device::builtin_profile("tc10");
    const auto list = device::dumped_parameters(*profile);
    std::size_t readable = 0;
    for (const auto& p : profile->parameters) readable += p.readable ? 1 : 0;
    EXPECT_EQ(list.size(), readable);
    EXPECT_NE(std::find(list.begin(), list.end(), profile->find("reserved_26")), list.end());
}

class AtomicWrite : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-dump-test-XXXXXX").string();
        ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
        dir = pattern;
    }
    void TearDown() override { std::filesystem::remove_all(dir); }
    std::size_t entries() const {
        return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()));
    }
    static std::string contents(const std::filesystem::path& path) {
        std::ifstream in(path);
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    }
    std::filesystem::path dir;
};

TEST_F(AtomicWrite, ReplacesTheFileWholeAndLeavesNoTemporaryBehind) {
    const auto path = (dir / "unit3.json").string();
    ASSERT_TRUE(write_file_atomically(path, "old\n"));
    ASSERT_TRUE(write_file_atomically(path, "{\"new\":true}\n"));
    EXPECT_EQ(contents(path), "{\"new\":true}\n");
    EXPECT_EQ(entries(), 1u);
}

TEST_F(AtomicWrite, AnUnwritableDestinationFailsWithoutLeavingAFile) {
    const auto path = (dir / "missing-dir" / "unit3.json").string();
    auto written = write_file_atomically(path, "x");
    ASSERT_FALSE(written);
    EXPECT_NE(written.error().message.find(path), std::string::npos);
    EXPECT_EQ(entries(), 0u);
}

TEST_F(AtomicWrite, ARenameOntoADirectoryFailsAndRemovesTheTemporary) {
    const auto path = dir / "taken";
    std::filesystem::create_directory(path);
    std::filesystem::create_directory(path / "inside");  // a non-empty directory cannot be replaced
    ASSERT_FALSE(write_file_atomically(path.string(), "x"));
    EXPECT_EQ(entries(), 1u);  // only the directory
}

}  // namespace
}  // namespace loopwire::app
