#include "simulation/simulated_device.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <vector>

namespace loopwire::device {
namespace {

constexpr std::uint8_t illegal_function = 1;
constexpr std::uint8_t illegal_data_address = 2;
constexpr std::uint8_t illegal_data_value = 3;

bool is_write(std::uint8_t function) { return function == 5 || function == 6 || function == 15 || function == 16; }
bool is_bit_function(std::uint8_t function) { return function == 1 || function == 2 || function == 5 || function == 15; }

bool supports(const Profile& profile, std::uint8_t function) {
    return std::find(profile.function_codes.begin(), profile.function_codes.end(), function) != profile.function_codes.end();
}

// profile.limits: the most items one request may name, per kind of request. FC5/FC6 name one.
std::optional<unsigned> limit_for(const Limits& limits, std::uint8_t function) {
    switch (function) {
        case 1: case 2: return limits.read_bits;
        case 3: case 4: return limits.read_registers;
        case 15: return limits.write_bits;
        case 16: return limits.write_registers;
        default: return std::nullopt;
    }
}

// A word written as a value whose special state is "dont-care" leaves the stored value alone
// (AC20 FC6/FC16: "The 8000h value ... should be considered as a don't care value"; profile
// word_specials). Raws compare both as int16 and as uint16, as in the profile.
bool is_dont_care(const Parameter& parameter, std::uint16_t raw) {
    return std::any_of(parameter.special.begin(), parameter.special.end(), [raw](const SpecialValue& special) {
        return special.state == "dont-care" &&
               (special.raw == raw || special.raw == static_cast<std::int16_t>(raw));
    });
}

struct StagedWrite {
    MemoryCell* cell = nullptr;
    std::uint16_t raw = 0;
};

}  // namespace

SimulatedDevice::SimulatedDevice(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : profile_(std::move(profile)),
      environment_(std::move(environment)),
      memory_(profile_),
      random_(environment_.seed),
      last_advance_(environment_.now()) {}

void SimulatedDevice::advance() {
    std::lock_guard lock(mutex_);
    advance_locked();
}

// The process catches up with the clock lazily, on each request: deterministic for a test
// that moves its clock by hand, and free while nobody asks. It walks a fixed grid of process
// time, max_process_step apart, carrying the remainder to the next request: with the same
// --seed the trajectory is the same however often (or seldom) clients poll. A pause longer
// than max_steps grid steps is walked in max_steps longer steps so a request never waits on the
// catch-up; the grid starts afresh after it.
void SimulatedDevice::advance_locked() {
    constexpr long long max_steps = 20000;
    // Sums of real seconds round differently for different poll patterns; this much slack
    // keeps them on the same grid step (1e-9 of a step over hours of process time).
    constexpr double grid_slack = 1e-9;
    const auto now = environment_.now();
    const double real = std::chrono::duration<double>(now - last_advance_).count();
    last_advance_ = now;
    if (real <= 0) return;
    pending_process_time_ += real * environment_.speed;
    long long steps = static_cast<long long>(std::floor(pending_process_time_ / max_process_step + grid_slack));
    if (steps <= 0) return;
    double step = max_process_step;
    if (steps > max_steps) {
        step = pending_process_time_ / max_steps;
        steps = max_steps;
    }
    for (long long i = 0; i < steps; ++i) step_process(step);
    const double walked = step * static_cast<double>(steps);
    process_time_ += walked;
    pending_process_time_ = std::max(0.0, pending_process_time_ - walked);
}

Result<void> SimulatedDevice::inject_fault(const std::string& fault) {
    const auto known = fault_names();
    if (fault != "none" && std::find(known.begin(), known.end(), fault) == known.end()) {
        return make_error(ErrorKind::usage,
                          known.empty() ? fmt::format("{} simulates no faults (asked for '{}')", profile_->id, fault)
                                        : fmt::format("{} knows no fault '{}'; it knows: {} (or none)", profile_->id,
                                                      fault, fmt::join(known, ", ")));
    }
    std::lock_guard lock(mutex_);
    advance_locked();
    apply_fault(fault);
    return {};
}

RawValues SimulatedDevice::saved_values() const {
    std::lock_guard lock(mutex_);
    return memory_.saved_values();
}

std::vector<std::string> SimulatedDevice::load_saved(const RawValues& saved) {
    std::lock_guard lock(mutex_);
    auto problems = memory_.load_saved(saved);
    describe_line();
    return problems;
}

std::optional<std::uint8_t> SimulatedDevice::answers_as() const {
    const int unit = answering_unit_.load();
    if (unit < 0) return std::nullopt;
    return static_cast<std::uint8_t>(unit);
}

void SimulatedDevice::answer_as(std::optional<std::uint8_t> unit) { answering_unit_.store(unit ? int{*unit} : -1); }

std::uint64_t SimulatedDevice::saved_generation() const {
    std::lock_guard lock(mutex_);
    return memory_.saved_generation() + condition_generation_;
}

RawValues SimulatedDevice::saved_condition() const {
    std::lock_guard lock(mutex_);
    return condition_at_power_off();
}

void SimulatedDevice::load_condition(const RawValues& condition) {
    std::lock_guard lock(mutex_);
    restore_condition(condition);
}

void SimulatedDevice::line_activity() {
    std::lock_guard lock(mutex_);
    on_line_activity();
}

std::uint16_t SimulatedDevice::value(std::string_view name) const {
    const MemoryCell* cell = memory_.cell(name);
    assert(cell != nullptr && "model names a parameter its profile lacks");
    return cell == nullptr ? 0 : cell->raw;
}

void SimulatedDevice::set_value(std::string_view name, std::uint16_t raw, Persistence persistence) {
    MemoryCell* cell = memory_.cell(name);
    assert(cell != nullptr && "model names a parameter its profile lacks");
    if (cell != nullptr) memory_.store(*cell, raw, persistence);
}

// profile.numberings: an alternative numbering (AC20 J-BUS, +1) is in force while its selecting
// parameter holds the selecting value (AC20 word 526). The word is read per request, so a
// switch takes effect with the request after the one that wrote it (AC20 "serial settings
// ... take effect after the reply").
std::uint16_t SimulatedDevice::numbering_offset() const {
    for (const NumberingAlternative& numbering : profile_->numberings) {
        const MemoryCell* selector = memory_.cell(numbering.selected_by_parameter);
        if (selector != nullptr && static_cast<std::int32_t>(selector->raw) == numbering.selected_by_value) {
            return static_cast<std::uint16_t>(numbering.offset);
        }
    }
    return 0;
}

MemoryCell* SimulatedDevice::find(Table table, std::uint16_t wire_address) {
    const std::uint16_t offset = numbering_offset();
    if (wire_address < offset) return nullptr;
    return memory_.find(table, static_cast<std::uint16_t>(wire_address - offset));
}

std::optional<Bytes> SimulatedDevice::refuse(std::uint8_t function, std::uint8_t code) const {
    return Bytes{static_cast<std::uint8_t>((function & 0x7F) | 0x80), code};
}

std::optional<std::uint8_t> SimulatedDevice::over_limit(ByteView request_pdu) const {
    const auto limit = limit_for(profile_->limits, request_pdu[0]);
    if (!limit || request_pdu.size() < 5) return std::nullopt;
    if (read_be16(request_pdu, 3) <= *limit) return std::nullopt;
    return profile_->limit_exception;  // AC20: 9; others 3 (profile limit_exception)
}

std::optional<Bytes> SimulatedDevice::handle(ByteView request_pdu, bool broadcast) {
    if (request_pdu.empty()) return std::nullopt;
    const std::uint8_t function = request_pdu[0];
    // Broadcast: executed only where the profile says the device does (AC20 Note 1, TC10 §3;
    // the ramp/soak manual describes none), only for writes, and never answered.
    if (broadcast && (!profile_->broadcast || !is_write(function))) return std::nullopt;
    std::lock_guard lock(mutex_);
    advance_locked();
    if (auto decided = intercept(request_pdu, broadcast)) return broadcast ? std::nullopt : *decided;
    if (!supports(*profile_, function)) {
        // AC20 "Error reply": no reply for an unimplemented function code; others: exception 1.
        if (profile_->silent_on_unsupported_function || broadcast) return std::nullopt;
        return refuse(function, illegal_function);
    }
    if (const auto code = over_limit(request_pdu)) return broadcast ? std::nullopt : refuse(function, *code);
    auto reply = RequestHandler::handle(request_pdu, broadcast);
    if (broadcast) return std::nullopt;
    return reply;
}

// FC2 and FC4 read the same bits and words as FC1 and FC3 where the profile lists no separate
// discrete-input or input-register table (AC20 "Function code 1 and 2", "3 and 4"; NOTES.md).
Table SimulatedDevice::table_for(std::uint8_t function) const {
    switch (function) {
        case 2: return memory_.has_table(Table::discrete_inputs) ? Table::discrete_inputs : Table::coils;
        case 4: return memory_.has_table(Table::input_registers) ? Table::input_registers : Table::holding_registers;
        default: return is_bit_function(function) ? Table::coils : Table::holding_registers;
    }
}

codec::Reply SimulatedDevice::serve(const codec::Request& request) {
    return is_write(request.function) ? write(request) : read(request);
}

codec::Reply SimulatedDevice::read(const codec::Request& request) {
    const Table table = table_for(request.function);
    const bool bits = is_bit_function(request.function);
    codec::Reply reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    for (unsigned i = 0; i < request.count; ++i) {
        const MemoryCell* cell = find(table, static_cast<std::uint16_t>(request.address + i));
        if (cell == nullptr || !cell->parameter->readable) {
            // unmapped_reads "answered": the AC20 reads unmapped words as 8000h (FC3/4); its manual
            // leaves unmapped bits undefined, read here as 0. "exception": code 2 for the range.
            if (!profile_->unmapped_reads_answered) return codec::exception_reply(request.function, illegal_data_address);
            reply.values.push_back(bits ? 0 : profile_->unmapped_value);
            continue;
        }
        const std::uint16_t raw = on_read(*cell->parameter, cell->raw);
        reply.values.push_back(bits ? static_cast<std::uint16_t>(raw != 0) : raw);
    }
    return reply;
}

// FC5/6/15/16. Each value is checked against the parameter at its address, with bounds taken
// from memory and from values earlier in the same request. block_writes "in-order" (AC20
// FC15/FC16: "At the first error found, the command will be aborted") keeps what came before
// the error; "all-or-nothing" (default; TC10 §4.4 B) leaves memory unchanged.
codec::Reply SimulatedDevice::write(const codec::Request& request) {
    const Table table = table_for(request.function);
    std::vector<StagedWrite> staged;
    RawValues pending;
    std::optional<std::uint8_t> failure;
    for (std::size_t i = 0; i < request.values.size() && !failure; ++i) {
        MemoryCell* cell = find(table, static_cast<std::uint16_t>(request.address + i));
        const std::uint16_t raw = request.values[i];
        if (cell == nullptr) {
            failure = illegal_data_address;  // not a word or bit of the device
        } else if (!cell->parameter->writable) {
            // read_only_writes "ignored": AC20 FC15/FC16 "data imposed for read only words will be
            // ignored"; otherwise exception 2 (TC10 §3.4, ramp/soak §4.6; NOTES.md).
            if (!profile_->read_only_writes_ignored) failure = illegal_data_address;
        } else if (!is_dont_care(*cell->parameter, raw)) {
            const RawValues known = memory_.known_for(*cell->parameter, pending);
            failure = raw_in_range(*cell->parameter, raw, known) ? accept_write(*cell->parameter, raw, known)
                                                                    : std::optional<std::uint8_t>(illegal_data_value);
            if (!failure) {
                staged.push_back({cell, raw});
                pending[cell->parameter->name] = raw;
            }
        }
    }
    if (!failure || profile_->block_writes_in_order) {
        for (const StagedWrite& write : staged) {
            memory_.store(*write.cell, write.raw, persistence_of(request.function));
            after_write(*write.cell->parameter, write.raw);
        }
    }
    if (failure) return codec::exception_reply(request.function, *failure);
    // Replies echo the request: address and value (FC5/6), address and quantity (FC15/16).
    codec::Reply reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    if (request.function == 5 || request.function == 6) reply.values = request.values;
    return reply;
}

std::optional<std::uint8_t> SimulatedDevice::accept_write(const Parameter&, std::uint16_t, const RawValues&) {
    return std::nullopt;
}

std::uint16_t SimulatedDevice::on_read(const Parameter&, std::uint16_t stored) { return stored; }

void SimulatedDevice::after_write(const Parameter&, std::uint16_t) {}

std::optional<std::optional<Bytes>> SimulatedDevice::intercept(ByteView, bool) { return std::nullopt; }

Persistence SimulatedDevice::persistence_of(std::uint8_t) const { return Persistence::saved; }

void SimulatedDevice::step_process(double) {}

void SimulatedDevice::apply_fault(const std::string&) {}

}  // namespace loopwire::device
