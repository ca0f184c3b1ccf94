#include "simulation/state_file.hpp"

#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "common/atomic_file.hpp"

namespace loopwire::device {
namespace {

constexpr const char* format_name = "loopwire-simulator-state";

Error bad_file(const std::string& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("{}: {}; it was left untouched: give another --state file, or "
                                                    "move this one away to start from defaults",
                                                    path, what));
}

Result<nlohmann::json> read_document(const std::string& path, bool& exists) {
    std::ifstream file(path, std::ios::binary);
    exists = static_cast<bool>(file);
    if (!exists) return nlohmann::json{{"format", format_name}, {"version", 1}, {"units", nlohmann::json::object()}};
    std::ostringstream text;
    text << file.rdbuf();
    auto document = nlohmann::json::parse(text.str(), nullptr, false);
    if (document.is_discarded()) return bad_file(path, "is not valid JSON");
    if (!document.is_object() || document.value("format", "") != format_name) {
        return bad_file(path, fmt::format("is not a loopwire simulator state file (no \"format\": \"{}\")", format_name));
    }
    if (document.value("version", 0) != 1) return bad_file(path, "has a state format version this loopwire does not know (expected 1)");
    if (!document.contains("units") || !document["units"].is_object()) return bad_file(path, "has no \"units\" object");
    return document;
}

}  // namespace

Result<SimulatorStateFile> SimulatorStateFile::open(const std::string& path, const Devices& devices) {
    bool exists = false;
    auto document = read_document(path, exists);
    if (!document) return document.error();
    SimulatorStateFile state(path, devices);
    if (auto loaded = state.load(*document); !loaded) return loaded.error();
    if (!exists) {
        if (auto saved = state.save(); !saved) return saved.error();  // fail now, not at the first write
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
            const std::string profile = entry.is_object() ? entry.value("profile", "") : "";
            if (profile != device->profile().id) {
                warnings_.push_back(fmt::format("{}: unit {} was saved as '{}', now serves {}: it starts from defaults and "
                                                "its saved values will be replaced",
                                                path_, unit, profile, device->profile().id));
            } else if (!entry.contains("saved") || !entry["saved"].is_object()) {
                return bad_file(path_, fmt::format("unit {} has no \"saved\" object", unit));
            } else {
                device::RawValues saved;
                for (const auto& [name, raw] : entry["saved"].items()) {
                    if (!raw.is_number_integer() || raw.get<long long>() < 0 || raw.get<long long>() > 0xFFFF) {
                        return bad_file(path_, fmt::format("unit {}: {} is not a raw word 0..65535", unit, name));
                    }
                    saved.emplace(name, static_cast<std::uint16_t>(raw.get<long long>()));
                }
                for (const std::string& unknown : device->load_saved(saved)) {
                    warnings_.push_back(fmt::format("{}: unit {} ({}): '{}' is not a saved parameter of this profile; ignored",
                                                    path_, unit, profile, unknown));
                }
            }
        }
        saved_generations_[unit] = device->saved_generation();
    }
    return {};
}

Result<void> SimulatorStateFile::save_if_changed() {
    bool changed = false;
    for (const auto& [unit, device] : devices_) changed |= saved_generations_[unit] != device->saved_generation();
    return changed ? save() : Result<void>{};
}

Result<void> SimulatorStateFile::save() {
    for (const auto& [unit, device] : devices_) {
        saved_generations_[unit] = device->saved_generation();
        nlohmann::json saved = nlohmann::json::object();
        for (const auto& [name, raw] : device->saved_values()) saved[name] = raw;
        document_["units"][std::to_string(unit)] = {{"profile", device->profile().id}, {"saved", saved}};
    }
    return write_file_atomically(path_, document_.dump(2) + "\n");
}

}  // namespace loopwire::device
