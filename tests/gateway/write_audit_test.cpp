// The audit of writes (gateway/write_audit.hpp): its log line, the words for a raw Modbus
// write and its reply, GET /api/audit's query and texts, the history file's `writes` table,
// and the Modbus TCP front's record of a write it refuses before the line.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "gateway/forwarding_unit.hpp"
#include "gateway/history_query.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"
#include "gateway/http_text.hpp"
#include "gateway/write_audit.hpp"
#include "support/history_test_support.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using std::chrono::system_clock;

AuditRecord set_point_write() {
    AuditRecord record;
    record.time = system_clock::time_point(1'796'680'000'000ms);
    record.origin = {"http", "127.0.0.1", ""};
    record.device = "oven";
    record.parameter = "set_point";
    record.old_value = "150.0 °C";
    record.new_value = "160.0 °C";
    record.outcome = std::string(audit_confirmed);
    return record;
}

TEST(WriteAudit, LogLineSaysWhoWhatAndHowItEnded) {
    EXPECT_EQ(audit_line(set_point_write()), "audit: http 127.0.0.1: oven.set_point 150.0 °C → 160.0 °C: confirmed");
    AuditRecord unknown = set_point_write();
    unknown.old_value.clear();
    unknown.origin = {"mqtt", "broker", "anna"};
    unknown.outcome = audit_refused("busy");
    EXPECT_EQ(audit_line(unknown), "audit: mqtt broker (anna): oven.set_point ? → 160.0 °C: refused: busy");
    AuditRecord without_peer = set_point_write();
    without_peer.origin.peer.clear();
    EXPECT_EQ(audit_line(without_peer), "audit: http: oven.set_point 150.0 °C → 160.0 °C: confirmed");
}

TEST(WriteAudit, LogLineOfARawWriteNamesItsRegisters) {
    AuditRecord raw;
    raw.origin = {"modbus_tcp", "127.0.0.1:50312", ""};
    raw.device = "oven";
    raw.parameter = "function 16 address 717 count 2";
    raw.new_value = "1600 20";
    raw.outcome = "refused: exception 02h";
    EXPECT_EQ(audit_line(raw), "audit: modbus_tcp 127.0.0.1:50312: oven function 16 address 717 count 2 values 1600 20: "
                               "refused: exception 02h");
}

TEST(WriteAudit, APeersBytesNeverBreakTheLogLineNorReachItRaw) {
    AuditRecord record = set_point_write();
    record.parameter = "set_p\xffoint";
    record.new_value = "1\n2 °C";
    EXPECT_EQ(audit_line(record), "audit: http 127.0.0.1: oven.set_p\\xffoint 150.0 °C → 1\\x0a2 °C: confirmed");
    record.new_value = std::string(300, '7');
    EXPECT_EQ(audit_line(record), "audit: http 127.0.0.1: oven.set_p\\xffoint 150.0 °C → " + std::string(256, '7') +
                                      "\u2026 (300 bytes): confirmed");
}

TEST(WriteAudit, RawWritesInWords) {
    const auto described = [](Bytes pdu) {
        auto text = describe_raw_write(pdu);
        return text.what + ": " + text.values;
    };
    EXPECT_EQ(described({0x05, 0x00, 0x10, 0xFF, 0x00}), "function 5 address 16 count 1: 1");
    EXPECT_EQ(described({0x05, 0x00, 0x10, 0x00, 0x00}), "function 5 address 16 count 1: 0");
    EXPECT_EQ(described({0x06, 0x02, 0xCD, 0x06, 0x40}), "function 6 address 717 count 1: 1600");
    // 6.11: ten coils from 19, 0xCD 0x01 = 1011 0011 10 lowest first.
    EXPECT_EQ(described({0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01}), "function 15 address 19 count 10: 1 0 1 1 0 0 1 1 1 0");
    EXPECT_EQ(described({0x10, 0x02, 0xCD, 0x00, 0x02, 0x04, 0x06, 0x40, 0x00, 0x14}), "function 16 address 717 count 2: 1600 20");
    EXPECT_EQ(described({0x16, 0x00, 0x04, 0x00, 0xF2, 0x00, 0x25}), "function 22 address 4 count 1: and 00F2h or 0025h");
    // 6.17: read 6 from 3, write 3 from 14.
    EXPECT_EQ(described({0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x03, 0x06, 0x00, 0xFF, 0x00, 0xFF, 0x00, 0xFF}),
              "function 23 address 14 count 3: 255 255 255");
    EXPECT_EQ(described({0x06, 0x02}), "function 6: 02");
    EXPECT_EQ(described({0x41, 0x01, 0x02}), "function 65: 01 02");
}

TEST(WriteAudit, RawRepliesOutcome) {
    EXPECT_EQ(raw_reply_outcome(Bytes{0x06, 0x02, 0xCD, 0x06, 0x40}), "confirmed");
    EXPECT_EQ(raw_reply_outcome(Bytes{0x86, 0x03}), "refused: exception 03h");
    EXPECT_EQ(raw_reply_outcome(Bytes{0x90, 0x0B}), "refused: exception 0Bh");
}

TEST(WriteAudit, QueryDefaultsAndRefusals) {
    const auto now = system_clock::time_point(1'796'680'000'000ms);
    auto defaults = audit_query("", now);
    ASSERT_TRUE(defaults) << defaults.error().message;
    EXPECT_EQ(defaults->to, now);
    EXPECT_EQ(defaults->from, now - 24h);
    EXPECT_EQ(defaults->limit, 1000u);
    EXPECT_TRUE(defaults->device.empty());
    auto asked = audit_query("from=-1h&device=oven&limit=5", now);
    ASSERT_TRUE(asked) << asked.error().message;
    EXPECT_EQ(asked->from, now - 1h);
    EXPECT_EQ(asked->device, "oven");
    EXPECT_EQ(asked->limit, 5u);
    EXPECT_FALSE(audit_query("limit=0", now));
    EXPECT_FALSE(audit_query("limit=100001", now));
    EXPECT_FALSE(audit_query("from=yesterday", now));
    EXPECT_FALSE(audit_query("from=now&to=-1h", now));
    auto unknown = audit_query("points=5", now);
    ASSERT_FALSE(unknown);
    EXPECT_NE(unknown.error().message.find("allowed: from, to, device, limit"), std::string::npos);
}

TEST(WriteAudit, JsonAndCsv) {
    const auto json = nlohmann::json::parse(audit_json({set_point_write()}));
    ASSERT_EQ(json["records"].size(), 1u);
    EXPECT_EQ(json["records"][0]["time"], "2026-12-07T21:46:40.000Z");
    EXPECT_EQ(json["records"][0]["front"], "http");
    EXPECT_EQ(json["records"][0]["new_value"], "160.0 °C");
    EXPECT_EQ(json["records"][0]["outcome"], "confirmed");
    AuditRecord refused = set_point_write();
    refused.outcome = "refused: set_point 99999, above 9999";
    EXPECT_EQ(audit_csv({refused}),
              "time,front,peer,user,device,parameter,old_value,new_value,outcome\r\n"
              "2026-12-07T21:46:40.000Z,http,127.0.0.1,,oven,set_point,150.0 °C,160.0 °C,\"refused: set_point 99999, above 9999\"\r\n");
}

TEST(WriteAudit, StoredInTheHistoryFileAndReadBackNewestFirst) {
    testing::TempFolder folder;
    HistoryOptions options;
    options.database = folder.path / "plant.db";
    auto store = HistoryStore::open(options);
    ASSERT_TRUE(store) << store.error().message;
    WriteAudit audit({}, [] { return system_clock::time_point(1'796'680'000'000ms); });
    audit.attach(store->get());
    audit.record(set_point_write());
    AuditRecord second = set_point_write();
    second.time = system_clock::time_point(1'796'680'001'000ms);
    second.device = "furnace";
    audit.record(second);
    AuditRecord unstamped = set_point_write();
    unstamped.time = {};
    unstamped.origin = {"sparkplug", "broker", ""};
    audit.record(unstamped);  // stamped by the audit's clock
    audit.attach(nullptr);
    audit.record(set_point_write());  // the log's alone now
    ASSERT_TRUE((*store)->write_pending());

    auto db = history::open_for_reading(options.database);
    ASSERT_TRUE(db) << db.error().message;
    AuditQuery query{system_clock::time_point(1'796'679'000'000ms), system_clock::time_point(1'796'690'000'000ms), "", 10};
    auto records = history::run_audit_query(*db, query);
    ASSERT_TRUE(records) << records.error().message;
    ASSERT_EQ(records->size(), 3u);
    EXPECT_EQ((*records)[0].device, "furnace");
    EXPECT_EQ((*records)[1].origin.front, "sparkplug");  // the same time as the first: the later one first
    EXPECT_EQ((*records)[2].origin.front, "http");
    EXPECT_EQ((*records)[2].old_value, "150.0 °C");
    EXPECT_EQ((*records)[2].outcome, "confirmed");
    query.device = "oven";
    query.limit = 1;
    records = history::run_audit_query(*db, query);
    ASSERT_TRUE(records);
    ASSERT_EQ(records->size(), 1u);
    EXPECT_EQ((*records)[0].origin.front, "sparkplug");
}

TEST(WriteAudit, ModbusWriteRefusedByTheFrontIsRecordedOnce) {
    std::vector<std::string> lines;
    auto audit = std::make_shared<WriteAudit>([&lines](const std::string& line) { lines.push_back(line); });
    ForwardingSettings settings;
    settings.line_unit = 3;
    settings.writes_allowed = false;
    settings.audit = audit;
    settings.device = "oven";
    // No line: the refusal comes before one would be asked.
    ForwardingUnit unit(nullptr, settings, steady_clock());
    std::optional<Bytes> replied;
    const session::UnitHandler::Asker asker(1, {}, true, std::make_shared<const std::string>("127.0.0.1:50312"));
    unit.handle_async(Bytes{0x06, 0x02, 0xCD, 0x06, 0x40}, false, asker, [&](std::optional<Bytes> reply) { replied = reply; });
    ASSERT_TRUE(replied);
    EXPECT_EQ(*replied, (Bytes{0x86, 0x01}));
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_EQ(lines[0], "notice: audit: modbus_tcp 127.0.0.1:50312: oven function 6 address 717 count 1 values 1600: refused: this "
                        "gateway is read-only (modbus_tcp.writes = false)");
}

}  // namespace
}  // namespace loopwire::gateway
