// A day of plant time on a gateway's lines and polls, in virtual time: 4 lines
// of 3 simulated devices, each device polled every 5 s, 20 clients reading and writing at random
// through the Modbus TCP front's units, a front writing by name, while the wires spoil 5 % of the
// devices' replies (late, repeated, bit-flipped, cut short, garbage), adapters are pulled for
// minutes, devices fall silent for minutes, and eleven reloads hand the lines over at once
// (whatever is queued or on the wire) to a new set of the gateway's parts. Everything that carries the lines and the polls
// runs as in the gateway: the lines' loop (here on a VirtualClock, so it jumps from deadline to
// deadline), a serial master on it per line, the line's ReopeningMaster and LineScheduler, the
// devices served by simulation::SimulatedLines on the same loop, and on that loop too
// (LineLoopEvents) the gateway's PollGroups and ValueCache, reading each device by parameter
// name through its profile, and its DeviceWriter, with the HTTP API's and the MQTT front's
// handlers writing through it as they do for a POST or a /set message (hostile ones among them).
// The clients' requests go through a ForwardingUnit per device, as the Modbus TCP front hands
// them on (with its ReadCache on two of the lines); only the sockets are left out.
//
// Asserted: no request or poll is ever answered with a reply that is not its own (every register
// of every device holds a value no other register has, every write's echo is checked, and a
// client reads back what it wrote, never the value before), no device reads `ok` (in the
// cache's snapshot, in what its subscribers - MQTT, history, the dashboard - were last told, or
// in the HTTP API's answer) while its poll is overdue by more than two intervals, every device
// answers its polls again within one back-off after each outage ends, the polls keep their rate
// outside the outages, a write by name to a device that can answer ends within a bound however
// the other lines fare, whichever front it came through, a hostile body or
// payload is refused with an answer in JSON, every MQTT command is answered, requests of a
// closed connection are dropped unsent, and the queues stay bounded.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "codec/rtu.hpp"
#include "gateway/device_writer.hpp"
#include "gateway/event_loop.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/http_api.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/mqtt_commands.hpp"
#include "gateway/poll_groups.hpp"
#include "gateway/reopening_master.hpp"
#include "gateway/value_cache.hpp"
#include "profile/profile.hpp"
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
// The register a front writes by name ("setting"), away from the polled ones and the clients'.
constexpr std::uint16_t setting_register = 0x2000;
// How often a front writes by name, to a device picked at random, and how long such a write
// may take on a line whose device can answer: behind the request on the wire and a late reply's
// silence, with a spoiled reply of its own failing it by its timeout.
constexpr Duration write_every = 7s;
constexpr Duration write_bound = 2s;
// The fronts a write by name comes through.
enum WriteFront { by_writer, by_http, by_mqtt, write_fronts };
constexpr std::array<const char*, write_fronts> front_names{"DeviceWriter", "HTTP", "MQTT"};
constexpr const char* http_token = "soak-token";
constexpr const char* mqtt_prefix = "soak";
// How old a reply the units of lines 2 and 3 may answer a client's read with (modbus_tcp max_age).
constexpr Duration read_cache_age = 2s;
// A reload (SIGHUP with the lines unchanged) eleven times in the soak (every 2 h
// of a day, every 20 min of the sanitizers' 4 h): the lines are handed over at once, whatever is
// queued or on the wire, and the gateway's parts above them (polls, cache, writer, the HTTP and
// MQTT handlers) opened again over the same lines.
constexpr int reload_count = 11;
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
constexpr Duration reload_every = plant_time / (reload_count + 1);

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

// The profile the polls read line `line`'s devices by: p0 ... p9, the words at holding registers
// 0 ... 9, as plain numbers. One per line, so that a sample's device label ("soak2@3") names its line.
std::shared_ptr<const device::Profile> soak_profile(int line) {
    std::string parameters = fmt::format(
        R"({{"name": "setting", "table": "holding", "address": {}, "type": "uint16", "unitless": "raw", "access": "rw", "source": "soak"}})",
        setting_register);
    for (int address = 0; address < polled_registers; ++address) {
        parameters += fmt::format(R"(, {{"name": "p{}", "table": "holding", "address": {}, "type": "uint16", "unitless": "raw", "access": "r", "source": "soak"}})",
                                  address, address);
    }
    const auto text = fmt::format(
        R"({{"id": "soak{}", "title": "soak device", "manual": {{"file": "none", "document": "none"}}, "protocols": ["rtu"],
            "serial_defaults": {{"baud": 19200, "data_bits": 8, "parity": "none", "stop_bits": 1}}, "function_codes": [3, 6],
            "limits": {{"read_registers": 16, "write_registers": 16}}, "unmapped_reads": "exception",
            "addressing": {{"numbering": "wire addresses"}}, "identification": {{"match": [{{"parameter": "p0", "equals": 0}}]}},
            "parameters": [{}]}})",
        line, parameters);
    auto profile = device::load_profile_text(text, fmt::format("soak{}.json", line));
    if (!profile) throw std::runtime_error(profile.error().message);
    return std::make_shared<const device::Profile>(std::move(*profile));
}

// The configured name of unit `unit` on line `line`.
std::string device_name(int line, int unit) { return fmt::format("line{}-unit{}", line, unit); }

// The gateway's configuration of the soak's lines: every device polled for p0 ... p9.
GatewayConfig soak_config() {
    GatewayConfig config;
    config.source = "soak";
    for (int line = 0; line < line_count; ++line) {
        LineConfig configured;
        configured.name = fmt::format("line{}", line);
        configured.link = *transport::parse_link_url("rtu:virtual?baud=19200&parity=none");
        const auto profile = soak_profile(line);
        for (int unit = 1; unit <= units_per_line; ++unit) {
            DeviceConfig device;
            device.name = device_name(line, unit);
            device.address = {profile, static_cast<std::uint8_t>(unit)};
            device.poll = std::chrono::duration_cast<std::chrono::milliseconds>(poll_interval);
            // Each register holds a value no other register of any unit holds (signature), so no
            // word reads the same on every unit of a line's profile: the polls take the units as
            // they are (identification is the wrong-device tests').
            device.identify = false;
            for (int address = 0; address < polled_registers; ++address) device.parameters.push_back(fmt::format("p{}", address));
            configured.devices.push_back(std::move(device));
        }
        config.lines.push_back(std::move(configured));
    }
    HttpConfig http;
    http.token = http_token;
    config.http = http;
    MqttConfig mqtt;
    mqtt.prefix = mqtt_prefix;
    mqtt.writes = true;
    config.mqtt = mqtt;
    return config;
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
    std::uint16_t holding(std::uint16_t address) const { return bank_.get(codec::Table::holding_registers, address); }

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
    std::uint64_t polls_held = 0;        // the unit was backing off, or its poll never went out
    std::uint64_t samples_missed = 0;    // slots of a group's schedule skipped: a sample ran past its interval
    // Checks of a device whose last answered poll was more than two intervals overdue, and of
    // those, the ones where it still read `ok` (in the snapshot or in what subscribers were told).
    std::uint64_t overdue_checks = 0;
    std::uint64_t ok_while_overdue = 0;
    std::uint64_t api_overdue_checks = 0;  // of those, looked at through the HTTP API
    std::vector<std::string> ok_while_overdue_examples;
    std::uint64_t stale_told = 0;  // devices the subscribers were told are `stale`
    // Writes by name (DeviceWriter): confirmed, failed, refused as busy; the longest a write took
    // to a device no outage touched, and those that took longer than write_bound.
    std::uint64_t writes_by_name_confirmed = 0;
    std::uint64_t writes_by_name_failed = 0;
    std::uint64_t writes_by_name_refused = 0;
    std::uint64_t writes_to_silent_failed = 0;  // the bursts of writes to a silent device
    std::array<std::uint64_t, write_fronts> writes_by_front{};  // ended, by the front they came through
    std::uint64_t hostile_writes = 0;                           // refused, as they must be
    Duration longest_write_by_name{};
    std::vector<std::string> slow_writes;
    std::uint64_t requests_answered = 0;
    std::uint64_t requests_failed = 0;
    std::uint64_t writes_confirmed = 0;
    std::uint64_t read_backs = 0;  // writes read back as written
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
    std::uint64_t abandoned = 0;  // clients' requests dropped unsent: their connection had closed
    std::uint64_t reloads = 0;    // the gateway's parts reopened over the kept lines (SIGHUP)
    std::uint64_t handed_over_asked = 0;  // requests queued or on the wire when their line was handed over
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

// A write by name a front was asked for.
struct FrontWrite {
    Instant asked;
    int line = 0;
    int unit = 1;
    std::uint16_t value = 0;
    WriteFront front = by_writer;
    bool hostile = false;  // a body or payload that must be refused
};

class LineSoak {
public:
    LineSoak() : loop_(std::make_shared<session::LineLoop>(clock_)), simulated_(loop_) {
        for (int index = 0; index < line_count; ++index) lines_.push_back(std::make_unique<Line>(*this, index));
    }
    ~LineSoak() {
        close_parts();
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
        open_parts();
        loop_->post([this, start, length, &day] { begin(start, length, day); });
        // The day, and the reloads it asks for on the way (a reload takes the parts down, which
        // waits for the loop: not on the loop's own thread, as in the gateway).
        const auto give_up = std::chrono::steady_clock::now() + 15min;
        for (;;) {
            std::unique_lock lock(reload_mutex_);
            reload_asked_.wait_until(lock, give_up, [this] { return reload_hold_ || day_over_; });
            if (day_over_) break;
            if (!reload_hold_) {
                ADD_FAILURE() << "the soak did not end in 15 minutes of wall time";
                std::abort();  // the loop still refers to `day`
            }
            auto hold = std::exchange(reload_hold_, nullptr);
            lock.unlock();
            reload(std::move(hold));
        }
        return ended.get();
    }

    const std::vector<Outage>& outages() const { return outages_; }

private:
    // The gateway's parts above the lines, as Gateway::open makes them.
    void open_parts() {
        cache_ = std::make_unique<ValueCache>(clock_, [this] { return events_.wall_now(); });
        told_ = cache_->subscribe([this](const ValueChange& change) { told(change); });
        std::map<std::string, std::shared_ptr<LineScheduler>> schedulers;
        for (const auto& line : lines_) schedulers[fmt::format("line{}", line->index)] = line->scheduler;
        polls_ = std::make_unique<PollGroups>(events_, config_, schedulers, *cache_, GatewayLog{}, &samples_);
        std::vector<WritableDevice> writable;
        for (const auto& line : config_.lines) {
            for (const auto& device : line.devices) writable.push_back({device.name, device.address, schedulers.at(line.name)});
        }
        writer_ = std::make_unique<DeviceWriter>(events_, std::move(writable), std::chrono::milliseconds(10000));
        // As the gateway has it: a write to a device its polls find silent is refused at once.
        writer_->refuse_silent(cache_->device_lookup());
        api_ = std::make_unique<HttpApi>(config_, HttpApiSources{cache_.get(), writer_.get(), {}, {}, nullptr});
        mqtt_ = std::make_unique<MqttCommands>(
            *config_.mqtt, *writer_, [this](std::string topic, std::string payload) { mqtt_published(topic, payload); }, GatewayLog{});
    }

    // As ~Gateway takes them down: the handlers, then the writer, the polls and the cache.
    void close_parts() {
        api_.reset();
        mqtt_.reset();    // waits for its writes under way: they end on the loop
        writer_.reset();  // its writes and the polls' reads on the lines end first
        polls_.reset();
        told_.reset();
        cache_.reset();
    }

    // On the loop, at each reload: the clock held still while the test's thread reopens the parts
    // (in the gateway a reload takes no plant time either), and the loop's own work leaves the
    // parts alone meanwhile.
    void ask_reload() {
        reloading_ = true;
        std::lock_guard lock(reload_mutex_);
        reload_hold_ = loop_->hold_time();
        reload_asked_.notify_all();
    }

    // On the test's thread, as Gateway::hand_over_to and the next Gateway::open do it: every line
    // handed over at once (what is queued or on the wire is answered "reloading", and a reply
    // still to come reaches no one), the parts above reopened, the lines resumed.
    void reload(std::shared_ptr<void> hold) {
        std::uint64_t asked = 0;
        for (const auto& line : lines_) {
            asked += line->scheduler->statistics().asked;
            line->scheduler->hand_over();
        }
        close_parts();
        open_parts();
        for (const auto& line : lines_) line->scheduler->resume();
        loop_->post([this, asked, hold = std::move(hold)]() mutable {
            reloading_ = false;
            ++tally_.reloads;
            tally_.handed_over_asked += asked;
            hold.reset();
        });
    }

    struct Line {
        Line(LineSoak& soak_, int line_index) : soak(soak_), index(line_index), faults(static_cast<unsigned>(line_index) + 1) {
            for (int unit = 1; unit <= units_per_line; ++unit) devices.push_back(std::make_shared<Device>(index, unit));
            master = std::make_shared<ReopeningMaster>(
                fmt::format("line{}", index), link().to_string(), [this] { return open(); }, ReopenSchedule{}, soak.clock_,
                [this](const std::string& said) { log(said); }, LinkConcurrency::on_loop, soak.loop_);
            scheduler = std::make_shared<LineScheduler>(master, LineSchedulerOptions{}, soak.clock_);
            for (int unit = 1; unit <= units_per_line; ++unit) {
                ForwardingSettings settings;
                settings.line_unit = static_cast<std::uint8_t>(unit);
                if (index >= 2) settings.max_age = std::chrono::duration_cast<std::chrono::milliseconds>(read_cache_age);
                front_units.push_back(std::make_unique<ForwardingUnit>(scheduler, settings, soak.clock_));
            }
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
        std::shared_ptr<LineScheduler> scheduler;  // after the master: goes first
        std::vector<std::unique_ptr<ForwardingUnit>> front_units;  // the Modbus TCP front's, per unit: go first
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
                // A repeater or relay that sends a reply again hundreds of milliseconds later,
                // dozens of exchanges on: the copy is known by its bytes, not by being recent.
                return {{sent, frame}, {sent + std::chrono::milliseconds(std::uniform_int_distribution<int>(150, 350)(random)), frame}};
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
        for (int client = 1; client <= client_count; ++client) at(start + std::chrono::milliseconds(client * 97), [this, client] { ask(client); });
        at(start, [this] { watch_queues(); });
        at(start, [this] { watch_staleness(); });
        at(start + write_every, [this] { write_by_name(); });
        for (Instant reload = start + reload_every; reload < start + length; reload += reload_every) {
            // Every client asks just before: the reload finds requests queued and on the wire.
            at(reload - 30ms, [this] {
                for (int client = 1; client <= client_count; ++client) read_anywhere(client);
            });
            at(reload, [this] { ask_reload(); });
        }
        at(start + length / 6, [this] { tally_.resident_settled = resident_bytes(); });
        at(start + length, [this, &day] { end_day(day); });
    }

    void begin_outage(const Outage& outage) {
        Line& line = *lines_[static_cast<std::size_t>(outage.line)];
        if (outage.kind == Outage::unplugged) return line.unplug(outage.until);
        line.devices[static_cast<std::size_t>(outage.unit - 1)]->fall_silent(true);
        write_to_silent(outage);
    }

    // Every 30 s while a device is silent, ten writes by name to it at once (an operator trying
    // again and again): each is refused at once once the polls find the device silent, waits out
    // its timeout on that line before they do, and none may hold up a write to another line.
    void write_to_silent(const Outage& outage) {
        const std::string name = device_name(outage.line, outage.unit);
        for (int write = 0; write < 10 && !reloading_; ++write) {
            const bool queued = writer_->write_async(name, {{"setting", "1"}}, [this, name, outage](Result<WrittenValues> written) {
                if (over_) return;
                if (!written) return void(++tally_.writes_to_silent_failed);
                // The last ones may be sent once the device answers again; not before.
                if (clock_->now() >= outage.until) return;
                wrong("a write by name to " + name + " was confirmed while the device was silent");
            });
            if (!queued) ++tally_.writes_by_name_refused;
        }
        if (clock_->now() + 30s < outage.until) at(clock_->now() + 30s, [this, outage] { write_to_silent(outage); });
    }

    void end_outage(const Outage& outage) {
        if (outage.kind == Outage::silent) lines_[static_cast<std::size_t>(outage.line)]->devices[static_cast<std::size_t>(outage.unit - 1)]->fall_silent(false);
        // An unplugged adapter is back once the line's next reopening finds it.
    }

    // On the loop, as each poll group's sample ends (PollGroups' `also` sink): every device's
    // values checked against its registers, and its answer or failure counted.
    void sampled(const device::SampleView& sample) {
        tally_.samples_missed += sample.missed;
        for (const auto& watched : *sample.devices) {
            const auto [line, unit] = line_and_unit(watched.label);
            for (std::size_t address = 0; address < watched.values.size(); ++address) {
                const auto& value = watched.values[address];
                if (!value.fresh || !value.last) continue;
                const auto expected = signature(line, unit, static_cast<int>(address));
                const auto* number = std::get_if<double>(&value.last->value);
                if (value.last->raw == expected && number && *number == expected) continue;
                wrong(fmt::format("poll of {} on line {}: p{} read {}, expected {}; the line's last frames:\n  {}", watched.label, line,
                                  address, value.last->raw, expected,
                                  fmt::join(lines_[static_cast<std::size_t>(line)]->recent_frames, "\n  ")));
            }
            count_poll(line, unit, watched);
        }
    }

    // "line2-unit3" (soak_config): the index of line 2's unit 3 in the tally's vectors.
    static std::size_t device_index(const std::string& name) {
        const auto dash = name.find("-unit");
        return static_cast<std::size_t>(std::stoi(name.substr(4, dash - 4)) * units_per_line + std::stoi(name.substr(dash + 5)) - 1);
    }

    // "soak2@3": line 2, unit 3 (soak_profile).
    static std::pair<int, int> line_and_unit(const std::string& label) {
        const auto at_sign = label.find('@');
        return {std::stoi(label.substr(4, at_sign - 4)), std::stoi(label.substr(at_sign + 1))};
    }

    void count_poll(int line, int unit, const device::WatchedDevice& watched) {
        const std::size_t device = static_cast<std::size_t>(line * units_per_line + unit - 1);
        switch (watched.status) {
            case device::DeviceStatus::ok:
                ++tally_.polls_answered;
                tally_.answered_polls[device].push_back(clock_->now());
                return;
            case device::DeviceStatus::waiting:
                ++tally_.polls_held;
                return note_after_outage(line, unit, "poll held or not sent: " + watched.last_error);
            default:
                ++tally_.polls_failed;
                return note_after_outage(line, unit, fmt::format("poll {}: {}", device::status_text(watched.status), watched.last_error));
        }
    }

    // On the loop: what the cache's subscribers (MQTT, the history, the dashboard) were told.
    void told(const ValueChange& change) {
        if (!change.about_device()) return;
        told_status_[device_index(change.device)] = change.status;
        if (change.status == "stale") ++tally_.stale_told;
    }

    // Every second of plant time: a device whose last answered poll is more than two intervals
    // overdue (three old: its next poll was due one interval after it) must not read `ok`, in the
    // snapshot at once, and for the subscribers once the staleness watch has looked (every
    // staleness_tick) - with a little room for what runs at the same instant.
    void watch_staleness() {
        const Instant now = clock_->now();
        const Duration overdue = poll_interval * (1 + overdue_intervals_allowed);
        const Duration watch_room = staleness_tick(std::chrono::duration_cast<std::chrono::milliseconds>(poll_interval)) + 100ms;
        at(now + 1s, [this] { watch_staleness(); });
        if (reloading_) return;
        for (const auto& cached : cache_->snapshot()) {
            const std::size_t device = device_index(cached.name);
            const auto& answered = tally_.answered_polls[device];
            if (answered.empty() || now - answered.back() <= overdue) continue;
            ++tally_.overdue_checks;
            const bool snapshot_ok = cached.state.status == device::DeviceStatus::ok;
            const bool told_ok = now - answered.back() > overdue + watch_room && told_status_[device] == "ok";
            const std::string api_status = status_in_api(cached.name);
            if (!snapshot_ok && !told_ok && api_status != "ok") continue;
            ++tally_.ok_while_overdue;
            if (tally_.ok_while_overdue_examples.size() < 5) {
                tally_.ok_while_overdue_examples.push_back(fmt::format("{} at {} ms: last answered {} ms before, snapshot says {}, "
                                                                       "subscribers were told {}, the HTTP API says {}",
                                                                       cached.name, milliseconds_at(now),
                                                                       std::chrono::duration_cast<std::chrono::milliseconds>(now - answered.back()).count(),
                                                                       device::status_text(cached.state.status), told_status_[device], api_status));
            }
        }
    }

    // GET /api/devices/NAME's status, as the dashboard and any HTTP client read it.
    std::string status_in_api(const std::string& device) {
        ++tally_.api_overdue_checks;
        HttpRequest request;
        request.method = "GET";
        request.host = "127.0.0.1";
        request.path = "/api/devices/" + device;
        const auto body = nlohmann::json::parse(api_->handle(request).response.body, nullptr, false);
        return body.is_object() ? body.value("status", std::string("none")) : std::string("not JSON");
    }

    // Every write_every: a front writes a random value by name to a random device's "setting":
    // in turn the DeviceWriter itself, HTTP's POST /api/devices/NAME/write and MQTT's
    // PREFIX/NAME/setting/set, each through the front's own handler (only the sockets are left
    // out). One HTTP or MQTT write in five is hostile (not JSON, not a number, out of range, an
    // unknown name, bytes that are not text, too long): it must be refused, with an answer that
    // is JSON. A write confirmed must have landed in the device; one to a device no outage
    // touched must end within write_bound, whatever the other lines do.
    void write_by_name() {
        const Instant asked = clock_->now();
        at(asked + write_every, [this] { write_by_name(); });
        if (reloading_) return;
        FrontWrite write;
        write.asked = asked;
        write.line = std::uniform_int_distribution<int>(0, line_count - 1)(clients_random_);
        write.unit = std::uniform_int_distribution<int>(1, units_per_line)(clients_random_);
        write.value = static_cast<std::uint16_t>(clients_random_());
        write.front = static_cast<WriteFront>(writes_by_name_++ % write_fronts);
        write.hostile = write.front != by_writer && std::uniform_int_distribution<int>(0, 4)(clients_random_) == 0;
        if (write.front == by_http) return write_over_http(write);
        if (write.front == by_mqtt) return write_over_mqtt(write);
        const bool queued = writer_->write_async(device_name(write.line, write.unit), {{"setting", std::to_string(write.value)}},
                                                 [this, write](Result<WrittenValues> written) {
                                                     write_ended(write, written ? std::string() : written.error().message);
                                                 });
        if (!queued) ++tally_.writes_by_name_refused;
    }

    // What a hostile HTTP body or MQTT payload is, picked at random.
    std::string hostile_value(WriteFront front) {
        static const std::array<std::string, 6> http_bodies{"\xff\xfe{", R"({"setting": "12abc"})", R"({"setting": 70000})",
                                                            R"({"no_such_parameter": 1})", R"([1, 2])", R"({"setting": {"a": [1]}})"};
        static const std::array<std::string, 6> mqtt_payloads{"\xff\xfe", "12abc", "70000", "", "-1", std::string(2000, '7')};
        const auto any = std::uniform_int_distribution<std::size_t>(0, 5)(clients_random_);
        return front == by_http ? http_bodies[any] : mqtt_payloads[any];
    }

    void write_over_http(const FrontWrite& write) {
        HttpRequest request;
        request.method = "POST";
        request.host = "127.0.0.1";
        request.path = fmt::format("/api/devices/{}/write", device_name(write.line, write.unit));
        request.authorization = fmt::format("Bearer {}", http_token);
        request.body = write.hostile ? hostile_value(by_http) : fmt::format(R"({{"setting": {}}})", write.value);
        HttpOutcome outcome = api_->handle(request);
        const auto answered = [this, write](const HttpResponse& response) {
            if (over_) return;
            const auto body = nlohmann::json::parse(response.body, nullptr, false);
            if (body.is_discarded()) return wrong(fmt::format("HTTP write answered {} with a body that is not JSON: {}", response.status, response.body));
            write_ended(write, response.status == 200 ? std::string() : body.value("error", fmt::format("status {}", response.status)));
        };
        if (!outcome.deferred) return answered(outcome.response);
        outcome.deferred([this, answered](HttpResponse response) {
            loop_->post([answered, response = std::move(response)] { answered(response); });
        });
    }

    void write_over_mqtt(const FrontWrite& write) {
        const std::string topic = fmt::format("{}/{}/setting/set", mqtt_prefix, device_name(write.line, write.unit));
        const std::string payload = write.hostile ? hostile_value(by_mqtt) : std::to_string(write.value);
        mqtt_taking_ = write;
        mqtt_->take(topic, payload);
        // Not answered at once: its result comes once the line has answered, in the order taken.
        if (mqtt_taking_) mqtt_pending_[topic + "/result"].push_back(write);
        mqtt_taking_.reset();
    }

    // A set/result document the MQTT front publishes: for the command being taken (refused at
    // once), or for the oldest one of its topic under way. Completions run on the loop.
    void mqtt_published(const std::string& topic, const std::string& payload) {
        if (over_) return;
        std::optional<FrontWrite> write = std::exchange(mqtt_taking_, std::nullopt);
        if (!write) {
            auto& pending = mqtt_pending_[topic];
            if (pending.empty()) return wrong(fmt::format("an MQTT result no command waited for: {} {}", topic, payload));
            write = pending.front();
            pending.pop_front();
        }
        const auto result = nlohmann::json::parse(payload, nullptr, false);
        if (result.is_discarded() || !result.contains("ok")) return wrong(fmt::format("an MQTT result that is not a result document: {}", payload));
        write_ended(*write, result.value("ok", false) ? std::string() : result.value("error", std::string("no error given")));
    }

    // A write by name ended, confirmed (no error) or not, whichever front it came through.
    void write_ended(const FrontWrite& write, const std::string& error) {
        if (over_) return;
        const Instant ended = clock_->now();
        const std::string name = device_name(write.line, write.unit);
        const auto& device = *lines_[static_cast<std::size_t>(write.line)]->devices[static_cast<std::size_t>(write.unit - 1)];
        if (write.hostile) {
            ++tally_.hostile_writes;
            if (error.empty()) wrong(fmt::format("a hostile write by {} to {} was confirmed", front_names[write.front], name));
            return;
        }
        ++tally_.writes_by_front[write.front];
        if (error.empty()) {
            ++tally_.writes_by_name_confirmed;
            if (device.holding(setting_register) != write.value) {
                wrong(fmt::format("write by name ({}) of {} to {} confirmed, the device holds {}", front_names[write.front], write.value, name,
                                  device.holding(setting_register)));
            }
        } else {
            ++tally_.writes_by_name_failed;
        }
        // Any outage on the write's own line: its writes go one after the other, so a write to a
        // silent device's neighbour waits for the writes to the silent device before it.
        const bool touched = std::any_of(outages_.begin(), outages_.end(), [&](const Outage& outage) {
            return outage.line == write.line && outage.from < ended && outage.until + longest_backoff > write.asked;
        });
        if (touched) return;
        tally_.longest_write_by_name = std::max(tally_.longest_write_by_name, ended - write.asked);
        if (ended - write.asked > write_bound && tally_.slow_writes.size() < 5) {
            tally_.slow_writes.push_back(fmt::format("write by name ({}) to {} at {} ms took {} ms: {}", front_names[write.front], name,
                                                     milliseconds_at(write.asked),
                                                     std::chrono::duration_cast<std::chrono::milliseconds>(ended - write.asked).count(),
                                                     error.empty() ? std::string("confirmed") : error));
        }
    }

    // A client's next request, 1 to 20 s after its last was sent, through the device's
    // ForwardingUnit as the Modbus TCP front forwards it (the units of lines 2 and 3 answer reads
    // from their ReadCache up to read_cache_age old): mostly a read of 1 to 16 registers
    // anywhere, sometimes a read-modify-write of its own register.
    void ask(int client) {
        at(clock_->now() + std::chrono::milliseconds(std::uniform_int_distribution<int>(1000, 20000)(clients_random_)),
           [this, client] { ask(client); });
        const int line = std::uniform_int_distribution<int>(0, line_count - 1)(clients_random_);
        const int unit = std::uniform_int_distribution<int>(1, units_per_line)(clients_random_);
        // One read-modify-write at a time: a second one's write could land between the first
        // one's write and its read-back.
        auto& modifying = modifying_[static_cast<std::size_t>(client - 1)];
        if (std::uniform_int_distribution<int>(0, 99)(clients_random_) < 15 && !modifying) {
            modifying = true;
            return read_modify_write(client, line, unit);
        }
        read(client, line, unit);
    }

    void read_anywhere(int client) {
        const int line = std::uniform_int_distribution<int>(0, line_count - 1)(clients_random_);
        read(client, line, std::uniform_int_distribution<int>(1, units_per_line)(clients_random_));
    }

    // A read of 1 to 16 registers anywhere in the unit, its reply checked.
    void read(int client, int line, int unit) {
        const auto count = static_cast<std::uint16_t>(std::uniform_int_distribution<int>(1, 16)(clients_random_));
        const auto address = static_cast<std::uint16_t>(std::uniform_int_distribution<int>(0, 1023 - count)(clients_random_));
        send(client, line, unit, read_pdu(address, count), [this, line, expected = expected_read(line, unit, address, count)](std::optional<Bytes> reply) {
            if (!answered(reply)) return;
            if (judge(*reply, expected, "read", line)) ++tally_.requests_answered;
        });
    }

    // A SCADA client's read-modify-write of its own register: read it, write a new value once
    // the read is answered, and read it back once the echo confirms the write. With the unit's
    // cache the first read is kept; the read-back must still get the value written, never the
    // one kept from before.
    void read_modify_write(int client, int line, int unit) {
        const auto own = static_cast<std::uint16_t>(0x1000 + client);
        const auto value = static_cast<std::uint16_t>(clients_random_());
        // Ends the read-modify-write, whatever its outcome.
        const auto done = [this, client] { modifying_[static_cast<std::size_t>(client - 1)] = false; };
        send(client, line, unit, read_pdu(own, 1), [this, client, line, unit, own, value, done](std::optional<Bytes> before) {
            // What it held is not known (a write whose echo was spoiled may have landed): the
            // read is there for the cache to keep.
            if (!answered(before)) return done();
            ++tally_.requests_answered;
            Bytes write{0x06, static_cast<std::uint8_t>(own >> 8), static_cast<std::uint8_t>(own), static_cast<std::uint8_t>(value >> 8),
                        static_cast<std::uint8_t>(value)};
            const std::string what = fmt::format("read-back at {} ms of unit {} (read {:02x} before the write)", milliseconds_at(clock_->now()), unit, fmt::join(*before, " "));
            send(client, line, unit, write, [this, client, line, unit, own, value, write, done, what](std::optional<Bytes> echo) {
                if (!answered(echo) || !judge(*echo, write, "write", line)) return done();
                ++tally_.requests_answered;
                ++tally_.writes_confirmed;
                const Bytes written{0x03, 2, static_cast<std::uint8_t>(value >> 8), static_cast<std::uint8_t>(value)};
                send(client, line, unit, read_pdu(own, 1), [this, line, written, done, what](std::optional<Bytes> after) {
                    done();
                    if (!answered(after) || !judge(*after, written, what.c_str(), line)) return;
                    ++tally_.requests_answered;
                    ++tally_.read_backs;
                });
            });
        });
    }

    // One request of a client, judged on the loop. One in 20 comes from a connection that closes
    // 10 ms after sending it: dropped unsent if the line has not taken it by then.
    void send(int client, int line, int unit, Bytes pdu, std::function<void(std::optional<Bytes>)> judged) {
        session::UnitHandler::Asker asker(static_cast<std::uint64_t>(client));
        if (std::uniform_int_distribution<int>(0, 19)(clients_random_) == 0) {
            auto open = std::make_shared<std::atomic<bool>>(true);
            at(clock_->now() + 10ms, [open] { *open = false; });
            asker.still_wanted = open;
        }
        auto& forwarding = *lines_[static_cast<std::size_t>(line)]->front_units[static_cast<std::size_t>(unit - 1)];
        // A reply runs where the scheduler's master ends the request (the loop, or a line's
        // reopening worker) or at once from the unit's cache: it is judged on the loop, after.
        forwarding.handle_async(std::move(pdu), false, asker, [this, judged = std::move(judged)](std::optional<Bytes> reply) mutable {
            loop_->post([judged = std::move(judged), reply = std::move(reply)]() mutable { judged(std::move(reply)); });
        });
    }

    // Whether the device answered a request, rather than the gateway telling why it could not
    // (0Ah, 0Bh, 06h exception replies); counted failed if not.
    bool answered(const std::optional<Bytes>& reply) {
        if (reply && !reply->empty() && ((*reply)[0] & 0x80) == 0) return true;
        ++tally_.requests_failed;
        return false;
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

    // A wrong value counted, and the first few kept to be shown.
    void wrong(std::string example) {
        ++tally_.wrong;
        if (tally_.wrong_examples.size() < 5) tally_.wrong_examples.push_back(std::move(example));
    }

    bool judge(const Bytes& reply, const Bytes& expected, const char* what, int line) {
        if (reply == expected) return true;
        wrong(fmt::format("{} on line {}: got {:02x}, expected {:02x}; the line's last frames:\n  {}", what, line, fmt::join(reply, " "),
                          fmt::join(expected, " "), fmt::join(lines_[static_cast<std::size_t>(line)]->recent_frames, "\n  ")));
        return false;
    }

    void watch_queues() {
        for (const auto& line : lines_) tally_.most_queued = std::max(tally_.most_queued, line->scheduler->statistics().queued);
        at(clock_->now() + 1min, [this] { watch_queues(); });
    }

    void end_day(std::promise<Tally>& day) {
        // Every MQTT command is answered: by the writer's limit (10 s) at the latest.
        for (const auto& [topic, pending] : mqtt_pending_) {
            for (const FrontWrite& write : pending) {
                if (clock_->now() - write.asked > 15s) wrong(fmt::format("MQTT command to {} at {} ms never answered", topic, milliseconds_at(write.asked)));
            }
        }
        over_ = true;
        for (const auto& line : lines_) {
            const auto statistics = line->scheduler->statistics();
            tally_.bad_replies += statistics.bad_replies;
            tally_.timeouts += statistics.timeouts;
            tally_.abandoned += statistics.abandoned;
            tally_.reopened += line->master->health().reopened;
            tally_.line_log[static_cast<std::size_t>(line->index)] = line->said();
        }
        tally_.resident_at_end = resident_bytes();
        day.set_value(tally_);
        std::lock_guard lock(reload_mutex_);
        day_over_ = true;
        reload_asked_.notify_all();
    }

    // The polls' `also` sink: each sample, on the loop.
    struct Samples final : device::SampleSink {
        explicit Samples(LineSoak& soak_) : soak(soak_) {}
        void write(const device::SampleView& sample) override {
            if (!soak.over_) soak.sampled(sample);
        }
        LineSoak& soak;
    };

    std::shared_ptr<VirtualClock> clock_ = std::make_shared<VirtualClock>();
    std::vector<Outage> outages_;
    const GatewayConfig config_ = soak_config();
    // The loop's only (before the loop: what it still runs while the soak is taken down uses them):
    Tally tally_;
    std::mt19937 clients_random_{7};
    std::array<bool, client_count> modifying_{};  // a client's read-modify-write is under way
    std::array<std::string, line_count * units_per_line> told_status_;
    bool over_ = false;
    bool reloading_ = false;  // the parts are being reopened on the test's thread: leave them alone
    Samples samples_{*this};
    std::shared_ptr<session::LineLoop> loop_;
    simulation::SimulatedLines simulated_;
    std::vector<std::unique_ptr<Line>> lines_;  // after the devices' lines: goes first
    // The gateway's polls and their cache, on the lines' loop and its clock.
    LineLoopEvents events_{loop_};
    std::unique_ptr<ValueCache> cache_;
    ValueSubscription told_;
    std::unique_ptr<PollGroups> polls_;
    std::unique_ptr<DeviceWriter> writer_;
    // The HTTP API's and the MQTT front's handlers, on the loop, writing through the writer.
    std::unique_ptr<HttpApi> api_;
    std::unique_ptr<MqttCommands> mqtt_;
    std::uint64_t writes_by_name_ = 0;
    std::optional<FrontWrite> mqtt_taking_;                         // the command take() is answering
    std::map<std::string, std::deque<FrontWrite>> mqtt_pending_;  // by result topic, oldest first
    // Between the loop and the test's thread: a reload asked for (the clock held meanwhile), the day's end.
    std::mutex reload_mutex_;
    std::condition_variable reload_asked_;
    std::shared_ptr<void> reload_hold_;
    bool day_over_ = false;
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
                "samples missed; %llu checks of a device overdue (%llu read ok), %llu told stale; client requests %llu answered "
                "(%llu writes confirmed, %llu read back), %llu failed; %zu outages; replies spoiled:",
                hours, wall, static_cast<unsigned long long>(tally.polls_answered), static_cast<unsigned long long>(tally.polls_failed),
                static_cast<unsigned long long>(tally.polls_held), static_cast<unsigned long long>(tally.samples_missed),
                static_cast<unsigned long long>(tally.overdue_checks), static_cast<unsigned long long>(tally.ok_while_overdue),
                static_cast<unsigned long long>(tally.stale_told),
                static_cast<unsigned long long>(tally.requests_answered), static_cast<unsigned long long>(tally.writes_confirmed),
                static_cast<unsigned long long>(tally.read_backs),
                static_cast<unsigned long long>(tally.requests_failed), outages.size());
    for (int kind = 0; kind < spoil_kinds; ++kind) {
        std::printf(" %llu %s", static_cast<unsigned long long>(tally.spoiled[static_cast<std::size_t>(kind)]), spoiled_names[static_cast<std::size_t>(kind)]);
    }
    std::printf("; writes by name %llu confirmed, %llu failed, %llu refused, %llu to silent devices failed, longest %lld ms "
                "outside outages",
                static_cast<unsigned long long>(tally.writes_by_name_confirmed), static_cast<unsigned long long>(tally.writes_by_name_failed),
                static_cast<unsigned long long>(tally.writes_by_name_refused), static_cast<unsigned long long>(tally.writes_to_silent_failed),
                static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(tally.longest_write_by_name).count()));
    std::printf(" (by front: %llu DeviceWriter, %llu HTTP, %llu MQTT; %llu hostile ones refused); %llu overdue checks through the HTTP API",
                static_cast<unsigned long long>(tally.writes_by_front[by_writer]), static_cast<unsigned long long>(tally.writes_by_front[by_http]),
                static_cast<unsigned long long>(tally.writes_by_front[by_mqtt]), static_cast<unsigned long long>(tally.hostile_writes),
                static_cast<unsigned long long>(tally.api_overdue_checks));
    std::printf("; lines: %llu bad replies, %llu timeouts, %llu dropped for a closed connection, %llu reopenings; most queued %zu; resident memory %.1f MiB "
                "settled, %.1f MiB at the end; %llu reloads (%llu clients' requests and writes waiting or on the wire "
                "answered at once); wrong values %llu\n",
                static_cast<unsigned long long>(tally.bad_replies), static_cast<unsigned long long>(tally.timeouts),
                static_cast<unsigned long long>(tally.abandoned),
                static_cast<unsigned long long>(tally.reopened), tally.most_queued, static_cast<double>(tally.resident_settled) / 1048576.0,
                static_cast<double>(tally.resident_at_end) / 1048576.0, static_cast<unsigned long long>(tally.reloads),
                static_cast<unsigned long long>(tally.handed_over_asked),
                static_cast<unsigned long long>(tally.wrong));

    EXPECT_EQ(tally.wrong, 0U) << fmt::format("{}", fmt::join(tally.wrong_examples, "\n"));
    // The faults happened, and were seen for what they are.
    for (const auto spoiled : tally.spoiled) EXPECT_GT(spoiled, 10U);
    EXPECT_GT(tally.bad_replies, 0U);
    EXPECT_GT(tally.timeouts, 0U);
    EXPECT_GT(tally.abandoned, 0U);
    EXPECT_GE(tally.reopened, 1U);
    EXPECT_EQ(tally.reloads, static_cast<std::uint64_t>(reload_count));
    EXPECT_LE(tally.most_queued, LineSchedulerOptions{}.max_queued);
    // A sample ends well inside its interval (three reads of 300 ms at most): one that ran past
    // it waited on something outside plant time (a request handed to a reopening worker without
    // the loop's time held; on a loaded machine 36 to 594 polls, and a line back 13 min after its
    // outage).
    EXPECT_EQ(tally.samples_missed, 0U);
    // No device read `ok` while its poll was overdue, and the outages made them overdue.
    EXPECT_EQ(tally.ok_while_overdue, 0U) << fmt::format("{}", fmt::join(tally.ok_while_overdue_examples, "\n"));
    EXPECT_GT(tally.overdue_checks, 0U);
    // Writes by name: each line's own, never waiting for another line's.
    EXPECT_LE(tally.longest_write_by_name, write_bound) << fmt::format("{}", fmt::join(tally.slow_writes, "\n"));
    EXPECT_EQ(tally.writes_by_name_refused, 0U);
    // Each front wrote (HTTP's and MQTT's handlers on the same loop), and the hostile bodies and
    // payloads were all refused (a confirmed one counts as a wrong value above).
    for (const auto ended : tally.writes_by_front) EXPECT_GT(static_cast<double>(ended), 100 * hours);
    EXPECT_GT(static_cast<double>(tally.hostile_writes), 50 * hours);
    EXPECT_EQ(tally.api_overdue_checks, tally.overdue_checks);
    EXPECT_GE(static_cast<double>(tally.writes_by_name_confirmed),
              0.9 * static_cast<double>(tally.writes_by_name_confirmed + tally.writes_by_name_failed));
    // The writes queued for silent devices all failed, and were many (some 40 an hour).
    EXPECT_GT(static_cast<double>(tally.writes_to_silent_failed), 15 * hours);
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
