// The MQTT front's writes without a broker (gateway/mqtt_commands.hpp): which topics are
// commands, and the bounds that keep a flood of commands from growing memory: the payload limit
// and the number of writes under way, over a line the test answers by hand.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "gateway/engine.hpp"
#include "gateway/mqtt_commands.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
constexpr auto deadline = 30s;

TEST(CommandTopic, OnlyPrefixDeviceParameterSetIsACommand) {
    const auto command = command_topic("loopwire/plant1", "loopwire/plant1/oven/set_point/set");
    ASSERT_TRUE(command);
    EXPECT_EQ(command->device, "oven");
    EXPECT_EQ(command->parameter, "set_point");
    for (const char* topic : {"loopwire/plant1/oven/set", "loopwire/plant1/oven/set_point/set/result", "loopwire/plant1x/oven/sp/set",
                              "loopwire/plant1//sp/set", "loopwire/plant1/oven//set", "loopwire/plant1/a/b/c/set", "loopwire/plant1",
                              "other/oven/sp/set", ""}) {
        EXPECT_FALSE(command_topic("loopwire/plant1", topic)) << topic;
    }
}

// A line whose requests wait until the test answers them, each with a timeout.
class HeldLine final : public session::Master {
public:
    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return failed(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(failed()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return failed(); }
    std::string describe() const override { return "held line"; }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override {
        std::lock_guard lock(mutex_);
        held_.push_back(std::move(done));
        ++sent_;
        arrived_.notify_all();
    }

    // Answers what is on the line until `finished` holds (or the deadline passes).
    bool answer_until(const std::function<bool()>& finished) {
        const auto give_up = std::chrono::steady_clock::now() + deadline;
        while (!finished()) {
            std::vector<ForwardCompletion> held;
            {
                std::unique_lock lock(mutex_);
                if (!arrived_.wait_until(lock, std::min(give_up, std::chrono::steady_clock::now() + 20ms),
                                         [this] { return !held_.empty(); })) {
                    if (std::chrono::steady_clock::now() > give_up) return false;
                    continue;
                }
                held.swap(held_);
            }
            for (auto& done : held) done(make_error(ErrorKind::timeout, "no reply (held line)"));
        }
        return true;
    }
    int sent() {
        std::lock_guard lock(mutex_);
        return sent_;
    }

private:
    static Error failed() { return make_error(ErrorKind::link, "only forwards"); }
    std::mutex mutex_;
    std::condition_variable arrived_;
    std::vector<ForwardCompletion> held_;
    int sent_ = 0;
};

struct Answers {
    std::mutex mutex;
    std::vector<std::pair<std::string, nlohmann::json>> published;
    std::vector<std::string> logged;
    std::size_t count() {
        std::lock_guard lock(mutex);
        return published.size();
    }
};

class MqttCommandsTest : public ::testing::Test {
protected:
    MqttCommandsTest() {
        auto address = device::parse_device_address("tc10@3");
        if (!address) throw std::runtime_error(address.error().message);
        writer_ = std::make_unique<DeviceWriter>(engine_, std::vector<WritableDevice>{{"oven", *address, line_}}, 10s);
        config_.prefix = "p";
        config_.writes = true;
        config_.max_payload = 16;
    }
    ~MqttCommandsTest() override {
        // Whatever a failed test left on the line is answered, so closing does not wait forever.
        if (commands_) (void)master_->answer_until([this] { return commands_->under_way() == 0; });
        commands_.reset();
    }

    void open(std::size_t max_commands) {
        commands_ = std::make_unique<MqttCommands>(
            config_, *writer_,
            [this](std::string topic, std::string payload) {
                std::lock_guard lock(answers_.mutex);
                answers_.published.emplace_back(std::move(topic), nlohmann::json::parse(payload));
            },
            [this](const std::string& line) {
                std::lock_guard lock(answers_.mutex);
                answers_.logged.push_back(line);
            },
            max_commands);
    }

    std::shared_ptr<HeldLine> master_ = std::make_shared<HeldLine>();
    std::shared_ptr<LineScheduler> line_ = std::make_shared<LineScheduler>(master_);
    Engine engine_;  // the writer's loop: goes after it
    std::unique_ptr<DeviceWriter> writer_;
    MqttConfig config_;
    Answers answers_;
    std::unique_ptr<MqttCommands> commands_;
};

TEST_F(MqttCommandsTest, BeyondTheWritesUnderWayCommandsAreRefusedBusyAtOnce) {
    open(3);
    for (int i = 0; i < 5; ++i) commands_->take("p/oven/set_point/set", std::to_string(100 + i));
    // Two answered at once, without reaching the line; three wait for it.
    EXPECT_EQ(commands_->under_way(), 3u);
    ASSERT_EQ(answers_.count(), 2u);
    for (const auto& [topic, result] : answers_.published) {
        EXPECT_EQ(topic, "p/oven/set_point/set/result");
        EXPECT_EQ(result.at("ok"), false);
        EXPECT_THAT(result.at("error").get<std::string>(), HasSubstr("busy: 3 writes are already waiting"));
    }
    ASSERT_TRUE(master_->answer_until([&] { return commands_->under_way() == 0; })) << "the writes never finished";
    EXPECT_EQ(answers_.count(), 5u);
    // Room again.
    commands_->take("p/oven/set_point/set", "150");
    EXPECT_EQ(commands_->under_way(), 1u);
    ASSERT_TRUE(master_->answer_until([&] { return commands_->under_way() == 0; }));
    EXPECT_EQ(answers_.count(), 6u);
}

TEST_F(MqttCommandsTest, AnOversizedPayloadIsRefusedUnreadAndLoggedCut) {
    open(3);
    commands_->take("p/oven/set_point/set", std::string(100000, '\x01'));
    EXPECT_EQ(commands_->under_way(), 0u);
    EXPECT_EQ(master_->sent(), 0);
    ASSERT_EQ(answers_.count(), 1u);
    EXPECT_THAT(answers_.published[0].second.at("error").get<std::string>(),
                HasSubstr("100000 bytes long; at most 16 are taken ([mqtt] max_payload)"));
    ASSERT_EQ(answers_.logged.size(), 1u);
    EXPECT_THAT(answers_.logged[0], HasSubstr("\"oven\".\"set_point\" = \"\\x01\\x01"));
    EXPECT_THAT(answers_.logged[0], HasSubstr("\u2026 (100000 bytes) refused"));
    EXPECT_LT(answers_.logged[0].size(), 500u);
}

TEST_F(MqttCommandsTest, WritesOffAndUnknownNamesAreAnsweredWithoutTheLine) {
    config_.writes = false;
    open(3);
    commands_->take("p/oven/set_point/set", "150");
    config_.writes = true;
    open(3);
    commands_->take("p/kiln/set_point/set", "150");
    commands_->take("p/oven/no_such/set", "150");
    commands_->take("p/oven/set_point/set/result", "{}");  // not a command: no answer
    EXPECT_EQ(master_->sent(), 0);
    std::lock_guard lock(answers_.mutex);
    ASSERT_EQ(answers_.published.size(), 3u);
    EXPECT_THAT(answers_.published[0].second.at("error").get<std::string>(), HasSubstr("writes are off"));
    EXPECT_THAT(answers_.published[1].second.at("error").get<std::string>(), HasSubstr("no device \"kiln\""));
    EXPECT_EQ(answers_.published[2].first, "p/oven/no_such/set/result");
    EXPECT_EQ(answers_.published[2].second.at("ok"), false);
}

// A retained command (the broker's copy, handed over at every subscription) never reaches the
// line, whatever its value: its refusal says why on the result topic and in the log.
TEST_F(MqttCommandsTest, ARetainedCommandIsRefusedWithTheReasonAndNeverWritten) {
    open(3);
    commands_->refuse_retained("p/oven/set_point/set", "444");
    commands_->refuse_retained("p/oven/set_point/set/result", "{}");  // not a command: no answer
    EXPECT_EQ(commands_->under_way(), 0u);
    EXPECT_EQ(master_->sent(), 0);
    std::lock_guard lock(answers_.mutex);
    ASSERT_EQ(answers_.published.size(), 1u);
    EXPECT_EQ(answers_.published[0].first, "p/oven/set_point/set/result");
    EXPECT_EQ(answers_.published[0].second.at("ok"), false);
    EXPECT_THAT(answers_.published[0].second.at("error").get<std::string>(),
                HasSubstr("published with the retain flag; nothing was written"));
    EXPECT_THAT(answers_.published[0].second.at("error").get<std::string>(),
                HasSubstr("an empty retained message on \"p/oven/set_point/set\""));
    ASSERT_EQ(answers_.logged.size(), 1u);
    EXPECT_THAT(answers_.logged[0],
                HasSubstr("\"oven\".\"set_point\" = \"444\" refused: published with the retain flag"));
}

}  // namespace
}  // namespace loopwire::gateway
