#include "transport/virtual_bus.hpp"

#include <sys/timerfd.h>

#include <algorithm>
#include <cassert>
#include <condition_variable>
#include <deque>
#include <thread>

#include "transport/file_descriptor.hpp"

// Model (see also virtual_bus.hpp):
// - The wire is half-duplex and shared. A write starts at max(now, end of the transmission on
//   the wire) — concurrent writers are serialised, as if every station waited for silence
//   before talking, instead of modelling collisions. Byte i of a write becomes readable at
//   start + (i + 1) character times on every other port, never on the sender's.
// - write() returns once its last byte has left (like tcdrain on a real port), or at once on a
//   port attached with Writes::return_at_once.
// - Faults, decided per write by the test's injector: noise bytes go on the wire first and
//   take wire time; a dropped write still occupies the wire (the sender did transmit) but
//   reaches nobody; corrupt_bytes indexes past the end are ignored; extra_delay is latency
//   (a slow repeater): the bytes arrive later but neither the wire nor the sender waits longer.
//   A truncated write sends (and spends wire time on) its first truncate_to bytes only; a
//   duplicated one is queued a second time, duplicate_after after the first copy's start, as
//   latency: its bytes interleave with whatever else is due then, as on a real line they would
//   collide.
// - poll_handle() is a timerfd per port, armed for the earliest pending byte, so it becomes
//   readable exactly when read_some() would return data.

namespace loopwire::transport {

namespace {

using Clock = std::chrono::steady_clock;

struct PendingByte {
    Instant due;
    std::uint8_t value;
};

// The receiving side of one port.
struct Station {
    std::string name;
    std::deque<PendingByte> inbox;  // ordered by `due`
    detail::FileDescriptor timer;   // readable while inbox.front() is due
};

// Points the port's timerfd at its earliest pending byte, or disarms it. Re-arming also clears
// an expiry that was already signalled, so the descriptor is readable only while bytes are due.
void rearm(Station& station) {
    if (!station.timer.valid()) return;
    itimerspec setting{};
    if (!station.inbox.empty()) {
        // Relative to now: no assumption about which clock steady_clock reads. Never zero,
        // which would disarm the timer; a due time in the past fires at once.
        const auto wait = std::max(station.inbox.front().due - Clock::now(), Clock::duration{1});
        const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
        setting.it_value.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
        setting.it_value.tv_nsec = static_cast<long>(ns % 1'000'000'000);
        if (setting.it_value.tv_sec == 0 && setting.it_value.tv_nsec == 0) setting.it_value.tv_nsec = 1;
    }
    ::timerfd_settime(station.timer.get(), 0, &setting, nullptr);
}

void enqueue(Station& station, Instant due, std::uint8_t value) {
    // Delayed writes can land behind bytes sent later, so insert in order rather than append.
    auto at = std::upper_bound(station.inbox.begin(), station.inbox.end(), due,
                               [](Instant t, const PendingByte& b) { return t < b.due; });
    station.inbox.insert(at, PendingByte{due, value});
}

}  // namespace

struct VirtualBus::Impl {
    Impl(std::uint32_t baud_rate, unsigned bits) : baud(baud_rate), bits_per_character(bits) {}

    // How long `characters` characters take on the wire, rounded up to the nanosecond so an
    // arrival is never earlier than the exact wire time.
    std::chrono::nanoseconds wire_time(std::size_t characters) const {
        const auto numerator = static_cast<std::uint64_t>(characters) * bits_per_character * 1'000'000'000ULL;
        return std::chrono::nanoseconds((numerator + baud - 1) / baud);
    }

    // Puts `noise` then `payload` on the wire from `sender`; returns when the last byte leaves.
    Instant transmit(const Station& sender, ByteView noise, ByteView payload, const BusFault& fault);
    std::size_t take_due(Station& station, std::span<std::uint8_t> buffer, Instant now);

    const std::uint32_t baud;
    const unsigned bits_per_character;

    std::mutex mutex;
    std::condition_variable arrived;  // notified whenever bytes are queued for any port
    Instant wire_free{};              // end of the last scheduled transmission
    FaultInjector injector;
    std::vector<Station*> stations;
};

Instant VirtualBus::Impl::transmit(const Station& sender, ByteView noise, ByteView payload, const BusFault& fault) {
    std::lock_guard lock(mutex);
    const Instant start = std::max(Clock::now(), wire_free);
    const Instant end = start + wire_time(noise.size() + payload.size());
    wire_free = end;
    for (Station* station : stations) {
        if (station == &sender) continue;
        for (std::size_t i = 0; i < noise.size(); ++i) enqueue(*station, start + wire_time(i + 1), noise[i]);
        if (!fault.drop) {
            const Instant payload_start = start + wire_time(noise.size()) + fault.extra_delay;
            for (std::size_t i = 0; i < payload.size(); ++i) {
                enqueue(*station, payload_start + wire_time(i + 1), payload[i]);
            }
            if (fault.duplicate_after) {
                const Instant copy_start = payload_start + *fault.duplicate_after;
                for (std::size_t i = 0; i < payload.size(); ++i) {
                    enqueue(*station, copy_start + wire_time(i + 1), payload[i]);
                }
            }
        }
        rearm(*station);
    }
    arrived.notify_all();
    return end;
}

std::size_t VirtualBus::Impl::take_due(Station& station, std::span<std::uint8_t> buffer, Instant now) {
    std::size_t count = 0;
    while (count < buffer.size() && !station.inbox.empty() && station.inbox.front().due <= now) {
        buffer[count++] = station.inbox.front().value;
        station.inbox.pop_front();
    }
    if (count > 0) rearm(station);
    return count;
}

namespace {

class BusPort final : public ByteStream {
public:
    BusPort(std::shared_ptr<VirtualBus> bus, VirtualBus::Impl& impl, const std::string& name, VirtualBus::Writes writes)
        : bus_(std::move(bus)), impl_(impl), writes_(writes) {
        station_.name = name;
        station_.timer = detail::FileDescriptor(::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC));
        std::lock_guard lock(impl_.mutex);
        impl_.stations.push_back(&station_);
    }

    ~BusPort() override {
        std::lock_guard lock(impl_.mutex);
        std::erase(impl_.stations, &station_);
    }

    Result<void> write(ByteView bytes) override;
    Result<Instant> write_without_waiting(ByteView bytes) override;
    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, milliseconds timeout) override;
    void discard_input() override;
    int poll_handle() const override { return station_.timer.get(); }
    std::string describe() const override {
        return "virtual bus port '" + station_.name + "' (" + std::to_string(impl_.baud) + " baud, " +
               std::to_string(impl_.bits_per_character) + "-bit characters)";
    }

private:
    BusFault decide_fault(ByteView bytes);

    std::shared_ptr<VirtualBus> bus_;  // keeps impl_ alive
    VirtualBus::Impl& impl_;
    VirtualBus::Writes writes_;
    Station station_;
};

// The injector runs outside the bus lock (it is the test's code and may take its time or
// touch the bus); it may therefore be called from several writing threads at once.
BusFault BusPort::decide_fault(ByteView bytes) {
    FaultInjector injector;
    {
        std::lock_guard lock(impl_.mutex);
        injector = impl_.injector;
    }
    return injector ? injector(station_.name, bytes) : BusFault{};
}

Result<void> BusPort::write(ByteView bytes) {
    auto end = write_without_waiting(bytes);
    if (!end) return end.error();
    if (writes_ == VirtualBus::Writes::wait_for_wire) std::this_thread::sleep_until(*end);
    return {};
}

Result<Instant> BusPort::write_without_waiting(ByteView bytes) {
    if (bytes.empty()) return Clock::now();
    const BusFault fault = decide_fault(bytes);
    Bytes payload(bytes.begin(), bytes.end());
    for (const std::size_t index : fault.corrupt_bytes) {
        if (index < payload.size()) payload[index] ^= 0xFF;
    }
    if (fault.truncate_to && *fault.truncate_to < payload.size()) payload.resize(*fault.truncate_to);
    return impl_.transmit(station_, fault.noise_before, payload, fault);
}

Result<std::size_t> BusPort::read_some(std::span<std::uint8_t> buffer, milliseconds timeout) {
    if (buffer.empty()) return std::size_t{0};
    const Instant deadline = detail::deadline_after(timeout);
    std::unique_lock lock(impl_.mutex);
    for (;;) {
        const Instant now = Clock::now();
        if (const std::size_t count = impl_.take_due(station_, buffer, now); count > 0) return count;
        if (now >= deadline) return std::size_t{0};
        Instant wake = deadline;
        if (!station_.inbox.empty()) wake = std::min(wake, station_.inbox.front().due);
        impl_.arrived.wait_until(lock, wake);
    }
}

// Like tcflush(TCIFLUSH): drops what has arrived; bytes still on the wire arrive later.
void BusPort::discard_input() {
    std::lock_guard lock(impl_.mutex);
    const Instant now = Clock::now();
    while (!station_.inbox.empty() && station_.inbox.front().due <= now) station_.inbox.pop_front();
    rearm(station_);
}

}  // namespace

std::shared_ptr<VirtualBus> VirtualBus::create(std::uint32_t baud, unsigned bits_per_character) {
    assert(baud > 0 && bits_per_character > 0);
    return std::make_shared<VirtualBus>(std::make_unique<Impl>(baud, bits_per_character));
}

VirtualBus::VirtualBus(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VirtualBus::~VirtualBus() = default;

std::unique_ptr<ByteStream> VirtualBus::attach(const std::string& name, Writes writes) {
    return std::make_unique<BusPort>(shared_from_this(), *impl_, name, writes);
}

void VirtualBus::set_fault_injector(FaultInjector injector) {
    std::lock_guard lock(impl_->mutex);
    impl_->injector = std::move(injector);
}

std::chrono::microseconds VirtualBus::character_time() const {
    return std::chrono::round<std::chrono::microseconds>(impl_->wire_time(1));
}

}  // namespace loopwire::transport
