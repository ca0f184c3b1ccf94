#include "simulation/device_memory.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace loopwire::device {
namespace {

const double* fixed(const std::optional<Bound>& bound) { return bound ? std::get_if<double>(&*bound) : nullptr; }
const std::string* named(const std::optional<Bound>& bound) { return bound ? std::get_if<std::string>(&*bound) : nullptr; }

// Which end of its own range a parameter starts at. Limit words start wide open, so the words
// they bound can be written at start (TC10 SP.LL/SP.HL bound SP, §5.3.8; AC20 rL/rH bound SP2-4).
enum class Start { zero, lowest, highest };

std::map<std::string, Start> limit_word_starts(const Profile& profile) {
    std::map<std::string, Start> starts;
    for (const Parameter& parameter : profile.parameters) {
        if (const std::string* name = named(parameter.min)) starts[*name] = Start::lowest;
        if (const std::string* name = named(parameter.max)) starts[*name] = Start::highest;
    }
    return starts;
}

bool is_special(const Parameter& parameter, std::int32_t raw) {
    return std::any_of(parameter.special.begin(), parameter.special.end(), [raw](const SpecialValue& special) {
        return static_cast<std::uint16_t>(special.raw) == static_cast<std::uint16_t>(raw);  // -32768 is 32768
    });
}

// The widest raw of the word's type that is not a special value (AC20 8000h is "not-available").
std::uint16_t extreme_raw(const Parameter& parameter, Start start) {
    const bool signed_word = parameter.type == ValueType::int16;
    std::int32_t raw = start == Start::lowest ? (signed_word ? -32768 : 0) : (signed_word ? 32767 : 65535);
    const std::int32_t step = start == Start::lowest ? 1 : -1;
    while (is_special(parameter, raw)) raw += step;
    return static_cast<std::uint16_t>(raw);
}

// 0 where the profile allows it, else the nearest fixed limit; limit words at their far end.
std::optional<double> start_value(const Parameter& parameter, Start start) {
    const double* min = fixed(parameter.min);
    const double* max = fixed(parameter.max);
    if (start == Start::lowest) return min ? std::optional<double>(*min) : std::nullopt;
    if (start == Start::highest) return max ? std::optional<double>(*max) : std::nullopt;
    if (min != nullptr && *min > 0) return *min;
    if (max != nullptr && *max < 0) return *max;
    return 0.0;
}

// Enums start at 0 when 0 is a listed code, else at the first listed code (an unlisted code
// would read back as "unknown-label"). Bits, bools and bit fields start at 0.
std::uint16_t default_raw(const Parameter& parameter, Start start, const RawValues& known) {
    if (parameter.type == ValueType::enumeration && !parameter.enum_labels.empty() &&
        !parameter.enum_labels.contains(0)) {
        return static_cast<std::uint16_t>(parameter.enum_labels.begin()->first);
    }
    if (parameter.type != ValueType::int16 && parameter.type != ValueType::uint16) return 0;
    const auto value = start_value(parameter, start);
    if (!value) return extreme_raw(parameter, start);
    // A range in display counts (Parameter::range_in_counts) gives the raw word itself.
    if (parameter.range_in_counts) return static_cast<std::uint16_t>(static_cast<std::int32_t>(*value));
    EngineeringValue engineering;
    engineering.value = *value;
    const auto raw = raw_of(parameter, engineering, known);
    return raw ? *raw : 0;
}

}  // namespace

DeviceMemory::DeviceMemory(std::shared_ptr<const Profile> profile) : profile_(std::move(profile)) {
    // Two entries may share an address only with a note explaining the manual's glitch
    // (profile_checks.hpp); the first listed one owns the cell.
    for (const Parameter& parameter : profile_->parameters) {
        cells_.emplace(Key{parameter.table, parameter.address}, MemoryCell{&parameter, 0, 0});
    }
    reset_to_defaults();
}

void DeviceMemory::reset_to_defaults() {
    const auto starts = limit_word_starts(*profile_);
    for (auto& [key, cell] : cells_) {
        const auto start = starts.find(cell.parameter->name);
        cell.raw = default_raw(*cell.parameter, start == starts.end() ? Start::zero : start->second,
                               known_for(*cell.parameter, {}));
    }
    set_identification();
    for (auto& [key, cell] : cells_) cell.saved = cell.raw;
    ++saved_generation_;
}

MemoryCell* DeviceMemory::cell(std::string_view name) {
    const Parameter* parameter = profile_->find(name);
    return parameter == nullptr ? nullptr : &cells_.at(Key{parameter->table, parameter->address});
}

const MemoryCell* DeviceMemory::cell(std::string_view name) const {
    const Parameter* parameter = profile_->find(name);
    return parameter == nullptr ? nullptr : &cells_.at(Key{parameter->table, parameter->address});
}

void DeviceMemory::store(MemoryCell& cell, std::uint16_t raw, Persistence persistence) {
    cell.raw = raw;
    if (persistence == Persistence::ram_only || cell.parameter->ram_only || cell.saved == raw) return;
    cell.saved = raw;
    ++saved_generation_;
}

RawValues DeviceMemory::saved_values() const {
    RawValues saved;
    for (const auto& [key, cell] : cells_) {
        if (!cell.parameter->ram_only && cell.parameter->writable) saved.emplace(cell.parameter->name, cell.saved);
    }
    return saved;
}

std::vector<std::string> DeviceMemory::load_saved(const RawValues& saved) {
    std::vector<std::string> unknown;
    for (const auto& [name, raw] : saved) {
        MemoryCell* target = cell(name);
        if (target == nullptr || target->parameter->ram_only || !target->parameter->writable) {
            unknown.push_back(name);
            continue;
        }
        target->raw = target->saved = static_cast<std::uint16_t>(raw);
    }
    ++saved_generation_;
    return unknown;
}

// profile.identification 'equals': AC20 word 120 = 50, TC10 word 21 = 20, ramp/soak VER = 104.
void DeviceMemory::set_identification() {
    for (const IdentificationCheck& check : profile_->identification) {
        const Parameter* parameter = profile_->find(check.parameter);
        if (parameter == nullptr) continue;
        cells_.at(Key{parameter->table, parameter->address}).raw = static_cast<std::uint16_t>(check.equals);
    }
}

// addressing.mirrors: a wire address inside a mirror range names the parameter `offset` below.
std::uint16_t DeviceMemory::own_address(Table table, std::uint16_t wire_address) const {
    for (const AddressMirror& mirror : profile_->mirrors) {
        const int own = wire_address - mirror.offset;
        if (mirror.table == table && own >= mirror.first && own <= mirror.last) return static_cast<std::uint16_t>(own);
    }
    return wire_address;
}

MemoryCell* DeviceMemory::find(Table table, std::uint16_t wire_address) {
    const auto it = cells_.find(Key{table, own_address(table, wire_address)});
    return it == cells_.end() ? nullptr : &it->second;
}

RawValues DeviceMemory::known_for(const Parameter& parameter, const RawValues& pending) const {
    RawValues known;
    for (const std::string& name : dependencies_of(parameter)) {
        if (const auto staged = pending.find(name); staged != pending.end()) {
            known.emplace(name, staged->second);
        } else if (const Parameter* source = profile_->find(name)) {
            known.emplace(name, cells_.at(Key{source->table, source->address}).raw);
        }
    }
    return known;
}

bool DeviceMemory::has_table(Table table) const {
    for (const auto& [key, cell] : cells_) {
        if (key.first == table) return true;
    }
    return false;
}

}  // namespace loopwire::device
