// A day of plant time on a gateway's lines, in virtual time (issue 20's soak, the lines' half):
// 4 lines of 3 simulated devices, each device polled every 5 s, 20 clients reading and writing
// at random through the lines' schedulers, while the wires spoil 5 % of the devices' replies
// (late, repeated, bit-flipped, cut short, garbage), adapters are pulled for minutes and devices
// fall silent for minutes. Everything that carries the lines runs as in the gateway: the lines'
// loop (here on a VirtualClock, so it jumps from deadline to deadline), a serial master on it per
// line, the line's ReopeningMaster and LineScheduler, and the devices served by
// simulation::SimulatedLines on the same loop. What a Modbus TCP client or a poll group would do
// with a reply is done by the test, on the loop.
//
// Asserted: no request is ever answered with a reply that is not its own (every register of
// every device holds a value no other register has, and every write's echo is checked), every
// device answers its polls again within one back-off after each outage ends, the polls keep
// their rate outside the outages, and the queues stay bounded.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <deque>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <future>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "codec/rtu.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/reopening_master.hpp"
#include "session/line_loop.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulated_lines.hpp"
#include "support/virtual_time_wire.hpp"
#include "transport/link_url.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using Duration = Instant::duration;

constexpr int line_count = 4;
constexpr int units_per_line = 3;
constexpr int client_count = 20;
constexpr Duration poll_interval = 5s;
constexpr Duration reply_timeout = 300ms;
constexpr Duration client_deadline = 1s;
constexpr std::uint16_t polled_registers = 10;
// The longest wait between two reopenings of a line, and between two polls of a unit that backs
// off (ReopenSchedule, LineSchedulerOptions: 1 s doubling to 30 s).
constexpr Duration longest_backoff = 30s;
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool sanitized = true;
#else
constexpr bool sanitized = false;
#endif
// A sanitizer's build runs some ten times slower.
constexpr Duration plant_time = sanitized ? Duration(4h) : Duration(24h);

// Holding register `address` of unit `unit` on line `line` (address < 1024): a value no other
// register of any device holds, so a reply that answers another request never passes for this one.
std::uint16_t signature(int line, int unit, int address) {
    return static_cast<std::uint16_t>((line << 13) | (unit << 10) | address);
}

Bytes read_pdu(std::uint16_t address, std::uint16_t count) {
    return Bytes{0x03, static_cast<std::uint8_t>(address >> 8), static_cast<std::uint8_t>(address),
                 static_cast<std::uint8_t>(count >> 8), static_cast<std::uint8_t>(count)};
}

Bytes expected_read(int line, int unit, std::uint16_t address, std::uint16_t count) {
    Bytes reply{0x03, static_cast<std::uint8_t>(2 * count)};
    for (std::uint16_t offset = 0; offset < count; ++offset) {
        const std::uint16_t value = signature(line, unit, address + offset);
        reply.push_back(static_cast<std::uint8_t>(value >> 8));
        reply.push_back(static_cast<std::uint8_t>(value));
    }
    return reply;
}

// A device that answers as its register bank does, unless it has fallen silent.
class Device final : public session::UnitHandler {
public:
    Device(int line, int unit) {
        for (int address = 0; address < 1024; ++address) {
            bank_.set(codec::Table::holding_registers, static_cast<std::uint16_t>(address), signature(line, unit, address));
        }
    }
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override {
        if (silent_.load()) return std::nullopt;
        return bank_.handle(request_pdu, broadcast);
    }
    void fall_silent(bool silent) { silent_ = silent; }

private:
    session::RegisterBank bank_;
    std::atomic<bool> silent_{false};
};

// What the wires did to the devices' replies.
enum Spoiled { late, repeated, flipped, cut_short, garbage, spoil_kinds };
constexpr std::array<const char*, spoil_kinds> spoiled_names{"late", "repeated", "bit-flipped", "cut short", "garbage"};

long long milliseconds_at(Instant at) {
    return static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(at.time_since_epoch()).count());
}

struct Noted {
    Instant at;
    std::string what;
};

// What was noted in [from, until), one line each with its time.
std::string noted_between(const std::vector<Noted>& notes, Instant from, Instant until) {
    std::string text;
    for (const auto& note : notes) {
        if (note.at >= from && note.at < until) text += fmt::format("\n  {} ms {}", milliseconds_at(note.at), note.what);
    }
    return text;
}

// Everything counted, on the loop's thread only (copied out when the day ends).
struct Tally {
    std::uint64_t polls_answered = 0;
    std::uint64_t polls_failed = 0;
    std::uint64_t polls_held = 0;        // the unit was backing off
    std::uint64_t polls_overlapping = 0;  // the previous poll had not ended
    std::uint64_t requests_answered = 0;
    std::uint64_t requests_failed = 0;
    std::uint64_t writes_confirmed = 0;
    std::uint64_t wrong = 0;
    std::vector<std::string> wrong_examples;
    std::array<std::uint64_t, spoil_kinds> spoiled{};
    std::vector<std::vector<Instant>> answered_polls = std::vector<std::vector<Instant>>(line_count * units_per_line);
    // When a reply of each device was spoiled: a poll that fails so keeps the device in back-off.
    std::vector<std::vector<Instant>> spoiled_replies = std::vector<std::vector<Instant>>(line_count * units_per_line);
    std::size_t most_queued = 0;
    std::uint64_t reopened = 0;
    std::uint64_t bad_replies = 0;
    std::uint64_t timeouts = 0;
    // The process's resident memory once the lines have settled (a sixth of the way in), and at
    // the end of the day.
    std::size_t resident_settled = 0;
    std::size_t resident_at_end = 0;
    // What the lines logged (reopening_master.hpp: down, still down, up again) and why each
    // device's polls failed in the five minutes after each outage: shown for a device that came
    // back late.
    std::vector<std::vector<Noted>> line_log = std::vector<std::vector<Noted>>(line_count);
    std::vector<std::vector<Noted>> failed_after_outage = std::vector<std::vector<Noted>>(line_count * units_per_line);
};

std::size_t resident_bytes() {
    std::FILE* statm = std::fopen("/proc/self/statm", "r");
    if (statm == nullptr) return 0;
    unsigned long size = 0;
    unsigned long resident = 0;
    const int read = std::fscanf(statm, "%lu %lu", &size, &resident);
    std::fclose(statm);
    return read == 2 ? static_cast<std::size_t>(resident) * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE)) : 0;
}

struct Outage {
    enum Kind { unplugged, silent } kind;
    int line;
    int unit;  // silent: the device; unplugged: every device of the line
    Instant from;
    Instant until;
    bool affects(int other_line, int other_unit) const {
        return line == other_line && (kind == unplugged || unit == other_unit);
    }
};

// An adapter pulled every 2 hours on the next line in turn, for 1 to 3 minutes, and a device
// silent every 90 minutes, for 1 to 5 minutes; starting 10 minutes in.
std::vector<Outage> outages_for(Instant start, Duration length, std::mt19937& random) {
    std::vector<Outage> outages;
    std::uniform_int_distribution<int> minutes_unplugged(60, 180);
    std::uniform_int_distribution<int> minutes_silent(60, 300);
    std::uniform_int_distribution<int> any_line(0, line_count - 1);
    std::uniform_int_distribution<int> any_unit(1, units_per_line);
    int next_line = 0;
    for (Duration at = 10min; at + 10min < length; at += 2h) {
        const Instant from = start + at;
        outages.push_back({Outage::unplugged, next_line++ % line_count, 0, from, from + std::chrono::seconds(minutes_unplugged(random))});
    }
    for (Duration at = 55min; at + 10min < length; at += 90min) {
        const Instant from = start + at;
        outages.push_back({Outage::silent, any_line(random), any_unit(random), from, from + std::chrono::seconds(minutes_silent(random))});
    }
    return outages;
}

class LineSoak {
public:
    LineSoak() : loop_(std::make_shared<session::LineLoop>(clock_)), simulated_(loop_) {
        for (int index = 0; index < line_count; ++index) lines_.push_back(std::make_unique<Line>(*this, index));
    }
    ~LineSoak() {
        lines_.clear();  // schedulers, then masters (each closes its serial master on the loop)
    }

    Tally run(Duration length) {
        std::mt19937 random(20);
        const Instant start = clock_->now();
        outages_ = outages_for(start, length, random);
        for (auto& line : lines_) {
            if (!line->master->start().ok()) ADD_FAILURE() << "line " << line->index << " did not start";
        }
        std::promise<Tally> day;
        auto ended = day.get_future();
        loop_->post([this, start, length, &day] { begin(start, length, day); });
        if (ended.wait_for(15min) != std::future_status::ready) {
            ADD_FAILURE() << "the soak did not end in 15 minutes of wall time";
            std::abort();  // the loop still refers to `day`
        }
        return ended.get();
    }

    const std::vector<Outage>& outages() const { return outages_; }

private:
    struct Line {
        Line(LineSoak& soak_, int line_index) : soak(soak_), index(line_index), faults(static_cast<unsigned>(line_index) + 1) {
            for (int unit = 1; unit <= units_per_line; ++unit) devices.push_back(std::make_shared<Device>(index, unit));
            master = std::make_shared<ReopeningMaster>(
                fmt::format("line{}", index), link().to_string(), [this] { return open(); }, ReopenSchedule{}, soak.clock_,
                [this](const std::string& said) { log(said); }, LinkConcurrency::on_loop, soak.loop_);
            scheduler = std::make_unique<LineScheduler>(master, LineSchedulerOptions{}, soak.clock_);
        }

        static transport::LinkUrl link() { return *transport::parse_link_url("rtu:virtual?baud=19200&parity=none"); }

        // On the line's reopening worker (and at start): a new wire, unless the adapter is out.
        Result<std::unique_ptr<session::Master>> open() {
            std::lock_guard lock(mutex);
            if (soak.clock_->now() < unplugged_until) return make_error(ErrorKind::link, "no such device (the adapter is unplugged)");
            const auto url = link();
            wire = testing::VirtualTimeWire::create(*soak.loop_, codec::CharacterTiming{url.serial.baud, url.serial.bits_per_character()},
                                                   [this](Bytes frame, Instant sent) { return soak.spoil(index, faults, std::move(frame), sent); });
            session::UnitMap units;
            for (int unit = 1; unit <= units_per_line; ++unit) units[static_cast<std::uint8_t>(unit)] = devices[static_cast<std::size_t>(unit - 1)];
            if (auto served = soak.simulated_.add(wire->end(testing::VirtualTimeWire::devices), std::make_unique<session::Slave>(url, units)); !served) {
                return served.error();
            }
            session::MasterOptions options;
            options.timeout = std::chrono::duration_cast<std::chrono::milliseconds>(reply_timeout);
            options.loop = soak.loop_;
            options.trace = [this](const session::TraceEvent& event) { remember(event); };
            return session::make_serial_master(wire->end(testing::VirtualTimeWire::master), url, options);
        }

        // On the loop: the master's last frames, shown with a wrong value.
        void remember(const session::TraceEvent& event) {
            static constexpr const char* directions[] = {"sent", "received", "discarded"};
            const auto at = milliseconds_at(event.at);
            recent_frames.push_back(fmt::format("{} ms {} {:02x} ({})", at, directions[static_cast<int>(event.direction)],
                                                fmt::join(event.bytes, " "), event.note));
            if (recent_frames.size() > 24) recent_frames.pop_front();
        }

        // On the loop or the line's reopening worker.
        void log(const std::string& said) {
            std::lock_guard lock(log_mutex);
            said_.push_back({soak.clock_->now(), said});
        }
        std::vector<Noted> said() {
            std::lock_guard lock(log_mutex);
            return said_;
        }

        // On the loop.
        void unplug(Instant until) {
            std::lock_guard lock(mutex);
            unplugged_until = until;
            if (wire) wire->hang_up();
        }

        LineSoak& soak;
        const int index;
        std::vector<std::shared_ptr<Device>> devices;
        std::mt19937 faults;  // the loop's only
        std::deque<std::string> recent_frames;  // the loop's only
        std::mutex mutex;     // guards wire and unplugged_until: open() runs on the reopening worker
        std::shared_ptr<testing::VirtualTimeWire> wire;
        Instant unplugged_until{};
        std::mutex log_mutex;  // guards said_
        std::vector<Noted> said_;
        std::shared_ptr<ReopeningMaster> master;
        std::unique_ptr<LineScheduler> scheduler;  // after the master: goes first
    };

    // On the loop, for every frame a device sends: 5 % of them spoiled, evenly among the kinds.
    std::vector<testing::WireDelivery> spoil(int line, std::mt19937& random, Bytes frame, Instant sent) {
        const int roll = std::uniform_int_distribution<int>(0, 99)(random);
        if (roll >= 5 || frame.size() < 2) return {{sent, std::move(frame)}};
        const auto kind = static_cast<Spoiled>(roll);
        ++tally_.spoiled[kind];
        if (frame[0] >= 1 && frame[0] <= units_per_line) {
            tally_.spoiled_replies[static_cast<std::size_t>(line * units_per_line + frame[0] - 1)].push_back(sent);
        }
        std::uniform_int_distribution<std::size_t> any_byte(0, frame.size() - 1);
        switch (kind) {
            case late:
                // After the master's timeout, within its late-reply window (MasterOptions::
                // late_reply_window: as long as the timeout unless set): RTU has no transaction id,
                // so a reply later than that cannot be told from the next request's of the same
                // shape, and the window is what a user widens for such a device. The window
                // runs from the end of the request, the delay here from the end of the reply,
                // which the request, the device's turnaround and the reply itself (up to 37
                // characters, 21 ms at 19200 baud) come before: 480 ms at most keeps a late
                // reply inside 600 ms with room to spare. (550 ms did not, now and then: a
                // client's read was answered with the late reply to another client's read of
                // the same unit and length.)
                return {{sent + std::chrono::milliseconds(std::uniform_int_distribution<int>(350, 550)(random)), std::move(frame)}};
            case repeated:
                return {{sent, frame}, {sent + 40ms, frame}};
            case flipped:
                frame[any_byte(random)] ^= static_cast<std::uint8_t>(1U << std::uniform_int_distribution<unsigned>(0, 7)(random));
                return {{sent, std::move(frame)}};
            case cut_short:
                frame.resize(std::uniform_int_distribution<std::size_t>(1, frame.size() - 1)(random));
                return {{sent, std::move(frame)}};
            case garbage:
                for (auto& byte : frame) byte = static_cast<std::uint8_t>(random());
                return {{sent, std::move(frame)}};
            case spoil_kinds:
                break;
        }
        return {{sent, std::move(frame)}};
    }

    // --- the day, on the loop ----------------------------------------------------------------

    void at(Instant when, std::function<void()> work) {
        loop_->wait(-1, when, [this, work = std::move(work)] {
            if (!over_) work();
        });
    }

    void begin(Instant start, Duration length, std::promise<Tally>& day) {
        for (const auto& outage : outages_) {
            at(outage.from, [this, outage] { begin_outage(outage); });
            at(outage.until, [this, outage] { end_outage(outage); });
        }
        for (int line = 0; line < line_count; ++line) {
            for (int unit = 1; unit <= units_per_line; ++unit) at(start, [this, line, unit, start] { poll(line, unit, start); });
        }
        for (int client = 1; client <= client_count; ++client) at(start + std::chrono::milliseconds(client * 97), [this, client] { ask(client); });
        at(start, [this] { watch_queues(); });
        at(start + length / 6, [this] { tally_.resident_settled = resident_bytes(); });
        at(start + length, [this, &day] { end_day(day); });
    }

    void begin_outage(const Outage& outage) {
        Line& line = *lines_[static_cast<std::size_t>(outage.line)];
        if (outage.kind == Outage::unplugged) return line.unplug(outage.until);
        line.devices[static_cast<std::size_t>(outage.unit - 1)]->fall_silent(true);
    }
    void end_outage(const Outage& outage) {
        if (outage.kind == Outage::silent) lines_[static_cast<std::size_t>(outage.line)]->devices[static_cast<std::size_t>(outage.unit - 1)]->fall_silent(false);
        // An unplugged adapter is back once the line's next reopening finds it.
    }

    // A poll group's tick: the unit's registers, unless it is backing off or its last poll is
    // still on its way; the next tick one interval later, whatever happened.
    void poll(int line_index, int unit, Instant tick) {
        at(tick + poll_interval, [this, line_index, unit, tick] { poll(line_index, unit, tick + poll_interval); });
        Line& line = *lines_[static_cast<std::size_t>(line_index)];
        const std::size_t device = static_cast<std::size_t>(line_index * units_per_line + unit - 1);
        if (polling_[device]) return void(++tally_.polls_overlapping);
        if (const auto held = line.scheduler->hold_poll(static_cast<std::uint8_t>(unit))) {
            ++tally_.polls_held;
            return note_after_outage(line_index, unit, fmt::format("poll held until {} ms", milliseconds_at(*held)));
        }
        polling_[device] = true;
        LineRequest request;
        request.unit = static_cast<std::uint8_t>(unit);
        request.pdu = read_pdu(0, polled_registers);
        request.priority = Priority::poll;
        request.deadline = tick + poll_interval;
        request.done = completion([this, device, line_index, unit, expected = expected_read(line_index, unit, 0, polled_registers)](Result<Bytes> reply) {
            polling_[device] = false;
            if (!reply) {
                ++tally_.polls_failed;
                return note_after_outage(line_index, unit, "poll failed: " + reply.error().message);
            }
            if (!judge(*reply, expected, "poll", line_index)) return;
            ++tally_.polls_answered;
            tally_.answered_polls[device].push_back(clock_->now());
        });
        line.scheduler->submit(std::move(request));
    }

    // A client's next request, 1 to 20 s after its last was sent: mostly a read of 1 to 16
    // registers anywhere, sometimes a write of its own register, which the echo must confirm.
    void ask(int client) {
        at(clock_->now() + std::chrono::milliseconds(std::uniform_int_distribution<int>(1000, 20000)(clients_random_)),
           [this, client] { ask(client); });
        const int line = std::uniform_int_distribution<int>(0, line_count - 1)(clients_random_);
        const int unit = std::uniform_int_distribution<int>(1, units_per_line)(clients_random_);
        LineRequest request;
        request.unit = static_cast<std::uint8_t>(unit);
        request.priority = Priority::client;
        request.client = static_cast<std::uint64_t>(client);
        request.deadline = clock_->now() + client_deadline;
        Bytes expected;
        if (std::uniform_int_distribution<int>(0, 99)(clients_random_) < 15) {
            const auto address = static_cast<std::uint16_t>(0x1000 + client);
            const auto value = static_cast<std::uint16_t>(clients_random_());
            request.pdu = Bytes{0x06, static_cast<std::uint8_t>(address >> 8), static_cast<std::uint8_t>(address),
                                static_cast<std::uint8_t>(value >> 8), static_cast<std::uint8_t>(value)};
            expected = request.pdu;
        } else {
            const auto count = static_cast<std::uint16_t>(std::uniform_int_distribution<int>(1, 16)(clients_random_));
            const auto address = static_cast<std::uint16_t>(std::uniform_int_distribution<int>(0, 1023 - count)(clients_random_));
            request.pdu = read_pdu(address, count);
            expected = expected_read(line, unit, address, count);
        }
        const bool write = request.pdu[0] == 0x06;
        request.done = completion([this, expected, write, line](Result<Bytes> reply) {
            if (!reply) return void(++tally_.requests_failed);
            if (!judge(*reply, expected, write ? "write" : "read", line)) return;
            ++tally_.requests_answered;
            if (write) ++tally_.writes_confirmed;
        });
        lines_[static_cast<std::size_t>(line)]->scheduler->submit(std::move(request));
    }

    // On the loop: what happened to a device's poll, kept if an outage of the device ended in the
    // last five minutes.
    void note_after_outage(int line, int unit, const std::string& what) {
        const Instant now = clock_->now();
        const bool after_outage = std::any_of(outages_.begin(), outages_.end(), [&](const Outage& outage) {
            return outage.affects(line, unit) && now >= outage.until && now < outage.until + 5min;
        });
        if (!after_outage) return;
        tally_.failed_after_outage[static_cast<std::size_t>(line * units_per_line + unit - 1)].push_back({now, what});
    }

    bool judge(const Bytes& reply, const Bytes& expected, const char* what, int line) {
        if (reply == expected) return true;
        ++tally_.wrong;
        if (tally_.wrong_examples.size() < 5) {
            tally_.wrong_examples.push_back(fmt::format("{} on line {}: got {:02x}, expected {:02x}; the line's last frames:\n  {}", what, line,
                                                        fmt::join(reply, " "), fmt::join(expected, " "),
                                                        fmt::join(lines_[static_cast<std::size_t>(line)]->recent_frames, "\n  ")));
        }
        return false;
    }

    // A completion runs where the scheduler's master ends the request (the loop, or a line's
    // reopening worker): its outcome is judged on the loop, as the gateway's engine posts it.
    session::Master::ForwardCompletion completion(std::function<void(Result<Bytes>)> judged) {
        return [this, judged = std::move(judged)](Result<Bytes> reply) mutable {
            loop_->post([judged = std::move(judged), reply = std::move(reply)]() mutable { judged(std::move(reply)); });
        };
    }

    void watch_queues() {
        for (const auto& line : lines_) tally_.most_queued = std::max(tally_.most_queued, line->scheduler->statistics().queued);
        at(clock_->now() + 1min, [this] { watch_queues(); });
    }

    void end_day(std::promise<Tally>& day) {
        over_ = true;
        for (const auto& line : lines_) {
            const auto statistics = line->scheduler->statistics();
            tally_.bad_replies += statistics.bad_replies;
            tally_.timeouts += statistics.timeouts;
            tally_.reopened += line->master->health().reopened;
            tally_.line_log[static_cast<std::size_t>(line->index)] = line->said();
        }
        tally_.resident_at_end = resident_bytes();
        day.set_value(tally_);
    }

    std::shared_ptr<VirtualClock> clock_ = std::make_shared<VirtualClock>();
    std::vector<Outage> outages_;
    // The loop's only (before the loop: what it still runs while the soak is taken down uses them):
    Tally tally_;
    std::mt19937 clients_random_{7};
    std::array<bool, line_count * units_per_line> polling_{};
    bool over_ = false;
    std::shared_ptr<session::LineLoop> loop_;
    simulation::SimulatedLines simulated_;
    std::vector<std::unique_ptr<Line>> lines_;  // after the devices' lines: goes first
};

// The first poll a device answered at or after `from`, if any.
std::optional<Instant> first_answer(const std::vector<Instant>& answered, Instant from) {
    auto found = std::lower_bound(answered.begin(), answered.end(), from);
    if (found == answered.end()) return std::nullopt;
    return *found;
}

TEST(LineSoak, ADayOfFaultsOnFourLinesServesNoWrongValueAndEveryDeviceComesBack) {
    const auto wall_start = std::chrono::steady_clock::now();
    auto soak = std::make_unique<LineSoak>();
    const Tally tally = soak->run(plant_time);
    const auto outages = soak->outages();
    soak.reset();
    const auto wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

    const auto hours = std::chrono::duration<double, std::ratio<3600>>(plant_time).count();
    std::printf("line soak: %.0f h of plant time in %.1f s of wall time; polls %llu answered, %llu failed, %llu held back, %llu "
                "overlapping; client requests %llu answered (%llu writes confirmed), %llu failed; %zu outages; replies spoiled:",
                hours, wall, static_cast<unsigned long long>(tally.polls_answered), static_cast<unsigned long long>(tally.polls_failed),
                static_cast<unsigned long long>(tally.polls_held), static_cast<unsigned long long>(tally.polls_overlapping),
                static_cast<unsigned long long>(tally.requests_answered), static_cast<unsigned long long>(tally.writes_confirmed),
                static_cast<unsigned long long>(tally.requests_failed), outages.size());
    for (int kind = 0; kind < spoil_kinds; ++kind) {
        std::printf(" %llu %s", static_cast<unsigned long long>(tally.spoiled[static_cast<std::size_t>(kind)]), spoiled_names[static_cast<std::size_t>(kind)]);
    }
    std::printf("; lines: %llu bad replies, %llu timeouts, %llu reopenings; most queued %zu; resident memory %.1f MiB "
                "settled, %.1f MiB at the end; wrong values %llu\n",
                static_cast<unsigned long long>(tally.bad_replies), static_cast<unsigned long long>(tally.timeouts),
                static_cast<unsigned long long>(tally.reopened), tally.most_queued, static_cast<double>(tally.resident_settled) / 1048576.0,
                static_cast<double>(tally.resident_at_end) / 1048576.0, static_cast<unsigned long long>(tally.wrong));

    EXPECT_EQ(tally.wrong, 0U) << fmt::format("{}", fmt::join(tally.wrong_examples, "\n"));
    // The faults happened, and were seen for what they are.
    for (const auto spoiled : tally.spoiled) EXPECT_GT(spoiled, 10U);
    EXPECT_GT(tally.bad_replies, 0U);
    EXPECT_GT(tally.timeouts, 0U);
    EXPECT_GE(tally.reopened, 1U);
    EXPECT_LE(tally.most_queued, LineSchedulerOptions{}.max_queued);
    // A poll ends by its deadline, the next tick: one still in flight there waited on something
    // outside plant time (a request handed to a reopening worker without the loop's time held;
    // on a loaded machine 36 to 594 of them, and a line back 13 min after its outage).
    EXPECT_EQ(tally.polls_overlapping, 0U);
    // Memory stays put: what the rest of the day adds is the test's own record of the polls
    // (8 bytes each, some 1.6 MB in 24 h, doubled by a vector's growth), not the lines'. A leak
    // of 100 bytes a request would add 30 MB. Not under a sanitizer, whose runtime keeps freed
    // memory (ASan's quarantine) and shadows what was touched.
    ASSERT_GT(tally.resident_settled, 0U);
    if (!sanitized) {
        EXPECT_LT(tally.resident_at_end, tally.resident_settled + std::size_t{12} * 1024 * 1024);
    }

    // Every device answers again within one back-off (and the poll tick after it) once each of
    // its outages ends, unless another one of its outages has begun by then; or, if a reply of
    // the device was spoiled in the meantime (the first poll after the outage may be one of the
    // 5 %), within one back-off of that.
    const Duration allowed = longest_backoff + 2 * poll_interval + reply_timeout;
    for (const auto& outage : outages) {
        for (int line = 0; line < line_count; ++line) {
            for (int unit = 1; unit <= units_per_line; ++unit) {
                if (!outage.affects(line, unit)) continue;
                const bool overlapped = std::any_of(outages.begin(), outages.end(), [&](const Outage& other) {
                    return &other != &outage && other.affects(line, unit) && other.from < outage.until + allowed && other.until > outage.until;
                });
                if (overlapped) continue;
                const auto& answered = tally.answered_polls[static_cast<std::size_t>(line * units_per_line + unit - 1)];
                const auto back = first_answer(answered, outage.until);
                ASSERT_TRUE(back.has_value()) << "line " << line << " unit " << unit << " never answered after an outage";
                Instant since = outage.until;
                for (const Instant spoiled : tally.spoiled_replies[static_cast<std::size_t>(line * units_per_line + unit - 1)]) {
                    if (spoiled > since && spoiled < *back) since = spoiled;
                }
                EXPECT_LE(*back - since, allowed)
                    << "line " << line << " unit " << unit << " answered "
                    << std::chrono::duration_cast<std::chrono::milliseconds>(*back - outage.until).count()
                    << " ms after its outage ended, "
                    << std::chrono::duration_cast<std::chrono::milliseconds>(*back - since).count()
                    << " ms after the outage or the last spoiled reply since (outage " << milliseconds_at(outage.from) << " to "
                    << milliseconds_at(outage.until) << " ms)\nthe line's log:"
                    << noted_between(tally.line_log[static_cast<std::size_t>(line)], outage.from - 1min, *back)
                    << "\nthe device's polls that failed or were held since:"
                    << noted_between(tally.failed_after_outage[static_cast<std::size_t>(line * units_per_line + unit - 1)], outage.until, *back);
                // And not a poll was answered while the device could not answer.
                const auto during = first_answer(answered, outage.from + 1s);
                if (during) {
                    EXPECT_GE(*during, outage.until) << "line " << line << " unit " << unit << " answered while out";
                }
            }
        }
    }

    // Polls keep their rate: outside the outages (and the back-off after them), at least 90 %
    // of a device's ticks are answered, with 5 % of the replies spoiled.
    const double ticks = std::chrono::duration<double>(plant_time) / std::chrono::duration<double>(poll_interval);
    for (int device = 0; device < line_count * units_per_line; ++device) {
        Duration out{};
        for (const auto& outage : outages) {
            if (outage.affects(device / units_per_line, device % units_per_line + 1)) out += outage.until - outage.from + allowed;
        }
        const double expected = ticks * (1.0 - std::chrono::duration<double>(out) / std::chrono::duration<double>(plant_time));
        EXPECT_GE(static_cast<double>(tally.answered_polls[static_cast<std::size_t>(device)].size()), 0.9 * expected) << "device " << device;
    }
}

}  // namespace
}  // namespace loopwire::gateway
