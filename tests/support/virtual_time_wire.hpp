#pragma once
// A serial line in virtual time, for soaks on the lines' loop (session/line_loop.hpp built on a
// VirtualClock): a master's end and the devices' end, each a ByteStream whose poll handle turns
// readable at the virtual instant its bytes have crossed the wire. A frame takes its wire time
// (one character per character time, after whatever is still on the wire); its bytes arrive
// together when its last one has left. What the devices send goes through a fault function,
// which may drop, delay, repeat or change it; hang_up() makes both ends fail as a pulled
// USB-RS485 adapter does.
//
// Writes and deliveries run on the loop's thread: the ends are used by a serial master on that
// loop and by simulation::SimulatedLines, and a delivery is a deadline on the loop.
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "codec/rtu.hpp"
#include "common/bytes.hpp"
#include "session/line_loop.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::testing {

struct WireDelivery {
    Instant at;
    Bytes bytes;
};
// The frame the devices sent, and when its last byte left: what reaches the master, and when.
using ReplyFault = std::function<std::vector<WireDelivery>(Bytes frame, Instant sent)>;

class VirtualTimeWire : public std::enable_shared_from_this<VirtualTimeWire> {
public:
    // `loop` outlives the wire's ends (its pending deliveries hold the wire, not the loop).
    static std::shared_ptr<VirtualTimeWire> create(session::LineLoop& loop, codec::CharacterTiming timing, ReplyFault fault) {
        return std::shared_ptr<VirtualTimeWire>(new VirtualTimeWire(loop, timing, std::move(fault)));
    }
    ~VirtualTimeWire() {
        for (const int handle : handles_) ::close(handle);
    }
    VirtualTimeWire(const VirtualTimeWire&) = delete;
    VirtualTimeWire& operator=(const VirtualTimeWire&) = delete;

    enum Side : std::size_t { master = 0, devices = 1 };

    std::unique_ptr<transport::ByteStream> end(Side side) { return std::make_unique<End>(shared_from_this(), side); }

    // On the loop: both ends fail from now on, and a wait on either wakes to find out.
    void hang_up() {
        std::lock_guard lock(mutex_);
        hung_up_ = true;
        signal(master);
        signal(devices);
    }

private:
    VirtualTimeWire(session::LineLoop& loop, codec::CharacterTiming timing, ReplyFault fault)
        : loop_(loop), timing_(timing), fault_(std::move(fault)),
          handles_{::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC), ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)} {}

    class End final : public transport::ByteStream {
    public:
        End(std::shared_ptr<VirtualTimeWire> wire, Side side) : wire_(std::move(wire)), side_(side) {}
        Result<void> write(ByteView bytes) override {
            if (auto sent = wire_->send(side_, bytes); !sent) return sent.error();
            return {};
        }
        Result<Instant> write_without_waiting(ByteView bytes) override { return wire_->send(side_, bytes); }
        Result<std::size_t> read_some(std::span<std::uint8_t> buffer, std::chrono::milliseconds /*timeout*/) override {
            return wire_->take(side_, buffer);
        }
        void discard_input() override { wire_->discard(side_); }
        int poll_handle() const override { return wire_->handles_[side_]; }
        std::string describe() const override { return side_ == master ? "virtual-time wire (master)" : "virtual-time wire (devices)"; }

    private:
        std::shared_ptr<VirtualTimeWire> wire_;
        Side side_;
    };

    static Side other(Side side) { return side == master ? devices : master; }

    Result<Instant> send(Side from, ByteView bytes) {
        std::vector<WireDelivery> deliveries;
        Instant sent;
        {
            std::lock_guard lock(mutex_);
            if (hung_up_) return make_error(ErrorKind::link, "virtual-time wire: the adapter was unplugged");
            const Instant start = std::max(loop_.clock()->now(), free_at_);
            free_at_ = start + timing_.character_time() * static_cast<int>(bytes.size());
            sent = free_at_;
        }
        Bytes frame(bytes.begin(), bytes.end());
        if (from == devices && fault_) {
            deliveries = fault_(std::move(frame), sent);
        } else {
            deliveries.push_back({sent, std::move(frame)});
        }
        for (auto& delivery : deliveries) {
            loop_.wait(-1, delivery.at, [wire = shared_from_this(), to = other(from), bytes = std::move(delivery.bytes)] {
                wire->arrive(to, bytes);
            });
        }
        return sent;
    }

    void arrive(Side to, const Bytes& bytes) {
        std::lock_guard lock(mutex_);
        if (hung_up_) return;
        inbox_[to].insert(inbox_[to].end(), bytes.begin(), bytes.end());
        signal(to);
    }

    Result<std::size_t> take(Side side, std::span<std::uint8_t> buffer) {
        std::lock_guard lock(mutex_);
        if (hung_up_) return make_error(ErrorKind::link, "virtual-time wire: the adapter was unplugged");
        Bytes& inbox = inbox_[side];
        const std::size_t count = std::min(buffer.size(), inbox.size());
        std::copy_n(inbox.begin(), count, buffer.begin());
        inbox.erase(inbox.begin(), inbox.begin() + static_cast<std::ptrdiff_t>(count));
        if (inbox.empty()) drain(side);
        return count;
    }

    void discard(Side side) {
        std::lock_guard lock(mutex_);
        inbox_[side].clear();
        if (!hung_up_) drain(side);
    }

    void signal(Side side) const {
        const std::uint64_t one = 1;
        [[maybe_unused]] const auto written = ::write(handles_[side], &one, sizeof one);
    }
    void drain(Side side) const {
        std::uint64_t count = 0;
        [[maybe_unused]] const auto read = ::read(handles_[side], &count, sizeof count);
    }

    session::LineLoop& loop_;
    const codec::CharacterTiming timing_;
    const ReplyFault fault_;
    const std::array<int, 2> handles_;
    std::mutex mutex_;
    std::array<Bytes, 2> inbox_;
    Instant free_at_{};
    bool hung_up_ = false;
};

}  // namespace loopwire::testing
