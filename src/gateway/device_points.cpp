#include "gateway/device_points.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "common/peer_text.hpp"
#include "common/regular_file.hpp"
#include "gateway/config_schema.hpp"

namespace loopwire::gateway {
namespace {

using Json = nlohmann::json;

constexpr std::string_view points_table = "lines.devices.points";
// What a point may be today: the device model holds one register (or one bit) a value.
constexpr std::string_view point_types = "int16, uint16 or bits (a coil or discrete input needs no type)";
constexpr std::array wider_types{"int32", "uint32", "int64", "uint64", "float32", "float64", "string"};

struct Where {
    const std::string& source;
    std::vector<Error>& mistakes;

    void note(const toml::source_region& at, const std::string& path, const std::string& what) const {
        const auto line = std::max<toml::source_index>(at.begin.line, 1);
        mistakes.push_back(make_error(ErrorKind::usage, fmt::format("{}:{}: {}: {}", source, line, path, without_control_bytes(what))));
    }
};

std::string key_path(const std::string& parent, std::string_view key) { return fmt::format("{}.{}", parent, key); }

const toml::source_region& source_of(const toml::table& table, std::string_view key) {
    const toml::node* node = table.get(key);
    return node ? node->source() : table.source();
}

// The table a point is in, as the profile names it.
std::optional<std::string> table_named(std::string_view text) {
    if (text == "holding") return "holding";
    if (text == "input") return "input";
    if (text == "coil" || text == "coils") return "coils";
    if (text == "discrete") return "discrete";
    return std::nullopt;
}

bool bit_table(const std::string& table) { return table == "coils" || table == "discrete"; }

struct Address {
    std::optional<std::string> table;  // set by a reference (40001 is the first holding register)
    std::uint16_t address = 0;
};

// A 0-based wire address, or a reference as manuals print them: 0xxxx coils, 1xxxx discrete
// inputs, 3xxxx input registers and 4xxxx holding registers, counted from 1 (five digits up to
// 9999, six up to 65536).
std::optional<Address> reference(std::string_view text) {
    if ((text.size() != 5 && text.size() != 6) ||
        !std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        return std::nullopt;
    }
    static const std::map<char, std::string> tables{{'0', "coils"}, {'1', "discrete"}, {'3', "input"}, {'4', "holding"}};
    const auto table = tables.find(text.front());
    if (table == tables.end()) return std::nullopt;
    const long number = std::stol(std::string(text.substr(1)));
    if (number < 1 || number > 65536) return std::nullopt;
    return Address{table->second, static_cast<std::uint16_t>(number - 1)};
}

std::optional<Address> point_address(const Where& at, const toml::table& point, const std::string& path) {
    const toml::node* node = point.get("address");
    const std::string key = key_path(path, "address");
    if (!node) {
        at.note(point.source(), path, "missing `address` (a 0-based register number such as 12, or a reference such as \"40013\")");
        return std::nullopt;
    }
    if (const auto* number = node->as_integer()) {
        if (number->get() < 0 || number->get() > 65535) {
            at.note(node->source(), key, fmt::format("{} is out of range (expected 0..65535, the wire address counted from "
                                                     "0; or a reference such as \"40001\")", number->get()));
            return std::nullopt;
        }
        return Address{std::nullopt, static_cast<std::uint16_t>(number->get())};
    }
    if (const auto* text = node->as_string()) {
        if (auto found = reference(text->get())) return found;
        at.note(node->source(), key,
                fmt::format("{} is not a register reference (expected 4xxxx holding, 3xxxx input, 0xxxx coils or 1xxxx "
                            "discrete, counted from 1, e.g. \"40001\" for holding register 0; or a number counted from 0)",
                            quoted_excerpt(text->get())));
        return std::nullopt;
    }
    at.note(node->source(), key, "expected a number counted from 0, or a reference string such as \"40001\"");
    return std::nullopt;
}

bool valid_point_name(const std::string& name) {
    return !name.empty() && name.front() >= 'a' && name.front() <= 'z' &&
           std::all_of(name.begin(), name.end(), [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_'; });
}

template <typename T>
std::optional<T> value_of(const Where& at, const toml::table& point, const std::string& path, std::string_view key,
                          std::string_view expected, bool& ok) {
    const toml::node* node = point.get(key);
    if (!node) return std::nullopt;
    if (const auto* value = node->as<T>()) return value->get();
    at.note(node->source(), key_path(path, key), fmt::format("expected {}", expected));
    ok = false;
    return std::nullopt;
}

std::optional<double> number_of(const Where& at, const toml::table& point, const std::string& path, std::string_view key,
                                bool& ok) {
    const toml::node* node = point.get(key);
    if (!node) return std::nullopt;
    if (const auto* real = node->as_floating_point()) return real->get();
    if (const auto* integer = node->as_integer()) return static_cast<double>(integer->get());
    at.note(node->source(), key_path(path, key), "expected a number");
    ok = false;
    return std::nullopt;
}

// The decimals a `scale` stands for: the device model shows a word divided by a power of ten.
std::optional<int> decimals_of_scale(double scale) {
    for (int decimals = 0; decimals <= 4; ++decimals) {
        if (std::abs(scale * std::pow(10.0, decimals) - 1.0) < 1e-9) return decimals;
    }
    return std::nullopt;
}

void check_keys(const Where& at, const toml::table& point, const std::string& path) {
    const auto allowed = config_keys_of(points_table);
    for (auto&& [key, node] : point) {
        if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
        at.note(key.source(), key_path(path, key.str()), fmt::format("unknown key (allowed here: {})", fmt::join(allowed, ", ")));
    }
}

// The point's type in the profile's words; the mistake noted when it has none.
std::optional<std::string> point_type(const Where& at, const toml::table& point, const std::string& path,
                                      const std::string& table, bool& ok) {
    auto type = value_of<std::string>(at, point, path, "type", "a type name such as \"uint16\"", ok);
    const std::string key = key_path(path, "type");
    if (bit_table(table)) {
        if (type && *type != "bool") {
            at.note(source_of(point, "type"), key,
                    fmt::format("a point of table {} is one bit: leave `type` out (or write \"bool\")", table));
            return std::nullopt;
        }
        return "bool";
    }
    if (!type) {
        if (ok) at.note(point.source(), path, fmt::format("missing `type` (one of {})", point_types));
        return std::nullopt;
    }
    if (*type == "int16" || *type == "uint16") return *type;
    if (*type == "bits") return "bitfield";
    if (std::find(wider_types.begin(), wider_types.end(), *type) != wider_types.end()) {
        at.note(source_of(point, "type"), key,
                fmt::format("{} spans more than one register, which the device model does not hold yet; read it with "
                            "`loopwire read --type {}`, or list its registers as uint16 points", *type, *type));
        return std::nullopt;
    }
    at.note(source_of(point, "type"), key, fmt::format("unknown type {} (expected {})", quoted_excerpt(*type), point_types));
    return std::nullopt;
}

void add_range(const Where& at, const toml::table& point, const std::string& path, Json& parameter, bool& ok) {
    const auto min = number_of(at, point, path, "min", ok);
    const auto max = number_of(at, point, path, "max", ok);
    if (min && max && *min > *max) {
        at.note(source_of(point, "min"), key_path(path, "min"),
                fmt::format("min {} is above max {}: swap them", *min, *max));
        ok = false;
        return;
    }
    if (!min && !max) return;
    Json range = Json::object();
    if (min) range["min"] = *min;
    if (max) range["max"] = *max;
    parameter["range"] = std::move(range);
}

void add_decimals(const Where& at, const toml::table& point, const std::string& path, Json& parameter, bool& ok) {
    auto decimals = value_of<std::int64_t>(at, point, path, "decimals", "an integer 0..4", ok);
    const auto scale = number_of(at, point, path, "scale", ok);
    if (decimals && scale) {
        at.note(source_of(point, "scale"), key_path(path, "scale"),
                "give `scale` or `decimals`, not both (scale = 0.1 is decimals = 1)");
        ok = false;
        return;
    }
    if (scale) {
        decimals = decimals_of_scale(*scale);
        if (!decimals) {
            at.note(source_of(point, "scale"), key_path(path, "scale"),
                    fmt::format("scale {} is not 1, 0.1, 0.01, 0.001 or 0.0001: a word is shown divided by a power of "
                                "ten (decimals = N)", *scale));
            ok = false;
            return;
        }
    }
    if (decimals && (*decimals < 0 || *decimals > 4)) {
        at.note(source_of(point, "decimals"), key_path(path, "decimals"),
                fmt::format("{} is out of range (expected an integer 0..4)", *decimals));
        ok = false;
        return;
    }
    parameter["decimals"] = decimals.value_or(0);
}

void add_unit(const Where& at, const toml::table& point, const std::string& path, Json& parameter, bool& ok) {
    auto unit = value_of<std::string>(at, point, path, "unit", "a unit such as \"kWh\"", ok);
    if (unit && !unit->empty()) {
        parameter["unit"] = *unit;
    } else {
        parameter["unitless"] = "unstated";
    }
}

// One point as a profile parameter; its table and address in `found`. None when it has a mistake.
std::optional<Json> parameter_of(const Where& at, const toml::table& point, const std::string& path,
                                 const std::string& device_name, Address& found, bool& polled) {
    check_keys(at, point, path);
    bool ok = true;
    Json parameter = Json::object();
    auto name = value_of<std::string>(at, point, path, "name", "a name such as \"energy_total\"", ok);
    if (!name && ok) at.note(point.source(), path, "missing `name` (e.g. name = \"energy_total\")");
    if (name && !valid_point_name(*name)) {
        at.note(source_of(point, "name"), key_path(path, "name"),
                fmt::format("{} is not a point name (expected lower-case letters, digits and '_', beginning with a "
                            "letter: it is a key in the API, MQTT topics and history)", quoted_excerpt(*name)));
        name.reset();
    }
    if (!name) ok = false;
    auto table_text = value_of<std::string>(at, point, path, "table", "\"holding\", \"input\", \"coil\" or \"discrete\"", ok);
    std::optional<std::string> table;
    if (table_text) {
        table = table_named(*table_text);
        if (!table) {
            at.note(source_of(point, "table"), key_path(path, "table"),
                    fmt::format("unknown table {} (expected \"holding\", \"input\", \"coil\" or \"discrete\")",
                                quoted_excerpt(*table_text)));
            ok = false;
        }
    }
    auto address = point_address(at, point, path);
    if (!address) return std::nullopt;
    if (address->table && table && *address->table != *table) {
        at.note(source_of(point, "table"), key_path(path, "table"),
                fmt::format("the reference is in table {}, not {}: leave `table` out, or give the address counted from 0",
                            *address->table, *table));
        return std::nullopt;
    }
    if (!table) table = address->table;
    if (!table) {
        if (ok) at.note(point.source(), path, "missing `table` (\"holding\", \"input\", \"coil\" or \"discrete\"), or give the address as a reference such as \"40001\"");
        return std::nullopt;
    }
    auto type = point_type(at, point, path, *table, ok);
    auto writable = value_of<bool>(at, point, path, "writable", "true or false", ok).value_or(false);
    if (writable && (*table == "input" || *table == "discrete")) {
        at.note(source_of(point, "writable"), key_path(path, "writable"),
                fmt::format("the {} table is read-only in Modbus: move the point to {} or drop `writable`", *table,
                            *table == "input" ? "holding" : "coil"));
        ok = false;
    }
    if (const toml::node* poll = point.get("poll")) {
        const auto* on = poll->as_boolean();
        if (!on || on->get()) {
            at.note(poll->source(), key_path(path, "poll"),
                    "expected false (a point is polled at the device's `poll` interval unless poll = false)");
            ok = false;
        } else {
            polled = false;
        }
    }
    if (type == "int16" || type == "uint16") {
        add_decimals(at, point, path, parameter, ok);
        add_unit(at, point, path, parameter, ok);
        add_range(at, point, path, parameter, ok);
    } else if (type) {
        for (std::string_view key : {"decimals", "scale", "unit", "min", "max"}) {
            if (!point.contains(key)) continue;
            at.note(source_of(point, key), key_path(path, key),
                    fmt::format("a {} point is not a number: remove `{}`", *type == "bool" ? "one-bit" : "bits", key));
            ok = false;
        }
    }
    if (!ok || !type) return std::nullopt;
    found = Address{table, address->address};
    parameter["name"] = *name;
    parameter["table"] = *table;
    parameter["address"] = address->address;
    parameter["type"] = *type;
    parameter["access"] = writable ? "rw" : "r";
    if (*type == "bitfield") {
        Json bits = Json::object();
        for (unsigned bit = 0; bit < 16; ++bit) bits[std::to_string(bit)] = fmt::format("bit{}", bit);
        parameter["bits"] = std::move(bits);
    }
    parameter["source"] = fmt::format("point {} of device {}", *name, device_name);
    return parameter;
}

std::string profile_id(const std::string& device_name) {
    std::string id = "points-";
    for (char c : device_name) id += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return id;
}

Json profile_document(const std::string& device_name, Json parameters) {
    return Json{
        {"id", profile_id(device_name)},
        {"title", fmt::format("Device {}, described by its points", device_name)},
        {"manual", {{"file", ""}, {"document", "the points listed in the gateway configuration"}}},
        {"protocols", {"rtu", "ascii", "tcp"}},
        {"serial_defaults", {{"baud", 19200}, {"data_bits", 8}, {"parity", "even"}, {"stop_bits", 1}}},
        {"function_codes", {1, 2, 3, 4, 5, 6, 15, 16}},
        {"limits", Json::object()},
        // Nothing says which addresses between the points the device answers: reads stop at holes.
        {"unmapped_reads", "exception"},
        {"addressing", {{"numbering", "The addresses are wire (PDU) addresses, counted from 0."}}},
        {"parameters", std::move(parameters)},
    };
}

}  // namespace

std::optional<PointsProfile> points_profile(const toml::table& table, const std::string& source, const std::string& path,
                                            const std::string& device_name, std::vector<Error>& mistakes) {
    const Where at{source, mistakes};
    const std::string list_path = key_path(path, "points");
    const toml::node* node = table.get("points");
    const auto* array = node ? node->as_array() : nullptr;
    if (!array || array->empty() || !array->is_array_of_tables()) {
        at.note(node ? node->source() : table.source(), list_path,
                "expected [[lines.devices.points]] tables, one per point (name, table, address, type)");
        return std::nullopt;
    }
    const std::size_t before = mistakes.size();
    PointsProfile profile;
    Json parameters = Json::array();
    std::map<std::string, std::string> names;                           // name -> path
    std::map<std::pair<std::string, std::uint16_t>, std::string> taken;  // (table, address) -> name
    for (std::size_t i = 0; i < array->size(); ++i) {
        const std::string point_path = fmt::format("{}[{}]", list_path, i);
        const toml::table& point = *array->get(i)->as_table();
        Address address;
        bool polled = true;
        auto parameter = parameter_of(at, point, point_path, device_name, address, polled);
        if (!parameter) continue;
        const std::string name = parameter->at("name").get<std::string>();
        if (auto [first, added] = names.emplace(name, point_path); !added) {
            at.note(source_of(point, "name"), key_path(point_path, "name"),
                    fmt::format("\"{}\" is already the name of {}; each point needs its own name", name, first->second));
            continue;
        }
        if (auto [first, added] = taken.emplace(std::pair{*address.table, address.address}, name); !added) {
            at.note(source_of(point, "address"), key_path(point_path, "address"),
                    fmt::format("{} {} is already point {}: two points cannot share a register; remove one, or fix "
                                "its address", *address.table, address.address, first->second));
            continue;
        }
        if (polled) profile.polled.push_back(name);
        parameters.push_back(std::move(*parameter));
    }
    if (mistakes.size() != before) return std::nullopt;
    if (profile.polled.empty()) {
        at.note(node->source(), list_path, "every point has poll = false: the device would poll nothing; poll one");
        return std::nullopt;
    }
    // Address order, as a profile lists its map and the planner reads it.
    std::sort(parameters.begin(), parameters.end(), [](const Json& a, const Json& b) {
        return std::pair(a.at("table").get<std::string>(), a.at("address").get<int>()) <
               std::pair(b.at("table").get<std::string>(), b.at("address").get<int>());
    });
    profile.document = profile_document(device_name, std::move(parameters));
    return profile;
}

Result<std::string> points_profile_text(const std::filesystem::path& file, const std::string& device_name) {
    const std::string source = file.string();
    auto text = read_regular_file(file, 1024 * 1024);
    if (!text) return make_error(ErrorKind::usage, fmt::format("{}: cannot read it: {}", source, text.error().message));
    toml::table root;
    try {
        root = toml::parse(*text, source);
    } catch (const toml::parse_error& error) {
        return make_error(ErrorKind::usage, fmt::format("{}:{}: {}", source, error.source().begin.line, error.description()));
    }
    std::vector<std::string> described;
    const auto* lines = root["lines"].as_array();
    for (std::size_t l = 0; lines && l < lines->size(); ++l) {
        const auto* line = lines->get(l)->as_table();
        const auto* devices = line ? (*line)["devices"].as_array() : nullptr;
        for (std::size_t d = 0; devices && d < devices->size(); ++d) {
            const auto* device = devices->get(d)->as_table();
            if (!device || !device->contains("points")) continue;
            const auto name = (*device)["name"].value<std::string>();
            if (!name) continue;
            described.push_back(*name);
            if (*name != device_name) continue;
            std::vector<Error> mistakes;
            auto profile = points_profile(*device, source, fmt::format("lines[{}].devices[{}]", l, d), *name, mistakes);
            if (!profile) {
                std::string all;
                for (const Error& mistake : mistakes) all += (all.empty() ? "" : "\n") + mistake.message;
                return make_error(ErrorKind::usage, all);
            }
            return profile->document.dump(2) + "\n";
        }
    }
    return make_error(ErrorKind::usage,
                      fmt::format("{}: no device {} described by its points (devices with points: {})", source,
                                  device_name, described.empty() ? "none" : fmt::format("{}", fmt::join(described, ", "))));
}

}  // namespace loopwire::gateway
