// The running gateway (gateway/gateway.hpp) in this process, on a simulated line: its change
// stream reaches a subscriber as a later front (MQTT, HTTP) will consume it, and
// `[modbus_tcp] max_age` reaches the Modbus TCP front.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <atomic>
#include <filesystem>
#include <iterator>
#include <iostream>
#include <fstream>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

#include <fmt/format.h>

#include "client/device_client.hpp"
#include "codec/pdu.hpp"
#include "codec/tcp.hpp"
#include "gateway/gateway.hpp"
#include "session/master.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "transport/link_url.hpp"
#include "transport/tcp.hpp"
#include "support/eventually.hpp"
#include "support/profile_test_support.hpp"
#include "support/thread_names.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using loopwire::testing::eventually;

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

// One TC10 simulated on a virtual line inside the gateway; no Modbus TCP front.
const char* const simulated_plant = R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"
retries = 1

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "100ms"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false
)toml";

struct Collected {
    std::mutex mutex;
    std::condition_variable arrived;
    std::vector<ValueChange> changes;

    ValueCallback collect() {
        return [this](const ValueChange& change) {
            std::lock_guard lock(mutex);
            changes.push_back(change);
            arrived.notify_all();
        };
    }
    // Until a value of `parameter` was read (a loaded machine may lose the first polls).
    bool wait_for_value(const std::string& parameter) {
        std::unique_lock lock(mutex);
        return arrived.wait_for(lock, 10s, [&] {
            return std::any_of(changes.begin(), changes.end(), [&](const ValueChange& change) {
                return change.parameter == parameter && change.value;
            });
        });
    }
};

TEST(Gateway, ASubscriberIsToldWhatThePollsRead) {
    auto config = parse_gateway_config(simulated_plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto gateway = Gateway::open(*config);
    ASSERT_TRUE(gateway) << gateway.error().message;
    Collected collected;
    auto subscription = (*gateway)->subscribe(collected.collect());
    ASSERT_TRUE(collected.wait_for_value("measured_value")) << "no value of the simulated device arrived";

    subscription.reset();
    std::lock_guard lock(collected.mutex);
    const auto& changes = collected.changes;
    // The first sample (or the picture, when a poll came first) tells the device, then each parameter.
    ASSERT_GE(changes.size(), 3u);
    EXPECT_EQ(changes[0].device, "oven1");
    EXPECT_TRUE(changes[0].about_device());
    EXPECT_EQ(changes[1].parameter, "measured_value");
    EXPECT_EQ(changes[2].parameter, "set_point");
    EXPECT_EQ(changes[1].unit, changes[2].unit);
    ASSERT_EQ((*gateway)->values().size(), 1u);
}

// A poll once a minute, so that after the first one only the clients' requests use the line.
const char* const cached_plant = R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"
retries = 1

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "1m"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
listen = "127.0.0.1:0"
max_age = "1m"
)toml";

std::uint64_t sent_on_the_line(const Gateway& gateway) { return gateway.report().at(0).statistics.sent; }

TEST(Gateway, WithAMaxAgeARepeatedReadIsAnsweredWithoutTheLine) {
    auto config = parse_gateway_config(cached_plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    Gateway& gateway = **opened;
    std::jthread serving([&gateway](std::stop_token stop) { (void)gateway.serve(std::move(stop)); });
    Collected collected;
    auto subscription = gateway.subscribe(collected.collect());
    ASSERT_TRUE(collected.wait_for_value("measured_value")) << "the first poll did not read the device";

    auto link = transport::parse_link_url(fmt::format("tcp://127.0.0.1:{}", gateway.modbus_tcp_port()));
    ASSERT_TRUE(link) << link.error().message;
    auto master = session::open_master(*link, {});
    ASSERT_TRUE(master) << master.error().message;
    const DeviceConfig& oven = config->lines[0].devices[0];
    device::DeviceClient client(**master, oven.address);
    const auto before = sent_on_the_line(gateway);
    const auto first = client.read(polled_parameters(oven));
    ASSERT_FALSE(first.first_error) << first.first_error->message;
    const auto after_first = sent_on_the_line(gateway);
    EXPECT_GT(after_first, before);
    const auto second = client.read(polled_parameters(oven));
    ASSERT_FALSE(second.first_error) << second.first_error->message;
    EXPECT_EQ(sent_on_the_line(gateway), after_first) << "the repeated read went to the line";
    ASSERT_EQ(second.readings.size(), first.readings.size());
    for (std::size_t i = 0; i < first.readings.size(); ++i) {
        EXPECT_EQ(second.readings[i].value->raw, first.readings[i].value->raw) << i;
    }
}

// The field's case: ten Modbus TCP clients reading back to back through the gateway
// keep its line busy all the time; its own poll every second still comes round, so the PV it
// hands out stays a few intervals old at most and the device stays ok (never stale).
const char* const busy_plant = R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200&parity=none"
timeout = "500ms"
retries = 1

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "1s"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
listen = "127.0.0.1:0"
)toml";

TEST(Gateway, TenClientsReadingBackToBackDoNotStopThePolls) {
    auto config = parse_gateway_config(busy_plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    Gateway& gateway = **opened;
    std::jthread serving([&gateway](std::stop_token stop) { (void)gateway.serve(std::move(stop)); });
    Collected collected;
    auto subscription = gateway.subscribe(collected.collect());
    ASSERT_TRUE(collected.wait_for_value("measured_value")) << "the first poll did not read the device";

    const DeviceConfig& oven = config->lines[0].devices[0];
    auto link = transport::parse_link_url(fmt::format("tcp://127.0.0.1:{}", gateway.modbus_tcp_port()));
    ASSERT_TRUE(link) << link.error().message;
    std::atomic<std::uint64_t> reads{0};
    std::atomic<std::uint64_t> failures{0};
    std::vector<std::jthread> clients;
    for (int i = 0; i < 10; ++i) {
        clients.emplace_back([&](std::stop_token stop) {
            auto master = session::open_master(*link, {});
            if (!master) {
                failures.fetch_add(1);
                return;
            }
            device::DeviceClient client(**master, oven.address);
            while (!stop.stop_requested()) {
                const auto report = client.read(polled_parameters(oven));
                (report.first_error ? failures : reads).fetch_add(1);
            }
        });
    }
    const auto polls_of = [&gateway] { return gateway.values().at(0).state.polls; };
    const auto utilisation = [&gateway] {
        const auto s = gateway.report().at(0).statistics;
        return std::pair(s.busy, s.open);
    };
    // The clients have the line busy before the watch starts.
    ASSERT_TRUE(eventually([&] { return reads.load() >= 50; })) << "the clients did not get going";

    // Ten intervals of watching, as a front reads the cache: the device ok, the PV young.
    const auto [busy_before, open_before] = utilisation();
    const auto polls_before = polls_of();
    const auto watch_until = std::chrono::steady_clock::now() + 10s;
    double oldest = 0;
    while (std::chrono::steady_clock::now() < watch_until) {
        const CachedDevice seen = gateway.values().at(0);
        ASSERT_EQ(seen.state.status, device::DeviceStatus::ok) << seen.state.last_error;
        const auto age = device::age_seconds(seen.state.values.at(0), device::MonitorClock::now());
        ASSERT_TRUE(age);
        oldest = std::max(oldest, *age);
        ASSERT_LE(*age, 3.0) << "the PV was not polled for " << *age << " s";
        std::this_thread::sleep_for(50ms);
    }
    const auto [busy_after, open_after] = utilisation();
    const auto polls_after = polls_of();
    for (auto& client : clients) client.request_stop();
    clients.clear();
    const double busy = static_cast<double>((busy_after - busy_before).count()) / static_cast<double>((open_after - open_before).count());
    std::cout << "10 clients: " << reads.load() << " reads, " << failures.load() << " failed; line busy " << busy * 100
              << " %; " << polls_after - polls_before << " polls in 10 s; oldest PV seen " << oldest << " s\n";
    EXPECT_GE(polls_after - polls_before, 5u) << "the polls every second nearly stopped";
    EXPECT_GT(busy, 0.5) << "the clients did not load the line: the test shows nothing";
}

// The polls' values reach the history: the gateway opens the database and answers for it.
TEST(Gateway, WithAHistoryThePolledValuesAreRecorded) {
    std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-gateway-history-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    const std::filesystem::path folder = pattern;
    const std::string text = std::string(simulated_plant) + fmt::format("\n[history]\ndatabase = \"{}\"\n", (folder / "plant.db").string());
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    {
        auto opened = Gateway::open(*config);
        ASSERT_TRUE(opened) << opened.error().message;
        const HistorySource* history = (*opened)->history();
        ASSERT_NE(history, nullptr);
        ASSERT_TRUE(eventually([&] { return history->rows_written() >= 2; })) << "no values were recorded";
        HistoryQuery query;
        query.device = "oven1";
        query.from = std::chrono::system_clock::now() - 1min;
        query.to = std::chrono::system_clock::now() + 1s;
        query.points = 10;
        auto series = history->query(query);
        ASSERT_TRUE(series) << series.error().message;
        ASSERT_EQ(series->size(), 2u);
        EXPECT_EQ((*series)[0].parameter, "measured_value");
        EXPECT_EQ((*series)[1].parameter, "set_point");
    }
    // A file that is not a history database stops the gateway at its start, saying which.
    std::filesystem::resize_file(folder / "plant.db", 0);
    std::filesystem::remove(folder / "plant.db-wal");
    std::filesystem::remove(folder / "plant.db-shm");
    { std::ofstream(folder / "plant.db") << "not a database, but a long enough line of text to fill a header and then some more\n"; }
    auto refused = Gateway::open(*config);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, ::testing::HasSubstr((folder / "plant.db").string() + ": cannot be read as an SQLite database"));
    std::filesystem::remove_all(folder);

    auto plain = Gateway::open(*parse_gateway_config(simulated_plant, "plant.toml", profiles()));
    ASSERT_TRUE(plain) << plain.error().message;
    EXPECT_EQ((*plain)->history(), nullptr);
}

// Each line keeps its own polls' pace (poll_groups.hpp): a line too slow for its devices' interval
// skips samples, and a device polled at the same interval on a fast line of its own skips none
// for it (once the two shared a sample, and the fast line waited for the slow one).
TEST(Gateway, ASlowLineDoesNotHoldAnotherLinesPolls) {
    const std::string plant =
        "[[lines]]\nname = \"slow\"\nlink = \"rtu:virtual?baud=1200&parity=none\"\ntimeout = \"2s\"\n"
        "[[lines.devices]]\nname = \"kiln\"\ndevice = \"rampsoak@1\"\npoll = \"200ms\"\n"
        "[[lines]]\nname = \"fast\"\nlink = \"rtu:virtual?baud=115200&parity=none\"\ntimeout = \"2s\"\n"
        "[[lines.devices]]\nname = \"oven\"\ndevice = \"tc10@2\"\npoll = \"200ms\"\nparameters = [\"measured_value\"]\n"
        "[modbus_tcp]\nenabled = false\n";
    auto config = parse_gateway_config(plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    const auto device = [&](const std::string& name) {
        for (const auto& cached : (*opened)->values()) {
            if (cached.name == name) return cached.state;
        }
        return device::WatchedDevice{};
    };
    (void)eventually([&] { return device("kiln").missed >= 6; });  // asserted below, with the figures
    const auto kiln = device("kiln");
    const auto oven = device("oven");
    std::cout << "samples skipped: kiln (slow line) " << kiln.missed << " in " << kiln.polls << " polls, oven (fast line) "
              << oven.missed << " in " << oven.polls << " polls\n";
    ASSERT_GE(kiln.missed, 6U) << "the slow line kept its pace: the test proves nothing";
    EXPECT_GT(oven.polls, kiln.polls * 2) << "the fast line was held to the slow line's pace";
    EXPECT_LT(oven.missed * 4, kiln.missed) << "the fast line skipped samples for the slow one";
}

// The threads of this process now.
std::size_t threads_now() {
    return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator("/proc/self/task"),
                                                  std::filesystem::directory_iterator{}));
}

// Until every device of the gateway has been polled at least once.
void wait_until_all_polled(const GatewayConfig& config, const Gateway& gateway) {
    std::size_t configured = 0;
    for (const auto& line : config.lines) configured += line.devices.size();
    const auto all_polled = [&] {
        const auto devices = gateway.values();
        return devices.size() == configured &&
               std::all_of(devices.begin(), devices.end(), [](const CachedDevice& device) { return device.state.polls > 0; });
    };
    EXPECT_TRUE(eventually(all_polled)) << "not every device was polled";
}

// The threads of a gateway on `plant` once every device has been polled.
std::size_t threads_of_gateway(const std::string& plant) {
    auto config = parse_gateway_config(plant, "plant.toml", profiles());
    EXPECT_TRUE(config) << config.error().message;
    if (!config) return 0;
    const std::size_t before = threads_now();
    auto opened = Gateway::open(*config);
    EXPECT_TRUE(opened) << opened.error().message;
    if (!opened) return 0;
    wait_until_all_polled(*config, **opened);
    return threads_now() - before;
}

// Every poll group runs on one loop and one thread (poll_groups.hpp): three devices polled at
// three intervals take no more threads than one device.
TEST(Gateway, ThePollsTakeOneThreadHoweverManyDevicesAndIntervals) {
    const std::string line = "[[lines]]\nname = \"sim\"\nlink = \"rtu:virtual?baud=115200&parity=none\"\ntimeout = \"500ms\"\n";
    const std::string one = line + "[[lines.devices]]\nname = \"oven\"\ndevice = \"tc10@1\"\npoll = \"100ms\"\n"
                                   "[modbus_tcp]\nenabled = false\n";
    const std::string three = line + "[[lines.devices]]\nname = \"oven\"\ndevice = \"tc10@1\"\npoll = \"100ms\"\n"
                                     "[[lines.devices]]\nname = \"furnace\"\ndevice = \"ac20@2\"\npoll = \"200ms\"\n"
                                     "[[lines.devices]]\nname = \"kiln\"\ndevice = \"rampsoak@3\"\npoll = \"300ms\"\n"
                                     "[modbus_tcp]\nenabled = false\n";
    // A first gateway, not counted: a sanitizer's runtime starts a thread of its own once, at a
    // moment of its choosing.
    (void)threads_of_gateway(three);
    const std::size_t for_one = threads_of_gateway(one);
    const std::size_t for_three = threads_of_gateway(three);
    std::cout << "threads of a gateway with one line: " << for_one << " for 1 device, " << for_three
              << " for 3 devices at 3 intervals\n";
    EXPECT_GT(for_one, 0U);
    EXPECT_EQ(for_three, for_one);
}

// Four virtual lines of three devices polled at three intervals.
std::string four_lines_of_three_devices() {
    std::string plant;
    for (int line = 0; line < 4; ++line) {
        plant += fmt::format("[[lines]]\nname = \"line{}\"\nlink = \"rtu:virtual?baud=115200&parity=none\"\n", line);
        for (int unit = 1; unit <= 3; ++unit) {
            plant += fmt::format("[[lines.devices]]\nname = \"oven{}{}\"\ndevice = \"tc10@{}\"\npoll = \"{}ms\"\ntcp_unit = {}\n",
                                 line, unit, unit, 100 * unit, line * 3 + unit);
        }
    }
    return plant + "[modbus_tcp]\nenabled = false\n";
}

// The gateway's threads by role, with four virtual lines of three devices polled at three
// intervals: the polls run on the engine's thread, and the four lines' masters and their
// simulated devices (simulation/simulated_lines.hpp) on the lines' loop (session/line_loop.hpp);
// no line has a thread of its own while it is up (gateway/reopening_master.hpp).
TEST(Gateway, FourVirtualLinesAndTheirSimulatedDevicesShareOneThread) {
    const std::string plant = four_lines_of_three_devices();
    auto config = parse_gateway_config(plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    wait_until_all_polled(*config, **opened);
    const auto names = testing::thread_names();
    EXPECT_EQ(names.count("lw-simulation"), 0U);
    EXPECT_EQ(names.count("lw-engine"), 1U);
    EXPECT_EQ(names.count("lw-lines"), 1U);
    EXPECT_EQ(testing::threads_named_like("lw-line "), 0U);
    EXPECT_EQ(names.count("lw-serial"), 0U);
}

// The measure: a gateway of one line with one device takes as many threads as one of
// four lines with three devices each, polled at three intervals.
TEST(Gateway, FourLinesOfThreeDevicesTakeNoMoreThreadsThanOneLineOfOne) {
    const std::string one = "[[lines]]\nname = \"sim\"\nlink = \"rtu:virtual?baud=115200&parity=none\"\n"
                            "[[lines.devices]]\nname = \"oven\"\ndevice = \"tc10@1\"\npoll = \"100ms\"\n"
                            "[modbus_tcp]\nenabled = false\n";
    const std::string four = four_lines_of_three_devices();
    (void)threads_of_gateway(four);  // not counted: a sanitizer's runtime may start a thread once
    const std::size_t for_one = threads_of_gateway(one);
    const std::size_t for_four = threads_of_gateway(four);
    std::cout << "threads of a gateway: " << for_one << " for 1 line x 1 device, " << for_four
              << " for 4 lines x 3 devices at 3 intervals\n";
    EXPECT_GT(for_one, 0U);
    EXPECT_EQ(for_four, for_one);
}

// A gateway with a Modbus TCP front and one line to a Modbus TCP device at `port`, unit 3
// as "oven1" (a TC10) polled every `poll`.
std::string tcp_device_plant(std::uint16_t port, const std::string& timeout, int max_in_flight, const std::string& poll) {
    return fmt::format(R"toml(
[[lines]]
name = "plc"
link = "tcp://127.0.0.1:{}"
timeout = "{}"
max_in_flight = {}

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "{}"
parameters = ["measured_value"]

[modbus_tcp]
listen = "127.0.0.1:0"
)toml", port, timeout, max_in_flight, poll);
}

// A Modbus TCP device that answers reads of address 1000 onwards only once it holds `batch` of
// them, and then the last first: a server may answer in any order, the transaction id pairs the
// replies. Other requests (the gateway's poll) are answered at once. Register r reads r * 7.
class BatchReversingDevice {
public:
    explicit BatchReversingDevice(std::size_t batch) : batch_(batch) {
        auto listening = transport::TcpListener::listen("127.0.0.1", 0);
        if (!listening) throw std::runtime_error(listening.error().message);
        listener_ = std::move(*listening);
        thread_ = std::jthread([this](std::stop_token stop) { serve(std::move(stop)); });
    }

    std::uint16_t port() const { return listener_->port(); }
    std::size_t batches() const { return batches_.load(); }

private:
    static constexpr std::uint16_t held_from = 1000;

    void serve(std::stop_token stop) {
        std::unique_ptr<transport::ByteStream> connection;
        while (!stop.stop_requested() && !connection) {
            auto accepted = listener_->accept(50ms);
            if (!accepted) return;
            connection = std::move(*accepted);
        }
        codec::MbapDecoder decoder;
        std::vector<codec::Frame> held;
        std::array<std::uint8_t, 1024> buffer{};
        while (!stop.stop_requested()) {
            auto got = connection->read_some(buffer, 50ms);
            if (!got) return;  // the gateway closed the connection
            auto frames = decoder.feed(ByteView(buffer.data(), *got));
            if (!frames) return;
            for (auto& frame : *frames) {
                auto request = codec::decode_request(frame.pdu);
                if (request && request->address >= held_from) {
                    held.push_back(std::move(frame));
                } else if (request) {
                    answer(*connection, frame, *request);
                }
            }
            if (held.size() < batch_) continue;
            for (auto frame = held.rbegin(); frame != held.rend(); ++frame) {
                answer(*connection, *frame, *codec::decode_request(frame->pdu));
            }
            held.clear();
            ++batches_;
        }
    }

    static void answer(transport::ByteStream& connection, const codec::Frame& frame, const codec::Request& request) {
        codec::Reply reply;
        reply.function = request.function;
        for (std::uint16_t i = 0; i < request.count; ++i) reply.values.push_back(static_cast<std::uint16_t>((request.address + i) * 7));
        auto pdu = codec::encode_reply(reply);
        if (!pdu) pdu = codec::encode_reply(codec::exception_reply(request.function, 0x01));
        (void)connection.write(codec::mbap_encode(frame.transaction, frame.unit, *pdu));
    }

    const std::size_t batch_;
    std::unique_ptr<transport::TcpListener> listener_;
    std::atomic<std::size_t> batches_{0};
    std::jthread thread_;  // last: joined before the rest goes
};

// `max_in_flight` on a Modbus TCP line: four clients' requests are on the device's connection at
// once (the device answers none until it holds four: one at a time would never be answered) and
// every client gets the values it asked for, though the device answers the last request first.
TEST(Gateway, AModbusTcpLineCarriesSeveralRequestsAtOncePairedByTransactionId) {
    constexpr int clients = 4;
    constexpr int reads_each = 25;
    BatchReversingDevice device(clients);
    const std::string plant = tcp_device_plant(device.port(), "20s", 8, "60m");
    auto config = parse_gateway_config(plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    Gateway& gateway = **opened;
    std::jthread serving([&gateway](std::stop_token stop) { (void)gateway.serve(std::move(stop)); });

    auto link = transport::parse_link_url(fmt::format("tcp://127.0.0.1:{}", gateway.modbus_tcp_port()));
    ASSERT_TRUE(link) << link.error().message;
    std::atomic<int> right{0};
    std::mutex wrong_mutex;
    std::vector<std::string> wrong;
    {
        std::vector<std::jthread> readers;
        for (int c = 0; c < clients; ++c) {
            readers.emplace_back([&, c] {
                session::MasterOptions options;
                options.timeout = 20s;  // a batch waits for the slowest of the four clients
                auto master = session::open_master(*link, options);
                for (int i = 0; master && i < reads_each; ++i) {
                    const auto address = static_cast<std::uint16_t>(1000 + 100 * c + i);
                    const auto count = static_cast<std::uint16_t>(1 + (i % 3));
                    auto reply = (*master)->execute(3, codec::read_request(codec::FunctionCode::read_holding_registers, address, count));
                    std::vector<std::uint16_t> expected;
                    for (std::uint16_t r = 0; r < count; ++r) expected.push_back(static_cast<std::uint16_t>((address + r) * 7));
                    if (reply && reply->values == expected) {
                        ++right;
                        continue;
                    }
                    std::lock_guard lock(wrong_mutex);
                    wrong.push_back(fmt::format("client {} read {} x{}: {}", c, address, count,
                                                reply ? "other values" : reply.error().message));
                }
                if (!master) {
                    std::lock_guard lock(wrong_mutex);
                    wrong.push_back(master.error().message);
                }
            });
        }
    }
    EXPECT_TRUE(wrong.empty()) << ::testing::PrintToString(wrong);
    EXPECT_EQ(right.load(), clients * reads_each);
    EXPECT_EQ(device.batches(), static_cast<std::size_t>(reads_each));
}

// A Modbus TCP device (a register bank behind session::Slave) on a port of its own.
class RestartableTcpDevice {
public:
    explicit RestartableTcpDevice(std::uint16_t value, std::uint16_t port = 0) { start(value, port); }

    std::uint16_t port() const { return port_; }
    void stop() {
        server_ = {};  // joined: its connections are closed
        listener_.reset();
    }
    void start(std::uint16_t value, std::uint16_t port) {
        auto listening = transport::TcpListener::listen("127.0.0.1", port);
        if (!listening) throw std::runtime_error(listening.error().message);
        listener_ = std::move(*listening);
        port_ = listener_->port();
        auto bank = std::make_shared<session::RegisterBank>();
        bank->set(session::Table::holding_registers, 0, value);
        const auto link = transport::parse_link_url(fmt::format("tcp://127.0.0.1:{}", port_));
        slave_ = std::make_unique<session::Slave>(*link, session::UnitMap{{3, bank}});
        server_ = std::jthread([this](std::stop_token stop) { (void)slave_->serve_listener(*listener_, std::move(stop)); });
    }

private:
    std::unique_ptr<transport::TcpListener> listener_;
    std::unique_ptr<session::Slave> slave_;
    std::uint16_t port_ = 0;
    std::jthread server_;
};

// Register 0 of unit 3 read through the gateway's front until `wanted` says yes (a loaded
// machine may take a while; 30 s at most, then the test fails saying what it saw last).
bool read_through_until(session::Master& client, const std::function<bool(const Result<codec::Reply>&)>& wanted,
                        std::string& last) {
    const auto read_wanted = [&] {
        auto reply = client.execute(3, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
        last = reply ? fmt::format("value {}", reply->values.at(0)) : reply.error().message;
        return wanted(reply);
    };
    return eventually(read_wanted, 30s, 50ms);
}

// A Modbus TCP device that goes away and comes back on the same port: the line's connection
// is read on the lines' loop, which does not connect again itself; the line goes down and its
// keeper reopens it with back-off, and clients are answered by the device again. Up, the line
// costs no thread (before, a TCP line kept a reader and its keeper's worker for good).
TEST(Gateway, AModbusTcpDeviceThatRestartsIsReopenedAndAnsweredAgain) {
    RestartableTcpDevice device(7);
    const std::string plant = tcp_device_plant(device.port(), "500ms", 4, "200ms");
    auto config = parse_gateway_config(plant, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto opened = Gateway::open(*config);
    ASSERT_TRUE(opened) << opened.error().message;
    Gateway& gateway = **opened;
    std::jthread serving([&gateway](std::stop_token stop) { (void)gateway.serve(std::move(stop)); });
    auto front = transport::parse_link_url(fmt::format("tcp://127.0.0.1:{}", gateway.modbus_tcp_port()));
    ASSERT_TRUE(front) << front.error().message;
    session::MasterOptions options;
    options.timeout = 5s;
    auto client = session::open_master(*front, options);
    ASSERT_TRUE(client) << client.error().message;

    const auto value_is = [](std::uint16_t value) {
        return [value](const Result<codec::Reply>& reply) { return reply && reply->values.at(0) == value; };
    };
    std::string last;
    ASSERT_TRUE(read_through_until(**client, value_is(7), last)) << "the device was never read: " << last;

    const std::uint16_t port = device.port();
    device.stop();
    ASSERT_TRUE(read_through_until(**client, [](const Result<codec::Reply>& reply) { return !reply; }, last))
        << "the device's going was never noticed: " << last;

    device.start(8, port);
    ASSERT_TRUE(read_through_until(**client, value_is(8), last)) << "the line was never reopened: " << last;
    // Up again, the line has no thread of its own: its reopening worker ended once idle.
    EXPECT_TRUE(eventually([] { return loopwire::testing::threads_named_like("lw-line ") == 0; }))
        << "a thread of the line's own stayed";
}

}  // namespace
}  // namespace loopwire::gateway
