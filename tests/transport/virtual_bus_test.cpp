#include "transport/virtual_bus.hpp"

#include <gtest/gtest.h>
#include <poll.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>
#include <vector>

#include "test_support.hpp"

namespace loopwire::transport {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using testing::read_exactly;

// Upper bounds only catch gross errors (a byte that never comes, a timer that waits seconds):
// a loaded 2-core CI machine can stall any thread for tens of milliseconds.
constexpr auto slack = 500ms;

// Exact wire time of `characters` characters, for lower bounds.
std::chrono::nanoseconds wire_time(std::size_t characters, std::uint32_t baud, unsigned bits) {
    return std::chrono::nanoseconds(characters * bits * 1'000'000'000ULL / baud);
}

struct Arrival {
    std::uint8_t value;
    Clock::time_point at;
};

// Reads one byte at a time so every byte gets its own arrival time.
std::vector<Arrival> read_with_times(ByteStream& port, std::size_t count, std::chrono::milliseconds timeout = 3s) {
    std::vector<Arrival> arrivals;
    const auto deadline = Clock::now() + timeout;
    while (arrivals.size() < count && Clock::now() < deadline) {
        std::uint8_t byte = 0;
        auto got = port.read_some(std::span(&byte, 1), 100ms);
        if (!got) break;
        if (*got == 1) arrivals.push_back({byte, Clock::now()});
    }
    return arrivals;
}

Bytes values_of(const std::vector<Arrival>& arrivals) {
    Bytes out;
    for (const auto& arrival : arrivals) out.push_back(arrival.value);
    return out;
}

std::size_t read_nothing(ByteStream& port, std::chrono::milliseconds wait) {
    std::uint8_t buffer[64];
    auto got = port.read_some(buffer, wait);
    return got ? *got : 9999;
}

TEST(VirtualBus, CharacterTimeFollowsBaudAndCharacterSize) {
    EXPECT_EQ(VirtualBus::create(9600, 11)->character_time(), 1146us);  // 1145.83 µs
    EXPECT_EQ(VirtualBus::create(19200, 11)->character_time(), 573us);
    EXPECT_EQ(VirtualBus::create(600, 10)->character_time(), 16667us);
}

TEST(VirtualBus, DeliversToEveryOtherPortButNotTheSender) {
    auto bus = VirtualBus::create(115200, 10);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    auto c = bus->attach("c");
    const Bytes frame = {0x01, 0x03, 0x00, 0x00, 0x00, 0x02};
    ASSERT_TRUE(a->write(frame));
    EXPECT_EQ(read_exactly(*b, frame.size()), frame);
    EXPECT_EQ(read_exactly(*c, frame.size()), frame);
    EXPECT_EQ(read_nothing(*a, 20ms), 0u);
}

TEST(VirtualBus, DescribesThePort) {
    auto bus = VirtualBus::create(9600, 11);
    auto port = bus->attach("master");
    EXPECT_EQ(port->describe(), "virtual bus port 'master' (9600 baud, 11-bit characters)");
}

// 9600 baud, 11-bit characters (8E1): 10 bytes take 11.46 ms on the wire.
TEST(VirtualBus, BytesArriveOneCharacterTimeApart) {
    constexpr std::uint32_t baud = 9600;
    constexpr unsigned bits = 11;
    auto bus = VirtualBus::create(baud, bits);
    auto sender = bus->attach("sender");
    auto receiver = bus->attach("receiver");
    const Bytes frame = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};

    std::vector<Arrival> arrivals;
    std::thread reader([&] { arrivals = read_with_times(*receiver, frame.size()); });
    const auto start = Clock::now();
    ASSERT_TRUE(sender->write(frame));
    const auto written = Clock::now();
    reader.join();

    // write() returns once the frame has left, like tcdrain().
    EXPECT_GE(written - start, wire_time(10, baud, bits));
    EXPECT_LT(written - start, wire_time(10, baud, bits) + slack);
    ASSERT_EQ(values_of(arrivals), frame);
    for (std::size_t i = 0; i < arrivals.size(); ++i) {
        EXPECT_GE(arrivals[i].at - start, wire_time(i + 1, baud, bits)) << "byte " << i << " arrived early";
    }
    EXPECT_LT(arrivals.back().at - start, wire_time(10, baud, bits) + slack);
}

TEST(VirtualBus, WriteBlocksForTheWholeTransmission) {
    auto bus = VirtualBus::create(600, 11);  // 18.3 ms per character
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    const auto start = Clock::now();
    ASSERT_TRUE(a->write(Bytes{1, 2, 3, 4, 5}));
    const auto elapsed = Clock::now() - start;
    EXPECT_GE(elapsed, wire_time(5, 600, 11));
    EXPECT_LT(elapsed, wire_time(5, 600, 11) + slack);
}

TEST(VirtualBus, ConcurrentWritersAreSerialisedOnTheWire) {
    constexpr std::uint32_t baud = 9600;
    constexpr unsigned bits = 11;
    auto bus = VirtualBus::create(baud, bits);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    auto listener = bus->attach("listener");
    const Bytes from_a(10, 0xAA);
    const Bytes from_b(10, 0xBB);

    std::vector<Arrival> arrivals;
    std::thread reader([&] { arrivals = read_with_times(*listener, 20); });
    const auto start = Clock::now();
    Clock::time_point a_done;
    Clock::time_point b_done;
    std::thread writer_a([&] {
        EXPECT_TRUE(a->write(from_a));
        a_done = Clock::now();
    });
    std::thread writer_b([&] {
        EXPECT_TRUE(b->write(from_b));
        b_done = Clock::now();
    });
    writer_a.join();
    writer_b.join();
    reader.join();

    // One whole frame, then the other: never interleaved.
    const Bytes heard = values_of(arrivals);
    ASSERT_EQ(heard.size(), 20u);
    const Bytes first(heard.begin(), heard.begin() + 10);
    const Bytes second(heard.begin() + 10, heard.end());
    EXPECT_TRUE((first == from_a && second == from_b) || (first == from_b && second == from_a));
    // The second frame waited for the first: 20 characters of wire time in all.
    EXPECT_GE(std::max(a_done, b_done) - start, wire_time(20, baud, bits));
    EXPECT_GE(arrivals.back().at - start, wire_time(20, baud, bits));
    // Each hears the other.
    EXPECT_EQ(read_exactly(*a, 10), from_b);
    EXPECT_EQ(read_exactly(*b, 10), from_a);
}

TEST(VirtualBus, ReadTimesOutWithZeroBytes) {
    auto bus = VirtualBus::create(19200, 11);
    auto port = bus->attach("idle");
    const auto start = Clock::now();
    EXPECT_EQ(read_nothing(*port, 30ms), 0u);
    const auto elapsed = Clock::now() - start;
    EXPECT_GE(elapsed, 30ms);
    EXPECT_LT(elapsed, 30ms + slack);
}

// Some callers say "no limit" with milliseconds::max(); the deadline must not overflow (UBSan).
TEST(VirtualBus, UnlimitedTimeoutStillReturnsWhatArrived) {
    auto bus = VirtualBus::create(115200, 10);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    ASSERT_TRUE(a->write(Bytes{1, 2, 3}));
    std::uint8_t buffer[8];
    auto got = b->read_some(buffer, std::chrono::milliseconds::max());
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 3u);
}

TEST(VirtualBus, ReadReturnsOnlyBytesAlreadyOnTheWire) {
    auto bus = VirtualBus::create(600, 10);  // 16.7 ms per character
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    const auto start = Clock::now();
    std::thread writer([&] { EXPECT_TRUE(a->write(Bytes(6, 0x11))); });
    std::uint8_t buffer[16];
    auto got = b->read_some(buffer, 2s);
    const auto returned = Clock::now();
    writer.join();
    ASSERT_TRUE(got);
    ASSERT_GE(*got, 1u);
    // However late we woke up, we never see a byte before its wire time.
    EXPECT_LE(static_cast<std::chrono::nanoseconds::rep>(*got),
              (returned - start) / wire_time(1, 600, 10));
}

TEST(VirtualBus, DiscardInputDropsArrivedBytesButNotThoseStillOnTheWire) {
    auto bus = VirtualBus::create(600, 10);  // 16.7 ms per character
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    ASSERT_TRUE(a->write(Bytes{1, 2}));
    b->discard_input();
    EXPECT_EQ(read_nothing(*b, 10ms), 0u);

    // The next frame is still on its way (333 ms) when the port discards its input: what had
    // arrived is gone, the rest still comes.
    Bytes frame(20);
    for (std::size_t i = 0; i < frame.size(); ++i) frame[i] = static_cast<std::uint8_t>(100 + i);
    std::thread writer([&] { EXPECT_TRUE(a->write(frame)); });
    pollfd entry{b->poll_handle(), POLLIN, 0};
    ASSERT_EQ(::poll(&entry, 1, 2000), 1);  // the first byte has arrived
    b->discard_input();
    writer.join();
    Bytes after = read_exactly(*b, frame.size(), 200ms);
    ASSERT_FALSE(after.empty());
    EXPECT_LT(after.size(), frame.size());
    EXPECT_TRUE(std::equal(after.rbegin(), after.rend(), frame.rbegin())) << "not the end of the frame";
}

TEST(VirtualBus, PollHandleIsReadableExactlyWhileBytesAreDue) {
    constexpr std::uint32_t baud = 1200;
    constexpr unsigned bits = 10;  // 8.3 ms per character
    auto bus = VirtualBus::create(baud, bits);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    const int handle = b->poll_handle();
    ASSERT_GE(handle, 0);
    pollfd entry{handle, POLLIN, 0};
    EXPECT_EQ(::poll(&entry, 1, 0), 0);

    const auto start = Clock::now();
    std::thread writer([&] { EXPECT_TRUE(a->write(Bytes{1, 2, 3})); });
    ASSERT_EQ(::poll(&entry, 1, 2000), 1);
    const auto readable = Clock::now();
    EXPECT_GE(readable - start, wire_time(1, baud, bits));
    std::uint8_t buffer[8];
    auto got = b->read_some(buffer, 0ms);
    ASSERT_TRUE(got);
    EXPECT_GE(*got, 1u);
    writer.join();

    EXPECT_EQ(read_exactly(*b, 3 - *got, 1s).size(), 3 - *got);
    entry.revents = 0;
    EXPECT_EQ(::poll(&entry, 1, 20), 0) << "readable with nothing to read";
}

TEST(VirtualBus, PortsKeepTheBusAlive) {
    auto bus = VirtualBus::create(115200, 10);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    bus.reset();
    ASSERT_TRUE(a->write(Bytes{5, 6}));
    EXPECT_EQ(read_exactly(*b, 2), (Bytes{5, 6}));
}

TEST(VirtualBus, DetachedPortsReceiveNothingAndAreNotMissed) {
    auto bus = VirtualBus::create(115200, 10);
    auto a = bus->attach("a");
    auto b = bus->attach("b");
    auto c = bus->attach("c");
    c.reset();
    ASSERT_TRUE(a->write(Bytes{9}));
    EXPECT_EQ(read_exactly(*b, 1), Bytes{9});
}

// ----- faults -----

struct FaultFixture : ::testing::Test {
    static constexpr std::uint32_t baud = 9600;
    static constexpr unsigned bits = 11;
    std::shared_ptr<VirtualBus> bus = VirtualBus::create(baud, bits);
    std::unique_ptr<ByteStream> master = bus->attach("master");
    std::unique_ptr<ByteStream> slave = bus->attach("slave");
    const Bytes frame = {0x07, 0x03, 0x00, 0x01, 0x00, 0x02};
};

using VirtualBusFaults = FaultFixture;

TEST_F(VirtualBusFaults, InjectorSeesTheSenderAndTheBytes) {
    std::vector<std::pair<std::string, Bytes>> seen;
    bus->set_fault_injector([&](const std::string& from, ByteView bytes) {
        seen.emplace_back(from, Bytes(bytes.begin(), bytes.end()));
        return BusFault{};
    });
    ASSERT_TRUE(master->write(frame));
    ASSERT_TRUE(slave->write(Bytes{0x42}));
    ASSERT_EQ(seen.size(), 2u);
    EXPECT_EQ(seen[0].first, "master");
    EXPECT_EQ(seen[0].second, frame);
    EXPECT_EQ(seen[1].first, "slave");
    EXPECT_EQ(seen[1].second, Bytes{0x42});
}

TEST_F(VirtualBusFaults, DroppedWriteNeverArrivesButStillTakesWireTime) {
    bus->set_fault_injector([&](const std::string&, ByteView bytes) {
        BusFault fault;
        fault.drop = bytes.size() == frame.size();
        return fault;
    });
    const auto start = Clock::now();
    ASSERT_TRUE(master->write(frame));
    EXPECT_GE(Clock::now() - start, wire_time(frame.size(), baud, bits));
    EXPECT_EQ(read_nothing(*slave, 30ms), 0u);
    ASSERT_TRUE(master->write(Bytes{0x55}));
    EXPECT_EQ(read_exactly(*slave, 1), Bytes{0x55});
}

TEST_F(VirtualBusFaults, CorruptBytesAreInverted) {
    bus->set_fault_injector([](const std::string&, ByteView) {
        BusFault fault;
        fault.corrupt_bytes = {0, 4, 99};  // 99 is past the end: ignored
        return fault;
    });
    ASSERT_TRUE(master->write(frame));
    Bytes expected = frame;
    expected[0] ^= 0xFF;
    expected[4] ^= 0xFF;
    EXPECT_EQ(read_exactly(*slave, frame.size()), expected);
}

TEST_F(VirtualBusFaults, ExtraDelayMakesBytesArriveLater) {
    constexpr auto delay = 40ms;
    bus->set_fault_injector([&](const std::string&, ByteView) {
        BusFault fault;
        fault.extra_delay = delay;
        return fault;
    });
    std::vector<Arrival> arrivals;
    std::thread reader([&] { arrivals = read_with_times(*slave, frame.size()); });
    const auto start = Clock::now();
    ASSERT_TRUE(master->write(frame));
    reader.join();
    ASSERT_EQ(values_of(arrivals), frame);
    EXPECT_GE(arrivals.front().at - start, wire_time(1, baud, bits) + delay);
    EXPECT_GE(arrivals.back().at - start, wire_time(frame.size(), baud, bits) + delay);
    EXPECT_LT(arrivals.back().at - start, wire_time(frame.size(), baud, bits) + delay + slack);
}

TEST_F(VirtualBusFaults, NoiseComesFirstAndTakesWireTime) {
    const Bytes noise = {0xFF, 0x00, 0xFF};
    bus->set_fault_injector([&](const std::string&, ByteView) {
        BusFault fault;
        fault.noise_before = noise;
        return fault;
    });
    std::vector<Arrival> arrivals;
    std::thread reader([&] { arrivals = read_with_times(*slave, noise.size() + frame.size()); });
    const auto start = Clock::now();
    ASSERT_TRUE(master->write(frame));
    const auto written = Clock::now();
    reader.join();

    Bytes expected = noise;
    expected.insert(expected.end(), frame.begin(), frame.end());
    ASSERT_EQ(values_of(arrivals), expected);
    const std::size_t total = noise.size() + frame.size();
    EXPECT_GE(arrivals.back().at - start, wire_time(total, baud, bits));
    EXPECT_GE(written - start, wire_time(total, baud, bits));
}

// A repeater that sends a frame twice: the same (corrupted) bytes again, the delay after the
// first copy started, without the sender waiting for it.
TEST_F(VirtualBusFaults, ADuplicatedWriteArrivesAgainAfterItsDelay) {
    constexpr auto again_after = 40ms;
    bus->set_fault_injector([&](const std::string&, ByteView) {
        BusFault fault;
        fault.corrupt_bytes = {1};
        fault.duplicate_after = again_after;
        return fault;
    });
    Bytes expected = frame;
    expected[1] ^= 0xFF;
    std::vector<Arrival> arrivals;
    std::thread reader([&] { arrivals = read_with_times(*slave, 2 * frame.size()); });
    const auto start = Clock::now();
    ASSERT_TRUE(master->write(frame));
    reader.join();
    Bytes twice = expected;
    twice.insert(twice.end(), expected.begin(), expected.end());
    ASSERT_EQ(values_of(arrivals), twice);
    EXPECT_GE(arrivals[frame.size()].at - start, wire_time(1, baud, bits) + again_after);
}

// A sender that stops mid-frame: only the first bytes go out, and only they take wire time.
TEST_F(VirtualBusFaults, ATruncatedWriteSendsItsFirstBytesOnly) {
    bus->set_fault_injector([&](const std::string&, ByteView bytes) {
        BusFault fault;
        if (bytes.size() == frame.size()) fault.truncate_to = 2;
        return fault;
    });
    ASSERT_TRUE(master->write(frame));
    ASSERT_TRUE(master->write(Bytes{0x55}));
    EXPECT_EQ(read_exactly(*slave, 3), (Bytes{frame[0], frame[1], 0x55}));
    EXPECT_EQ(read_nothing(*slave, 30ms), 0u);
}

TEST_F(VirtualBusFaults, FaultsApplyPerWrite) {
    int writes = 0;
    bus->set_fault_injector([&](const std::string&, ByteView) {
        BusFault fault;
        fault.drop = ++writes == 2;
        return fault;
    });
    ASSERT_TRUE(master->write(Bytes{1}));
    ASSERT_TRUE(master->write(Bytes{2}));
    ASSERT_TRUE(master->write(Bytes{3}));
    EXPECT_EQ(read_exactly(*slave, 2), (Bytes{1, 3}));
    bus->set_fault_injector(nullptr);
    ASSERT_TRUE(master->write(Bytes{4}));
    EXPECT_EQ(read_exactly(*slave, 1), Bytes{4});
}

// Several stations talking at once from their own threads: every byte reaches every other
// station, and frames stay whole.
TEST(VirtualBus, SurvivesManyThreadsWritingAndReading) {
    auto bus = VirtualBus::create(115200, 10);
    constexpr std::size_t stations = 4;
    constexpr int frames_each = 20;
    constexpr std::size_t frame_size = 8;
    std::vector<std::unique_ptr<ByteStream>> ports;
    for (std::size_t i = 0; i < stations; ++i) ports.push_back(bus->attach("station" + std::to_string(i)));

    std::vector<Bytes> heard(stations);
    std::vector<std::thread> threads;
    for (std::size_t i = 0; i < stations; ++i) {
        threads.emplace_back([&, i] {
            const std::size_t expected = (stations - 1) * frames_each * frame_size;
            std::thread talker([&] {
                for (int f = 0; f < frames_each; ++f) {
                    EXPECT_TRUE(ports[i]->write(Bytes(frame_size, static_cast<std::uint8_t>(i))));
                }
            });
            heard[i] = read_exactly(*ports[i], expected, 10s);
            talker.join();
        });
    }
    for (auto& thread : threads) thread.join();
    for (std::size_t i = 0; i < stations; ++i) {
        ASSERT_EQ(heard[i].size(), (stations - 1) * frames_each * frame_size) << "station " << i;
        for (std::size_t at = 0; at < heard[i].size(); at += frame_size) {
            const auto start = heard[i].begin() + static_cast<std::ptrdiff_t>(at);
            const Bytes frame(start, start + static_cast<std::ptrdiff_t>(frame_size));
            EXPECT_EQ(frame, Bytes(frame_size, frame[0])) << "interleaved frame at " << at;
            EXPECT_NE(frame[0], i) << "station heard itself";
        }
    }
}

}  // namespace
}  // namespace loopwire::transport
