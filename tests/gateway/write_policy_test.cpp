// The one write policy every front follows (gateway/device_writer.hpp, silent_device_refusal):
// a write to a device its polls find silent, whose line is down, or that is not the configured
// device is refused before its completion could wait for anything, with the writer's words, on
// the writer itself, MQTT's set/result, HTTP (503 and a JSON error) and the Modbus TCP front
// (exception 0Bh; 0Ah for a line that is down). "At once" is checked as the only thing that
// needs no clock: the answer is there when the call returns, and nothing reached the line.
// Sparkplug's Device Control/Last Error is checked with its broker (sparkplug_node_test.cpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <optional>

#include <nlohmann/json.hpp>

#include "gateway/engine.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/http_api.hpp"
#include "gateway/mqtt_commands.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;

// A line that counts what reaches it and answers each request with a timeout at once.
class CountingLine final : public session::Master {
public:
    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return reached(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(reached()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return reached(); }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override { done(reached()); }
    std::string describe() const override { return "counting line"; }

    int reached_count() const { return reached_.load(); }

private:
    Error reached() {
        ++reached_;
        return make_error(ErrorKind::timeout, "no reply (counting line)");
    }
    std::atomic<int> reached_{0};
};

// The oven as its last poll left it.
device::WatchedDevice polled_as(device::DeviceStatus status, const std::string& why) {
    device::WatchedDevice state = device::watch("tc10@3", {});
    state.status = status;
    state.last_error = why;
    return state;
}

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

constexpr const char* silence = "timeout: no reply within 1 s";

TEST(SilentDeviceRefusal, EachStatusIsRuledOnceAndSaysWhyInTheSameWords) {
    for (const device::DeviceStatus status : device::all_device_statuses) {
        const auto refused = silent_device_refusal("oven", DeviceSeen{status, "why"});
        switch (status) {
            case device::DeviceStatus::no_reply:
                ASSERT_TRUE(refused);
                EXPECT_EQ(refused->kind, ErrorKind::timeout);
                EXPECT_THAT(refused->message, HasSubstr("device \"oven\" does not answer its polls (why); nothing was sent"));
                break;
            case device::DeviceStatus::line_down:
                ASSERT_TRUE(refused);
                EXPECT_EQ(refused->kind, ErrorKind::link);
                EXPECT_THAT(refused->message, HasSubstr("its line is down (why); nothing was sent"));
                break;
            case device::DeviceStatus::wrong_device:
                ASSERT_TRUE(refused);
                EXPECT_EQ(refused->kind, ErrorKind::mismatch);
                EXPECT_THAT(refused->message, HasSubstr("not the configured device (why); nothing was sent"));
                break;
            default: EXPECT_FALSE(refused) << device::status_text(status) << " refuses: " << refused->message;
        }
    }
    EXPECT_FALSE(silent_device_refusal("oven", std::nullopt)) << "a device not polled yet is written to";
    // Without a reason from the polls, the words still say what is wrong.
    EXPECT_THAT(silent_device_refusal("oven", DeviceSeen{device::DeviceStatus::no_reply, ""})->message,
                HasSubstr("its polls time out"));
}

class WritePolicyTest : public ::testing::Test {
protected:
    WritePolicyTest() {
        auto address = device::parse_device_address("tc10@3");
        if (!address) throw std::runtime_error(address.error().message);
        writer_ = std::make_unique<DeviceWriter>(engine_, std::vector<WritableDevice>{{"oven", *address, line_}}, 10s);
        writer_->refuse_silent(cache_.device_lookup());
    }

    void poll(device::DeviceStatus status, const std::string& why = silence) {
        cache_.update("oven", polled_as(status, why), std::chrono::system_clock::now());
    }

    // The expected refusal's words, as the writer gives them.
    std::string refusal_words() const { return writer_->refusal("oven").value().message; }

    std::shared_ptr<CountingLine> master_ = std::make_shared<CountingLine>();
    std::shared_ptr<LineScheduler> line_ = std::make_shared<LineScheduler>(master_);
    ValueCache cache_;
    Engine engine_;  // the writer's loop: goes after it
    std::unique_ptr<DeviceWriter> writer_;
};

TEST_F(WritePolicyTest, TheWriterRefusesASilentDeviceBeforeReturningAndWritesOnceItAnswers) {
    poll(device::DeviceStatus::no_reply);
    std::optional<Result<WrittenValues>> outcome;
    ASSERT_TRUE(writer_->write_async("oven", {{"set_point", "150"}}, [&](Result<WrittenValues> r) { outcome = std::move(r); }));
    ASSERT_TRUE(outcome) << "the refusal waited for something";
    ASSERT_FALSE(*outcome);
    EXPECT_EQ(outcome->error().kind, ErrorKind::timeout);
    EXPECT_THAT(outcome->error().message, HasSubstr("does not answer its polls (" + std::string(silence) + ")"));
    // What is wrong with the write itself is said first, whatever the device's state.
    std::optional<Result<WrittenValues>> unknown;
    ASSERT_TRUE(writer_->write_async("oven", {{"no_such", "1"}}, [&](Result<WrittenValues> r) { unknown = std::move(r); }));
    ASSERT_TRUE(unknown && !*unknown);
    EXPECT_EQ(unknown->error().kind, ErrorKind::usage);

    poll(device::DeviceStatus::line_down, "cannot open /dev/ttyUSB0");
    const auto line_down = writer_->write(std::string("oven"), {{"set_point", "150"}});
    ASSERT_FALSE(line_down);
    EXPECT_EQ(line_down.error().kind, ErrorKind::link);
    EXPECT_EQ(master_->reached_count(), 0) << "a refused write reached the line";

    // Answering again, the device is written to: the write goes to the line (which times out).
    poll(device::DeviceStatus::ok);
    const auto sent = writer_->write(std::string("oven"), {{"set_point", "150"}});
    EXPECT_GT(master_->reached_count(), 0) << "a write to an answering device never reached its line";
    EXPECT_FALSE(sent) << "the counting line answers nothing";
}

TEST_F(WritePolicyTest, MqttAnswersASilentDeviceOnItsResultTopicAtOnceInTheWritersWords) {
    poll(device::DeviceStatus::no_reply);
    MqttConfig config;
    config.prefix = "p";
    config.writes = true;
    std::vector<std::pair<std::string, nlohmann::json>> published;
    MqttCommands commands(config, *writer_,
                          [&](std::string topic, std::string payload) { published.emplace_back(topic, nlohmann::json::parse(payload)); },
                          GatewayLog{});
    commands.take("p/oven/set_point/set", "150");
    ASSERT_EQ(published.size(), 1u) << "the refusal waited for something";
    EXPECT_EQ(published[0].first, "p/oven/set_point/set/result");
    EXPECT_EQ(published[0].second.at("ok"), false);
    EXPECT_EQ(published[0].second.at("error"), refusal_words());
    EXPECT_EQ(commands.under_way(), 0u);
    EXPECT_EQ(master_->reached_count(), 0);
}

TEST_F(WritePolicyTest, HttpAnswersASilentDevice503AtOnceInTheWritersWords) {
    auto config = parse_gateway_config(R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"

[modbus_tcp]
enabled = false
)toml", "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    config->http = HttpConfig{};
    config->http->token = "t";
    HttpApi api(*config, HttpApiSources{&cache_, writer_.get(), {}, {}, nullptr});
    poll(device::DeviceStatus::no_reply);
    HttpRequest request;
    request.method = "POST";
    request.host = "127.0.0.1";
    request.path = "/api/devices/oven/write";
    request.authorization = "Bearer t";
    request.body = R"({"set_point": 150})";
    const HttpOutcome outcome = api.handle(request);
    EXPECT_FALSE(outcome.deferred) << "the refusal waits for the line";
    EXPECT_EQ(outcome.response.status, 503u) << outcome.response.body;
    EXPECT_EQ(nlohmann::json::parse(outcome.response.body).at("error"), refusal_words());
    EXPECT_EQ(master_->reached_count(), 0);
}

TEST_F(WritePolicyTest, TheModbusFrontAnswersAWriteToASilentDevice0BhAtOnceAndStillForwardsReads) {
    ForwardingSettings settings;
    settings.line_unit = 3;
    settings.write_refusal = [lookup = cache_.device_lookup()] { return silent_device_refusal("oven", lookup("oven")); };
    ForwardingUnit unit(line_, settings, steady_clock());
    const auto ask = [&](Bytes pdu, bool broadcast = false) {
        std::optional<std::optional<Bytes>> reply;
        unit.handle_async(std::move(pdu), broadcast, 0, [&](std::optional<Bytes> r) { reply = std::move(r); });
        return reply;
    };
    const Bytes write_set_point{0x06, 0x00, 0x01, 0x00, 0x96};
    poll(device::DeviceStatus::no_reply);
    const auto refused = ask(write_set_point);
    ASSERT_TRUE(refused) << "the refusal waited for the line";
    EXPECT_EQ(*refused, (Bytes{0x86, 0x0B}));
    poll(device::DeviceStatus::line_down);
    EXPECT_EQ(ask(write_set_point), std::optional<std::optional<Bytes>>(Bytes{0x86, 0x0A}));
    EXPECT_EQ(master_->reached_count(), 0) << "a refused write reached the line";

    // A read still goes to the line: the policy is about writes.
    std::promise<std::optional<Bytes>> read;
    unit.handle_async(Bytes{0x03, 0x00, 0x00, 0x00, 0x01}, false, 0, [&](std::optional<Bytes> r) { read.set_value(std::move(r)); });
    ASSERT_EQ(read.get_future().wait_for(30s), std::future_status::ready);
    EXPECT_EQ(master_->reached_count(), 1);
}

}  // namespace
}  // namespace loopwire::gateway
