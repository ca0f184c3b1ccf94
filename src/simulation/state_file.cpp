#include "simulation/state_file.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "common/atomic_file.hpp"
#include "common/json_checks.hpp"
#include "common/regular_file.hpp"
#include "common/text_parsing.hpp"

namespace loopwire::device {
namespace {

constexpr const char* format_name = "loopwire-simulator-state";
// Far above what any simulator saves (a few kilobytes per device).
constexpr std::size_t max_state_file_size = 64 * 1024 * 1024;

Error bad_file(const std::string& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("{}: {}; it was left untouched: give another --state file, or "
                                                    "move this one away to start from defaults",
                                                    path, what));
}

Error wrong_value(const std::string& path, const std::string& pointer, std::string_view expected, const nlohmann::json* found) {
    return bad_file(path, fmt::format("at {}: expected {}, found {}", pointer, expected, found ? describe_json(*found) : "nothing"));
}

const nlohmann::json* member(const nlohmann::json& object, const char* key) {
    const auto found = object.find(key);
    return found == object.end() ? nullptr : &*found;
}

// Every value of the document is checked here, units this run does not serve included (they
// are written back as they are), so load() and save() meet only the shapes they expect.
Result<void> check_document(const std::string& path, const nlohmann::json& document) {
    if (!document.is_object()) return wrong_value(path, "(the document)", "a loopwire simulator state object", &document);
    const auto* format = member(document, "format");
    if (!format || !format->is_string() || format->get<std::string>() != format_name) {
        return bad_file(path, fmt::format("is not a loopwire simulator state file (at /format: expected \"{}\", found {})", format_name,
                                          format ? describe_json(*format) : "nothing"));
    }
    const auto* version = member(document, "version");
    if (!version || json_word(*version) != std::optional<std::uint16_t>(1)) {
        return bad_file(path, fmt::format("has a state format version this loopwire does not know (at /version: expected 1, found {})",
                                          version ? describe_json(*version) : "nothing"));
    }
    const auto* units = member(document, "units");
    if (!units || !units->is_object()) return wrong_value(path, "/units", "an object of units by unit id", units);
    for (const auto& [key, entry] : units->items()) {
        const std::string pointer = json_pointer("/units", key);
        const auto unit = parse_decimal_digits(key);
        if (!unit || *unit < 1 || *unit > 255) return bad_file(path, fmt::format("at {}: expected a unit id 1..255 as the key, found \"{}\"", pointer, key));
        if (!entry.is_object()) return wrong_value(path, pointer, "an object with \"profile\" and \"saved\"", &entry);
        const auto* profile = member(entry, "profile");
        if (!profile || !profile->is_string()) return wrong_value(path, json_pointer(pointer, "profile"), "a profile id as a string (e.g. \"tc10\")", profile);
        const auto* saved = member(entry, "saved");
        if (!saved || !saved->is_object()) return wrong_value(path, json_pointer(pointer, "saved"), "an object of raw words by parameter name", saved);
        for (const auto& [name, raw] : saved->items()) {
            if (!json_word(raw)) return wrong_value(path, json_pointer(json_pointer(pointer, "saved"), name), "a raw word, an integer 0..65535", &raw);
        }
        // Optional (files written before it was kept have none): what the device was doing at
        // power-off, besides its parameters (SimulatedDevice::saved_condition).
        if (const auto* condition = member(entry, "condition")) {
            if (!condition->is_object()) return wrong_value(path, json_pointer(pointer, "condition"), "an object of raw words by name", condition);
            for (const auto& [name, raw] : condition->items()) {
                if (!json_word(raw)) return wrong_value(path, json_pointer(json_pointer(pointer, "condition"), name), "a raw word, an integer 0..65535", &raw);
            }
        }
    }
    return {};
}

}  // namespace

Result<nlohmann::json> parse_state_text(const std::string& text, const std::string& path) {
    if (auto deep = json_nesting_problem(text)) return bad_file(path, *deep);
    auto document = nlohmann::json::parse(text, nullptr, false);
    if (document.is_discarded()) return bad_file(path, "is not valid JSON");
    if (auto checked = check_document(path, document); !checked) return checked.error();
    return document;
}

namespace {

// A state file is the simulator's own, written whole by rename: anything but a regular file (a
// FIFO, which would block the start forever, a directory, a device) is refused unopened.
Result<nlohmann::json> read_document(const std::string& path, bool& exists) {
    std::error_code error;
    exists = std::filesystem::status(path, error).type() != std::filesystem::file_type::not_found;
    if (!exists) return nlohmann::json{{"format", format_name}, {"version", 1}, {"units", nlohmann::json::object()}};
    if (auto what = not_a_regular_file(path)) return bad_file(path, *what);
    auto text = read_regular_file(path, max_state_file_size);
    if (!text) return bad_file(path, text.error().message);
    return parse_state_text(*text, path);
}

}  // namespace

Result<SimulatorStateFile> SimulatorStateFile::open(const std::string& path, const Devices& devices) {
    // A save killed between writing its temporary and renaming it (kill -9, power loss) left
    // the temporary behind; the file itself is whole, the temporary of no use.
    const auto stale = remove_stale_temporaries(path);
    bool exists = false;
    auto document = read_document(path, exists);
    if (!document) return document.error();
    SimulatorStateFile state(path, devices);
    for (const std::string& removed : stale) {
        state.warnings_.push_back(fmt::format("removed {}, left by an earlier run stopped while saving", removed));
    }
    if (auto loaded = state.load(*document); !loaded) return loaded.error();
    // Fail now, before a remote write is acknowledged, not at the first save.
    if (!exists) {
        if (auto saved = state.save(); !saved) return saved.error();
    } else if (auto writable = check_writable_atomically(path); !writable) {
        return make_error(ErrorKind::usage, fmt::format("{}; the simulator could not keep its state: make it writable, or give "
                                                        "another --state file", writable.error().message));
    }
    return state;
}

Result<void> SimulatorStateFile::load(const nlohmann::json& document) {
    document_ = document;
    for (const auto& [unit, device] : devices_) {
        const std::string key = std::to_string(unit);
        const auto& units = document_["units"];
        if (units.contains(key)) {
            const auto& entry = units[key];
            const std::string profile = entry["profile"].get<std::string>();  // check_document: a string
            if (profile != device->profile().id) {
                warnings_.push_back(fmt::format("{}: unit {} was saved as '{}', now serves {}: it starts from defaults and "
                                                "its saved values will be replaced",
                                                path_, unit, profile, device->profile().id));
            } else {
                device::RawValues saved;
                for (const auto& [name, raw] : entry["saved"].items()) saved.emplace(name, *json_word(raw));  // checked
                for (const std::string& unknown : device->load_saved(saved)) {
                    warnings_.push_back(fmt::format("{}: unit {} ({}): '{}' is not a saved parameter of this profile; ignored",
                                                    path_, unit, profile, unknown));
                }
                device::RawValues condition;
                if (entry.contains("condition")) {
                    for (const auto& [name, raw] : entry["condition"].items()) condition.emplace(name, *json_word(raw));  // checked
                }
                device->load_condition(condition);
            }
        }
        saved_generations_[unit] = device->saved_generation();
    }
    return {};
}

bool SimulatorStateFile::has_unsaved_changes() const {
    for (const auto& [unit, device] : devices_) {
        const auto saved = saved_generations_.find(unit);
        if (saved == saved_generations_.end() || saved->second != device->saved_generation()) return true;
    }
    return false;
}

Result<void> SimulatorStateFile::save_if_changed() { return has_unsaved_changes() ? save() : Result<void>{}; }

Result<void> SimulatorStateFile::save() {
    std::map<std::uint8_t, std::uint64_t> generations;
    for (const auto& [unit, device] : devices_) {
        generations[unit] = device->saved_generation();  // before reading: a later change is saved next time
        nlohmann::json saved = nlohmann::json::object();
        for (const auto& [name, raw] : device->saved_values()) saved[name] = raw;
        auto& entry = document_["units"][std::to_string(unit)];
        entry = {{"profile", device->profile().id}, {"saved", saved}};
        const auto condition = device->saved_condition();
        if (!condition.empty()) {
            entry["condition"] = nlohmann::json::object();
            for (const auto& [name, raw] : condition) entry["condition"][name] = raw;
        }
    }
    // Lock combinations are among the saved words: a new state file is private to its owner.
    auto written = write_file_atomically(path_, document_.dump(2) + "\n", private_file_mode);
    if (written) saved_generations_ = std::move(generations);  // only a save that happened counts
    return written;
}

}  // namespace loopwire::device
