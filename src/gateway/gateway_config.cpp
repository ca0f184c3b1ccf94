#include "gateway/gateway_config.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cctype>
#include <cerrno>
#include <initializer_list>
#include <map>
#include <optional>
#include <set>
#include <system_error>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "common/peer_text.hpp"
#include "common/regular_file.hpp"
#include "common/text_parsing.hpp"
#include "gateway/alarms/alarm_config.hpp"
#include "gateway/config_schema.hpp"
#include "gateway/device_points.hpp"
#include "gateway/http_server.hpp"
#include "gateway/postgres_database.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::transport {
bool operator==(const SerialSettings& a, const SerialSettings& b) {
    return a.baud == b.baud && a.data_bits == b.data_bits && a.parity == b.parity && a.stop_bits == b.stop_bits &&
           a.rs485 == b.rs485 && a.rs485_delay_before == b.rs485_delay_before &&
           a.rs485_delay_after == b.rs485_delay_after && a.guard == b.guard;
}
bool operator==(const LinkUrl& a, const LinkUrl& b) {
    return a.framing == b.framing && a.path == b.path && a.host == b.host && a.port == b.port && a.serial == b.serial;
}
}  // namespace loopwire::transport

namespace loopwire::device {
bool operator==(const DeviceAddress& a, const DeviceAddress& b) {
    return a.profile == b.profile && a.unit == b.unit && a.address_offset == b.address_offset;
}
}  // namespace loopwire::device

namespace loopwire::gateway {
namespace {

using std::chrono::milliseconds;

constexpr std::uintmax_t max_file_size = 1024 * 1024;  // a real configuration is a few kilobytes

// ---------------------------------------------------------------------------------------------
// Locations: every message starts "FILE:LINE: KEY.PATH: ", so an editor can jump to the spot.

std::string key_path(const std::string& parent, std::string_view key) {
    return parent.empty() ? std::string(key) : fmt::format("{}.{}", parent, key);
}

std::string index_path(const std::string& parent, std::size_t index) { return fmt::format("{}[{}]", parent, index); }

// Mistakes are collected, not thrown at the first: a key whose value is wrong keeps its default
// and the keys, tables, lines and devices after it are still checked, so that one run of
// `--check` lists every mistake of the file. A check that a mistake makes meaningless (a
// device's parameters when its profile is unknown, the serial keys of a link that does not
// parse) is left out rather than reported as a second, made-up mistake.
struct Context {
    const std::string& source;
    const device::ProfileRegistry& profiles;
    std::vector<Error>& mistakes;

    void note(Error mistake) const { mistakes.push_back(std::move(mistake)); }

    // The value when it parsed; else its mistake is noted and there is none.
    template <typename T>
    std::optional<T> kept(Result<T> parsed) const {
        if (parsed) return std::optional<T>(std::move(*parsed));
        note(parsed.error());
        return std::nullopt;
    }
    bool kept(const Result<void>& checked) const {
        if (!checked) note(checked.error());
        return checked.ok();
    }

    Error fail(const toml::source_region& where, const std::string& path, const std::string& what) const {
        // Line 0 means toml++ knows no position (a node built in code); the root is line 1.
        const auto line = std::max<toml::source_index>(where.begin.line, 1);
        // The file's strings may hold control characters (TOML's \u escapes): none reaches a
        // terminal or the log raw, whichever message quotes them.
        return make_error(ErrorKind::usage, fmt::format("{}:{}: {}: {}", source, line, path, without_control_bytes(what)));
    }
};

// Messages of the shared parsers begin with the name they were given ("{option} '{text}' is
// not ..."): given an empty name they begin with a space, trimmed here since the key path
// already says what was parsed.
std::string without_option_name(const std::string& message) {
    const auto first = message.find_first_not_of(' ');
    return first == std::string::npos ? message : message.substr(first);
}

// ---------------------------------------------------------------------------------------------
// Typed access to the values of one table. Absent keys are std::nullopt; a value of the wrong
// type is an error saying which type is expected.

// `schema_table`: the table's name in config_schema.hpp ("lines.devices"), where its keys are
// described; `path` is where it is in the file ("lines[0].devices[1]").
// Every unknown key is noted; the table's other keys are read as if it were not there.
void check_keys(const Context& ctx, const toml::table& table, const std::string& path, std::string_view schema_table) {
    const std::vector<std::string_view> allowed = config_keys_of(schema_table);
    for (auto&& [key, node] : table) {
        if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
        // A typo must not leave a setting at its default without a word: unknown keys are errors.
        ctx.note(ctx.fail(key.source(), key_path(path, key.str()),
                          fmt::format("unknown key (allowed here: {})", fmt::join(allowed, ", "))));
    }
}

template <typename T>
Result<std::optional<T>> optional_value(const Context& ctx, const toml::table& table, const std::string& path,
                                        std::string_view key, std::string_view expected) {
    const toml::node* node = table.get(key);
    if (!node) return std::optional<T>{};
    if (const auto* value = node->as<T>()) return std::optional<T>{value->get()};
    return ctx.fail(node->source(), key_path(path, key), fmt::format("expected {}", expected));
}

Result<std::string> required_string(const Context& ctx, const toml::table& table, const std::string& path,
                                    std::string_view key, std::string_view example) {
    auto text = optional_value<std::string>(ctx, table, path, key, fmt::format("a string such as {}", example));
    if (!text) return text.error();
    if (!*text) return ctx.fail(table.source(), path, fmt::format("missing `{}` (e.g. {} = {})", key, key, example));
    return std::move(**text);
}

const toml::source_region& source_of(const toml::table& table, std::string_view key) {
    const toml::node* node = table.get(key);
    return node ? node->source() : table.source();
}

// `least`: shorter is refused, saying so; a key whose own least is longer passes 0 and checks
// it with its own words, so the error quotes the real minimum.
Result<std::optional<milliseconds>> optional_duration(const Context& ctx, const toml::table& table, const std::string& path,
                                                      std::string_view key, milliseconds least = milliseconds(1)) {
    auto text = optional_value<std::string>(ctx, table, path, key, "a duration string such as \"500ms\" or \"1s\"");
    if (!text) return text.error();
    if (!*text) return std::optional<milliseconds>{};
    auto duration = parse_duration(**text, "", least);
    if (!duration) return ctx.fail(source_of(table, key), key_path(path, key), without_option_name(duration.error().message));
    // Sub-millisecond precision means nothing to a poll or a timeout; round to whole ms.
    return std::optional<milliseconds>{std::chrono::round<milliseconds>(*duration)};
}

// A duration within the range the schema gives the key (config_schema.hpp); refused outside it
// with the schema's words for the range and `hint` (an example; what "off" means).
Result<std::optional<milliseconds>> bounded_duration(const Context& ctx, const toml::table& table, const std::string& path,
                                                     std::string_view schema_table, std::string_view key, std::string_view hint) {
    const ConfigRange& range = config_range(schema_table, key);
    const milliseconds least{static_cast<long long>(range.least)};
    // A range of only "at least 1ms" is the duration parser's own ("give at least 1ms"); any
    // other is quoted here as the schema words it, never as 1ms.
    const bool bounded = std::isfinite(range.most);
    auto duration = optional_duration(ctx, table, path, key, !bounded && least <= milliseconds(1) ? least : milliseconds(0));
    if (!duration || !*duration) return duration;
    const bool too_long = bounded && **duration > milliseconds(static_cast<long long>(range.most));
    if (**duration < least || too_long) {
        return ctx.fail(source_of(table, key), key_path(path, key),
                        fmt::format("expected {} ({})", config_key(schema_table, key).bounds, hint));
    }
    return duration;
}

// Integers and numbers take the range the schema gives the key (config_schema.hpp), in
// `schema_table` ("lines.devices"), so the bounds checked are the ones the man page states.
Result<std::optional<long long>> optional_integer(const Context& ctx, const toml::table& table, const std::string& path,
                                                  std::string_view schema_table, std::string_view key) {
    const ConfigRange& range = config_range(schema_table, key);
    const auto min = static_cast<long long>(range.least);
    const auto max = static_cast<long long>(range.most);
    const std::string expected = fmt::format("an integer {}..{}", min, max);
    auto value = optional_value<std::int64_t>(ctx, table, path, key, expected);
    if (!value) return value.error();
    if (!*value) return std::optional<long long>{};
    if (**value < min || **value > max) {
        return ctx.fail(source_of(table, key), key_path(path, key), fmt::format("{} is out of range (expected {})", **value, expected));
    }
    return std::optional<long long>{**value};
}

Result<std::optional<double>> optional_number(const Context& ctx, const toml::table& table, const std::string& path,
                                              std::string_view schema_table, std::string_view key) {
    const ConfigRange& range = config_range(schema_table, key);
    const double min = range.least;
    const double max = range.most;
    const std::string expected = fmt::format("a number {}..{}", min, max);
    const toml::node* node = table.get(key);
    if (!node) return std::optional<double>{};
    std::optional<double> value;
    if (const auto* real = node->as_floating_point()) value = real->get();
    if (const auto* integer = node->as_integer()) value = static_cast<double>(integer->get());
    if (!value) return ctx.fail(node->source(), key_path(path, key), fmt::format("expected {}", expected));
    if (!(*value >= min && *value <= max)) {
        return ctx.fail(node->source(), key_path(path, key), fmt::format("{} is out of range (expected {})", *value, expected));
    }
    return value;
}

// An array of tables ([[lines]], [[lines.devices]]); absent is an empty list.
Result<std::vector<const toml::table*>> tables_of(const Context& ctx, const toml::table& table, const std::string& path,
                                                  std::string_view key) {
    std::vector<const toml::table*> tables;
    const toml::node* node = table.get(key);
    if (!node) return tables;
    const auto* array = node->as_array();
    if (array && array->empty()) return tables;  // "lines = []": the caller says what is missing
    if (!array || !array->is_array_of_tables()) {
        return ctx.fail(node->source(), key_path(path, key), fmt::format("expected [[{}]] tables", key_path(path, key)));
    }
    for (const toml::node& element : *array) tables.push_back(element.as_table());
    return tables;
}

// ---------------------------------------------------------------------------------------------
// Names go into MQTT topics and URLs: nothing there may need escaping.

bool name_character(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
}

Result<std::string> checked_name(const Context& ctx, const toml::table& table, const std::string& path) {
    auto name = required_string(ctx, table, path, "name", "\"furnace-line\"");
    if (!name) return name.error();
    if (name->empty() || !std::all_of(name->begin(), name->end(), name_character)) {
        return ctx.fail(source_of(table, "name"), key_path(path, "name"),
                        fmt::format("{} is not a valid name (expected letters, digits, '-' and '_' only: it is used "
                                    "in MQTT topics and URLs)", quoted_excerpt(*name)));
    }
    return name;
}

// Where each name, unit and Modbus TCP unit was first given, for messages about clashes.
struct Seen {
    std::string path;
    toml::source_index line = 0;
    std::string name;
};

struct DeviceSeen {
    Seen seen;
    std::uint8_t tcp_unit = 0;
    std::string tcp_unit_key;             // "tcp_unit", or "device" when the unit defaults from it
    toml::source_region tcp_unit_source;
};

struct Registry {
    std::map<std::string, Seen> line_names;
    std::map<std::string, Seen> line_ports;  // serial device paths, by path
    std::map<std::string, Seen> device_names;
    std::vector<DeviceSeen> devices;  // every device, in file order
};

Result<void> claim_name(const Context& ctx, std::map<std::string, Seen>& names, const Seen& claim,
                        const toml::source_region& where, std::string_view what) {
    auto [it, fresh] = names.emplace(claim.name, claim);
    if (fresh) return {};
    return ctx.fail(where, key_path(claim.path, "name"),
                    fmt::format("\"{}\" is already the name of {} (line {}); {} names must be unique", claim.name,
                                it->second.path, it->second.line, what));
}

// ---------------------------------------------------------------------------------------------
// Devices

// One name of `parameters`, resolved as `loopwire read` resolves names, so what works there
// works here. `named_at`: where each parameter was named first.
Result<std::string> polled_parameter(const Context& ctx, const toml::node& element, const std::string& list_path,
                                     std::size_t index, const device::Profile& profile, const std::string& device_name,
                                     std::map<const device::Parameter*, std::size_t>& named_at) {
    const std::string path = index_path(list_path, index);
    const auto* name = element.as_string();
    if (!name) return ctx.fail(element.source(), path, "expected a parameter name (a string)");
    auto found = device::resolve_parameters(profile, {name->get()});
    if (!found) return ctx.fail(element.source(), path, fmt::format("device {}: {}", device_name, found.error().message));
    for (const device::Parameter* parameter : *found) {
        if (!parameter->readable) {
            return ctx.fail(element.source(), path,
                            fmt::format("device {}: {} is write-only and cannot be polled", device_name, parameter->name));
        }
        // "PV" and "measured_value" are one parameter: polled once, so named once.
        const auto [first, added] = named_at.emplace(parameter, index);
        if (!added) {
            return ctx.fail(element.source(), path,
                            fmt::format("device {}: \"{}\" is {}, already named at {}; name each parameter once",
                                        device_name, name->get(), parameter->name, index_path(list_path, first->second)));
        }
    }
    return name->get();
}

// Each name of the list is checked, whatever is wrong with another.
std::vector<std::string> parameter_names(const Context& ctx, const toml::table& table, const std::string& path,
                                         const device::Profile& profile, const std::string& device_name) {
    std::vector<std::string> names;
    const toml::node* node = table.get("parameters");
    if (!node) return names;
    const std::string list_path = key_path(path, "parameters");
    const auto* array = node->as_array();
    if (!array) {
        ctx.note(ctx.fail(node->source(), list_path, "expected a list of parameter names, e.g. [\"measured_value\"]"));
        return names;
    }
    if (array->empty()) {
        ctx.note(ctx.fail(node->source(), list_path,
                          fmt::format("device {}: an empty list polls nothing; name the parameters to poll, or leave the "
                                      "key out for the profile's watch list", device_name)));
        return names;
    }
    std::map<const device::Parameter*, std::size_t> named_at;
    for (std::size_t i = 0; i < array->size(); ++i) {
        if (auto name = ctx.kept(polled_parameter(ctx, *array->get(i), list_path, i, profile, device_name, named_at))) {
            names.push_back(std::move(*name));
        }
    }
    return names;
}

Result<void> check_unit_free_on_line(const Context& ctx, const LineConfig& line, const DeviceConfig& device,
                                     const std::vector<Seen>& line_devices, const toml::source_region& where,
                                     const std::string& path) {
    for (std::size_t i = 0; i < line.devices.size(); ++i) {
        if (line.devices[i].address.unit != device.address.unit) continue;
        // One unit id answers once on a serial line: two devices there would answer together.
        return ctx.fail(where, key_path(path, "device"),
                        fmt::format("unit {} is already used by {} ({}, line {}) on line {}; each device on a line "
                                    "needs its own unit", device.address.unit, line.devices[i].name, line_devices[i].path,
                                    line_devices[i].line, line.name));
    }
    return {};
}

// A device answers only in the protocols its profile lists (its manual's): on a line of another,
// every poll would time out. RTU through a device server (rtu+tcp) is RTU; behind a Modbus TCP
// link is whatever the far gateway speaks to the device, which this side cannot see.
Result<void> check_protocol(const Context& ctx, const LineConfig& line, const DeviceConfig& device,
                            const toml::source_region& where, const std::string& path) {
    if (line.link.framing == transport::Framing::tcp) return {};
    const std::string spoken =
        transport::framing_name(line.link.framing == transport::Framing::rtu_over_tcp ? transport::Framing::rtu : line.link.framing);
    const auto& protocols = device.address.profile->protocols;
    if (std::find(protocols.begin(), protocols.end(), spoken) != protocols.end()) return {};
    return ctx.fail(where, key_path(path, "device"),
                    fmt::format("device {} ({}) does not speak {}, the protocol of line {} (it speaks {}): put it on a "
                                "line of its own protocol, or set the device and the link to one both speak",
                                device.name, device.address.profile->id, spoken, line.name, fmt::join(protocols, ", ")));
}

// `device = "PROFILE@UNIT"`.
Result<device::DeviceAddress> device_address(const Context& ctx, const toml::table& table, const std::string& path) {
    auto text = required_string(ctx, table, path, "device", "\"tc10@3\"");
    if (!text) return text.error();
    // The command line's "tc10" means unit 1; in a configuration, where each device of a line
    // needs its own unit, a unit left out is more likely forgotten than meant.
    if (text->find('@') == std::string::npos) {
        return ctx.fail(source_of(table, "device"), key_path(path, "device"),
                        fmt::format("\"{}\" names no unit: add the device's Modbus address after '@' (e.g. \"{}@1\")",
                                    *text, *text));
    }
    auto address = device::parse_device_address(ctx.profiles, *text);
    if (!address) return ctx.fail(source_of(table, "device"), key_path(path, "device"), address.error().message);
    return std::move(*address);
}

// `unit = N` and [[lines.devices.points]] instead of `device`: the points become the device's
// profile (device_points.hpp), and the points polled its parameters. Every mistake is noted.
std::optional<device::DeviceAddress> points_device_address(const Context& ctx, const toml::table& table,
                                                           const std::string& path, DeviceConfig& device) {
    if (table.contains("device")) {
        ctx.note(ctx.fail(source_of(table, "device"), key_path(path, "device"),
                          "a device is described by a profile (device = \"PROFILE@UNIT\") or by its points (unit = N "
                          "and [[lines.devices.points]]), not both: remove one"));
        return std::nullopt;
    }
    auto unit = ctx.kept(optional_integer(ctx, table, path, "lines.devices", "unit"));
    if (unit && !*unit) ctx.note(ctx.fail(table.source(), path, "missing `unit` (the device's Modbus address, e.g. unit = 1)"));
    auto points = points_profile(table, ctx.source, path, device.name, ctx.mistakes);
    if (!unit || !*unit || !points) return std::nullopt;
    auto profile = device::load_profile_text(points->document.dump(), "the profile of its points");
    if (!profile) {
        ctx.note(ctx.fail(table.source(), path, profile.error().message));
        return std::nullopt;
    }
    device.parameters = std::move(points->polled);
    return device::DeviceAddress{std::make_shared<const device::Profile>(std::move(*profile)),
                                 static_cast<std::uint8_t>(**unit), 0};
}

// The device, its mistakes noted; none when its profile and unit are unknown, which the checks
// of its parameters and against the line and the other devices need.
std::optional<DeviceConfig> parse_device(const Context& ctx, const toml::table& table, const std::string& path,
                                         Registry& registry, DeviceSeen& seen) {
    check_keys(ctx, table, path, "lines.devices");
    DeviceConfig device;
    // A device without a valid name is still checked, called by its place in the file.
    auto name = ctx.kept(checked_name(ctx, table, path));
    device.name = name ? std::move(*name) : path;
    seen.seen = Seen{path, table.source().begin.line, device.name};
    if (name) ctx.kept(claim_name(ctx, registry.device_names, seen.seen, source_of(table, "name"), "device"));
    if (auto poll = ctx.kept(bounded_duration(ctx, table, path, "lines.devices", "poll", "e.g. \"1s\"")); poll && *poll) {
        device.poll = **poll;
    }
    if (auto identify = ctx.kept(optional_value<bool>(ctx, table, path, "identify", "true or false")); identify && *identify) {
        device.identify = **identify;
    }
    auto tcp_unit = ctx.kept(optional_integer(ctx, table, path, "lines.devices", "tcp_unit"));
    if (!table.contains("points") && table.contains("unit")) {
        // Read for its mistakes too, so that a wrong unit is not hidden behind the one of `device`.
        ctx.kept(optional_integer(ctx, table, path, "lines.devices", "unit"));
        ctx.note(ctx.fail(source_of(table, "unit"), key_path(path, "unit"),
                          "`unit` goes with [[lines.devices.points]]; with a profile, the unit is given by device = "
                          "\"PROFILE@UNIT\": remove it"));
    }
    auto address = table.contains("points") ? points_device_address(ctx, table, path, device)
                                            : ctx.kept(device_address(ctx, table, path));
    if (!address) return std::nullopt;
    device.address = std::move(*address);
    if (table.contains("parameters") || !table.contains("points")) {
        device.parameters = parameter_names(ctx, table, path, *device.address.profile, device.name);
    }
    // A wrong tcp_unit leaves seen.tcp_unit 0, out of the clash check: its own mistake is said.
    if (!tcp_unit) return device;
    // The manuals allow units past 247 (AC20: 1-255, TC10: up to 254), Modbus TCP clients reach
    // 1..247 only (application protocol V1.1b3, 4.2: 248-255 reserved).
    if (!*tcp_unit && device.address.unit > 247) {
        ctx.note(ctx.fail(source_of(table, "device"), key_path(path, "device"),
                          fmt::format("device {}: unit {} cannot be a Modbus TCP unit (1..247); give it one with "
                                      "tcp_unit = N", device.name, device.address.unit)));
        return device;
    }
    device.tcp_unit = *tcp_unit ? static_cast<std::uint8_t>(**tcp_unit) : device.address.unit;  // 1..247, checked
    seen.tcp_unit = device.tcp_unit;
    seen.tcp_unit_key = *tcp_unit ? "tcp_unit" : "device";
    seen.tcp_unit_source = source_of(table, seen.tcp_unit_key);
    return device;
}

// `link_known`: whether the line's link parsed; a device's protocol is checked against it only then.
void parse_devices(const Context& ctx, const toml::table& table, const std::string& path, Registry& registry,
                   LineConfig& line, bool link_known) {
    auto tables = ctx.kept(tables_of(ctx, table, path, "devices"));
    if (!tables) return;
    std::vector<Seen> line_devices;
    for (std::size_t i = 0; i < tables->size(); ++i) {
        const std::string device_path = index_path(key_path(path, "devices"), i);
        DeviceSeen seen;
        auto device = parse_device(ctx, *(*tables)[i], device_path, registry, seen);
        if (!device) continue;
        const auto& where = source_of(*(*tables)[i], "device");
        if (link_known) ctx.kept(check_protocol(ctx, line, *device, where, device_path));
        ctx.kept(check_unit_free_on_line(ctx, line, *device, line_devices, where, device_path));
        line_devices.push_back(seen.seen);
        registry.devices.push_back(std::move(seen));
        line.devices.push_back(std::move(*device));
    }
}

// ---------------------------------------------------------------------------------------------
// Lines

// `speed` and `seed` set the simulation of a virtual line and mean nothing on a real one.
// On a real line only their being there is the mistake, whatever their values.
void parse_line_simulation(const Context& ctx, const toml::table& table, const std::string& path, LineConfig& line) {
    if (!is_virtual_bus(line.link)) {
        for (std::string_view key : {"speed", "seed"}) {
            if (!table.contains(key)) continue;
            ctx.note(ctx.fail(source_of(table, key), key_path(path, key),
                              fmt::format("{} applies to a simulated line only (link = \"rtu:virtual?baud=19200\"); "
                                          "remove it for a line with a real device", key)));
        }
        return;
    }
    auto speed = ctx.kept(optional_number(ctx, table, path, "lines", "speed"));
    auto seed = ctx.kept(optional_integer(ctx, table, path, "lines", "seed"));
    LineSimulation simulation;
    if (speed && *speed) simulation.speed = **speed;
    if (seed && *seed) simulation.seed = static_cast<std::uint64_t>(**seed);
    line.simulation = simulation;
}

// A serial line carries one request at a time: RTU, ASCII and Linking replies say nothing of
// which request they answer, and neither does RTU through a device server (rtu+tcp).
Result<void> parse_max_in_flight(const Context& ctx, const toml::table& table, const std::string& path, LineConfig& line) {
    auto in_flight = optional_integer(ctx, table, path, "lines", "max_in_flight");
    if (!in_flight) return in_flight.error();
    if (!*in_flight) return {};
    if (**in_flight > 1 && line.link.framing != transport::Framing::tcp) {
        return ctx.fail(source_of(table, "max_in_flight"), key_path(path, "max_in_flight"),
                        fmt::format("a {} line carries one request at a time; more than 1 needs a Modbus TCP device "
                                    "(link = \"tcp://host:502\"), whose replies carry the request's transaction id",
                                    transport::framing_name(line.link.framing)));
    }
    line.max_in_flight = static_cast<std::size_t>(**in_flight);
    return {};
}

// `rs485 = true`, false or "auto".
Result<std::optional<transport::Rs485>> rs485_setting(const Context& ctx, const toml::table& table, const std::string& path) {
    const toml::node* rs485 = table.get("rs485");
    if (!rs485) return std::optional<transport::Rs485>{};
    if (const auto* on = rs485->as_boolean()) return std::optional{on->get() ? transport::Rs485::on : transport::Rs485::off};
    if (const auto* text = rs485->as_string(); text && text->get() == "auto") return std::optional{transport::Rs485::if_supported};
    return ctx.fail(rs485->source(), key_path(path, "rs485"), "expected true, false or \"auto\"");
}

// RS-485 direction control and the guard time of a serial line: keys of their own in the table,
// which override the same options in the link URL.
void parse_line_serial_keys(const Context& ctx, const toml::table& table, const std::string& path, LineConfig& line) {
    static constexpr std::array serial_keys{"rs485", "rs485_delay_before", "rs485_delay_after", "guard"};
    if (!line.link.is_serial()) {
        for (const char* key : serial_keys) {
            if (!table.get(key)) continue;
            ctx.note(ctx.fail(source_of(table, key), key_path(path, key),
                              fmt::format("{} applies to a serial line only (this link is {})", key, line.link.to_string())));
        }
        return;
    }
    auto& serial = line.link.serial;
    if (auto rs485 = ctx.kept(rs485_setting(ctx, table, path)); rs485 && *rs485) serial.rs485 = **rs485;
    auto before = ctx.kept(bounded_duration(ctx, table, path, "lines", "rs485_delay_before", "e.g. \"1ms\""));
    if (before && *before) serial.rs485_delay_before = **before;
    auto after = ctx.kept(bounded_duration(ctx, table, path, "lines", "rs485_delay_after", "e.g. \"1ms\""));
    if (after && *after) serial.rs485_delay_after = **after;
    auto guard_text = ctx.kept(optional_value<std::string>(ctx, table, path, "guard", "a string such as \"3.5c\" or \"5ms\""));
    if (guard_text && *guard_text) {
        auto guard = transport::parse_line_guard(**guard_text);
        if (guard) {
            serial.guard = *guard;
        } else {
            ctx.note(ctx.fail(source_of(table, "guard"), key_path(path, "guard"), guard.error().message));
        }
    }
}

Result<transport::LinkUrl> line_link(const Context& ctx, const toml::table& table, const std::string& path) {
    auto link_text = required_string(ctx, table, path, "link", "\"rtu:/dev/ttyUSB0?baud=19200\"");
    if (!link_text) return link_text.error();
    auto link = transport::parse_link_url(*link_text);
    if (!link) return ctx.fail(source_of(table, "link"), key_path(path, "link"), link.error().message);
    return std::move(*link);
}

// The line's own keys; false when its link is unknown, which the serial keys, max_in_flight,
// the simulation and the devices' protocols are checked against.
bool parse_line_settings(const Context& ctx, const toml::table& table, const std::string& path, LineConfig& line) {
    if (auto timeout = ctx.kept(bounded_duration(ctx, table, path, "lines", "timeout", "e.g. \"1s\"")); timeout && *timeout) {
        line.timeout = **timeout;
    }
    if (auto retries = ctx.kept(optional_integer(ctx, table, path, "lines", "retries")); retries && *retries) {
        line.retries = static_cast<unsigned>(**retries);  // 0..10, checked
    }
    auto late_reply_window = ctx.kept(bounded_duration(ctx, table, path, "lines", "late_reply_window",
                                                       "e.g. \"500ms\", default: the line's timeout"));
    if (late_reply_window && *late_reply_window) line.late_reply_window = **late_reply_window;
    auto link = ctx.kept(line_link(ctx, table, path));
    if (!link) return false;
    line.link = std::move(*link);
    line.link_written_at = fmt::format("{}:{}", ctx.source, source_of(table, "link").begin.line);
    parse_line_serial_keys(ctx, table, path, line);
    ctx.kept(parse_max_in_flight(ctx, table, path, line));
    parse_line_simulation(ctx, table, path, line);
    return true;
}

// One serial port is one line: two lines on it would each open it, and the second would find it
// "in use by another program" only when the gateway runs. Virtual lines and TCP links have no
// port to share.
Result<void> claim_port(const Context& ctx, Registry& registry, const Seen& line_seen, const toml::table& table,
                        const LineConfig& line) {
    if (!line.link.is_serial() || line.simulation) return {};
    const auto [first, fresh] = registry.line_ports.emplace(line.link.path, line_seen);
    if (fresh) return {};
    return ctx.fail(source_of(table, "link"), key_path(line_seen.path, "link"),
                    fmt::format("{} is already the port of line {} ({}, line {}); one port is one line: put the devices of "
                                "both in one [[lines]] table", line.link.path, first->second.name, first->second.path,
                                first->second.line));
}

LineConfig parse_line(const Context& ctx, const toml::table& table, const std::string& path, Registry& registry) {
    check_keys(ctx, table, path, "lines");
    LineConfig line;
    // A line without a valid name is still checked, called by its place in the file.
    auto name = ctx.kept(checked_name(ctx, table, path));
    line.name = name ? std::move(*name) : path;
    const Seen seen{path, table.source().begin.line, line.name};
    if (name) ctx.kept(claim_name(ctx, registry.line_names, seen, source_of(table, "name"), "line"));
    const bool link_known = parse_line_settings(ctx, table, path, line);
    if (link_known) ctx.kept(claim_port(ctx, registry, seen, table, line));
    parse_devices(ctx, table, path, registry, line, link_known);
    return line;
}

// The lowest Modbus TCP unit no device uses, to suggest in a clash message.
unsigned free_tcp_unit(const std::vector<DeviceSeen>& devices) {
    std::set<unsigned> used;
    for (const DeviceSeen& device : devices) used.insert(device.tcp_unit);
    unsigned unit = 1;
    while (unit <= 247 && used.count(unit) != 0) ++unit;
    return unit;
}

// Modbus TCP clients address devices by unit id alone, across every line: each needs its own.
// Each device that takes a unit an earlier one has is a mistake of its own; one whose unit is
// unknown (0: its tcp_unit or device is wrong, and said so) clashes with none.
void check_tcp_units(const Context& ctx, const std::vector<DeviceSeen>& devices) {
    for (std::size_t later = 0; later < devices.size(); ++later) {
        if (devices[later].tcp_unit == 0) continue;
        for (std::size_t earlier = 0; earlier < later; ++earlier) {
            if (devices[earlier].tcp_unit != devices[later].tcp_unit) continue;
            const Seen& a = devices[earlier].seen;
            const Seen& b = devices[later].seen;
            ctx.note(ctx.fail(devices[later].tcp_unit_source, key_path(b.path, devices[later].tcp_unit_key),
                              fmt::format("Modbus TCP unit {} would be both {} ({}, line {}) and {} ({}, line {}); map one "
                                          "of them to another unit with tcp_unit = {}", devices[later].tcp_unit, a.name,
                                          a.path, a.line, b.name, b.path, b.line, free_tcp_unit(devices))));
            break;
        }
    }
}

std::vector<LineConfig> parse_lines(const Context& ctx, const toml::table& root, Registry& registry) {
    std::vector<LineConfig> lines;
    auto tables = ctx.kept(tables_of(ctx, root, "", "lines"));
    if (!tables) return lines;
    if (tables->empty()) {
        ctx.note(ctx.fail(source_of(root, "lines"), "lines",
                          "no lines: at least one [[lines]] table is needed, with a name and a link"));
    }
    for (std::size_t i = 0; i < tables->size(); ++i) lines.push_back(parse_line(ctx, *(*tables)[i], index_path("lines", i), registry));
    return lines;
}

// ---------------------------------------------------------------------------------------------
// [log]

Result<LogConfig::Level> log_level(const Context& ctx, const toml::table& table) {
    auto text = optional_value<std::string>(ctx, table, "log", "level", "a string: \"debug\", \"info\", \"warning\" or \"error\"");
    if (!text) return text.error();
    if (!*text) return LogConfig::Level::info;
    constexpr std::pair<std::string_view, LogConfig::Level> levels[] = {
        {"debug", LogConfig::Level::debug}, {"info", LogConfig::Level::info},
        {"warning", LogConfig::Level::warning}, {"error", LogConfig::Level::error}};
    for (const auto& [name, level] : levels) {
        if (**text == name) return level;
    }
    return ctx.fail(source_of(table, "level"), "log.level",
                    fmt::format("{} is not a log level (expected \"debug\", \"info\", \"warning\" or \"error\")", quoted_excerpt(**text)));
}

// `statistics = "60s"` logs each line's figures that often; "off" only at exit. Less than a
// second apart would bury everything else in the log.
Result<std::chrono::milliseconds> statistics_interval(const Context& ctx, const toml::table& table) {
    const toml::node* node = table.get("statistics");
    if (node && node->value<std::string>() == "off") return milliseconds(0);
    auto interval = bounded_duration(ctx, table, "log", "log", "statistics",
                                     "closer together they would bury the log in figures; e.g. \"60s\", or \"off\" for only at exit");
    if (!interval) return interval.error();
    if (!*interval) return LogConfig{}.statistics;
    return **interval;
}

LogConfig parse_log(const Context& ctx, const toml::table& root) {
    LogConfig config;
    const toml::node* node = root.get("log");
    if (!node) return config;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "log", "expected a [log] table"));
        return config;
    }
    check_keys(ctx, *table, "log", "log");
    if (auto level = ctx.kept(log_level(ctx, *table))) config.level = *level;
    if (auto interval = ctx.kept(statistics_interval(ctx, *table))) config.statistics = *interval;
    return config;
}

// ---------------------------------------------------------------------------------------------
// [modbus_tcp]

struct HostPort {
    std::string host;
    std::uint16_t port = 0;
};

// "HOST:PORT", or "[IPV6]:PORT": the brackets keep the address's own colons apart from the
// port's. The host is kept without them, as the socket layer takes it.
// A host the gateway can listen on or connect to: an IPv6 address in brackets, an IPv4 address
// (anything of digits and dots must be one: "999.1.1.1" is no name either), or a host name.
// Otherwise --check would pass what the start cannot resolve.
bool valid_host(std::string_view host, bool bracketed) {
    if (host.empty()) return false;
    const std::string text(host);
    if (bracketed) {
        in6_addr address{};
        return ::inet_pton(AF_INET6, text.c_str(), &address) == 1;
    }
    if (host.find_first_not_of("0123456789.") == std::string_view::npos) {
        in_addr address{};
        return ::inet_pton(AF_INET, text.c_str(), &address) == 1;
    }
    const bool name_characters = std::all_of(host.begin(), host.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '-' || c == '.';
    });
    return name_characters && host.front() != '-' && host.front() != '.' && host.find("..") == std::string_view::npos;
}

std::optional<HostPort> split_listen(std::string_view text) {
    std::string_view host;
    std::string_view port;
    if (!text.empty() && text.front() == '[') {
        const auto close = text.find(']');
        if (close == std::string_view::npos || close + 1 >= text.size() || text[close + 1] != ':') return std::nullopt;
        host = text.substr(1, close - 1);
        port = text.substr(close + 2);
    } else {
        const auto colon = text.find(':');
        if (colon == std::string_view::npos || text.find(':', colon + 1) != std::string_view::npos) return std::nullopt;
        host = text.substr(0, colon);
        port = text.substr(colon + 1);
    }
    const auto number = parse_decimal_digits(port);
    // Port 0: the kernel picks a free one, which the gateway prints when it starts (tests, and
    // several gateways on one machine).
    if (!valid_host(host, text.front() == '[') || !number || *number > 65535) return std::nullopt;
    return HostPort{std::string(host), static_cast<std::uint16_t>(*number)};  // 0..65535, checked
}

// `allow = ["10.1.0.0/16", "fd00::/8", "192.168.1.20"]` (key `key` of [section]): the client
// addresses a front serves; absent or empty: every address. Each entry is checked, whatever is
// wrong with another; the list is the entries that parse.
transport::AddressAllowList address_list(const Context& ctx, const toml::table& table, const std::string& section,
                                         const std::string& key) {
    const toml::node* node = table.get(key);
    if (!node) return {};
    const auto* array = node->as_array();
    const std::string path = section + "." + key;
    constexpr std::string_view example = "[\"10.1.0.0/16\", \"192.168.1.20\", \"fd00::/8\"]";
    if (!array) {
        ctx.note(ctx.fail(node->source(), path, fmt::format("expected a list of addresses and networks, e.g. {}", example)));
        return {};
    }
    std::vector<std::string> entries;
    for (std::size_t i = 0; i < array->size(); ++i) {
        const toml::node& element = *array->get(i);
        const auto* entry = element.as_string();
        if (!entry) {
            ctx.note(ctx.fail(element.source(), index_path(path, i),
                              fmt::format("expected an address or a network (a string), e.g. {}", example)));
        } else if (auto checked = transport::check_allow_entry(entry->get()); !checked) {
            ctx.note(ctx.fail(element.source(), index_path(path, i), checked.error().message));
        } else {
            entries.push_back(entry->get());
        }
    }
    auto list = transport::AddressAllowList::parse(entries);
    return list ? std::move(*list) : transport::AddressAllowList{};  // every entry was checked above
}

// `idle_timeout = "60s"`: a Modbus TCP connection quiet this long is closed; "off": never. Under
// a second would close clients that poll every second between two of their requests.
Result<std::optional<milliseconds>> front_idle_timeout(const Context& ctx, const toml::table& table) {
    const toml::node* node = table.get("idle_timeout");
    if (node && node->value<std::string>() == "off") return std::optional<milliseconds>{milliseconds(0)};
    return bounded_duration(ctx, table, "modbus_tcp", "modbus_tcp", "idle_timeout",
                            "e.g. \"60s\"; \"off\" keeps idle connections open");
}

ModbusTcpConfig parse_modbus_tcp(const Context& ctx, const toml::table& root) {
    ModbusTcpConfig config;
    const toml::node* node = root.get("modbus_tcp");
    if (!node) return config;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "modbus_tcp", "expected a [modbus_tcp] table"));
        return config;
    }
    check_keys(ctx, *table, "modbus_tcp", "modbus_tcp");
    auto listen = ctx.kept(optional_value<std::string>(ctx, *table, "modbus_tcp", "listen", "a string such as \"127.0.0.1:1502\""));
    if (listen && *listen) {
        if (auto address = split_listen(**listen)) {
            config.host = std::move(address->host);
            config.port = address->port;
        } else {
            ctx.note(ctx.fail(source_of(*table, "listen"), "modbus_tcp.listen",
                              fmt::format("{} is not an address to listen on (expected HOST:PORT with a port 0..65535, "
                                          "0 for any free one, e.g. \"127.0.0.1:1502\", \"0.0.0.0:502\" or \"[::1]:1502\")",
                                          quoted_excerpt(**listen))));
        }
    }
    auto writes = ctx.kept(optional_value<bool>(ctx, *table, "modbus_tcp", "writes", "true or false"));
    if (writes && *writes) config.writes = **writes;
    auto enabled = ctx.kept(optional_value<bool>(ctx, *table, "modbus_tcp", "enabled", "true or false"));
    if (enabled && *enabled) config.enabled = **enabled;
    auto max_age = ctx.kept(bounded_duration(ctx, *table, "modbus_tcp", "modbus_tcp", "max_age", "e.g. \"250ms\""));
    if (max_age && *max_age) config.max_age = **max_age;
    auto max_connections = ctx.kept(optional_integer(ctx, *table, "modbus_tcp", "modbus_tcp", "max_connections"));
    if (max_connections && *max_connections) config.max_connections = static_cast<std::size_t>(**max_connections);  // 1..10000, checked
    auto idle_timeout = ctx.kept(front_idle_timeout(ctx, *table));
    if (idle_timeout && *idle_timeout) config.idle_timeout = **idle_timeout;
    config.allow = address_list(ctx, *table, "modbus_tcp", "allow");
    config.write_allow = address_list(ctx, *table, "modbus_tcp", "write_allow");
    return config;
}

// ---------------------------------------------------------------------------------------------
// [mqtt]

// "mqtt://HOST[:PORT]" or "mqtts://HOST[:PORT]"; the port defaults to MQTT's 1883, or 8883 over
// TLS (the ports IANA assigned to MQTT).
std::optional<HostPort> split_broker(std::string_view text, bool& tls) {
    constexpr std::string_view plain = "mqtt://";
    constexpr std::string_view secure = "mqtts://";
    tls = text.substr(0, secure.size()) == secure;
    if (!tls && text.substr(0, plain.size()) != plain) return std::nullopt;
    text.remove_prefix(tls ? secure.size() : plain.size());
    if (!text.empty() && text.back() == '/') text.remove_suffix(1);
    if (text.empty() || text.find('/') != std::string_view::npos) return std::nullopt;
    const bool bracketed = text.front() == '[';
    const bool has_port = bracketed ? text.find("]:") != std::string_view::npos
                                    : text.find(':') != std::string_view::npos && text.find(':') == text.rfind(':');
    if (!has_port) {
        if (!bracketed && text.find(':') != std::string_view::npos) return std::nullopt;  // a bare IPv6 address
        std::string host(text);
        if (bracketed) {
            if (host.back() != ']') return std::nullopt;
            host = host.substr(1, host.size() - 2);
        }
        if (host.empty()) return std::nullopt;
        return HostPort{std::move(host), static_cast<std::uint16_t>(tls ? 8883 : 1883)};
    }
    auto address = split_listen(text);
    if (!address || address->port == 0) return std::nullopt;
    return address;
}

// Topic levels joined by '/': none empty, no wildcards, no NUL (MQTT 3.1.1, 4.7).
// Levels joined by '/', none empty, without wildcards, spaces or control characters, and not
// under "$": brokers keep topics starting with '$' for themselves ($SYS/, MQTT 3.1.1, 4.7.2), and
// clients subscribing to '#' do not see them.
bool valid_prefix(std::string_view prefix) {
    if (prefix.empty() || prefix.front() == '/' || prefix.back() == '/' || prefix.front() == '$') return false;
    if (prefix.find("//") != std::string_view::npos) return false;
    return std::none_of(prefix.begin(), prefix.end(), [](char c) {
        return c == '+' || c == '#' || c == ' ' || static_cast<unsigned char>(c) < 0x20 || c == 0x7F;
    });
}

// A file named in the configuration: relative paths are taken from the configuration's folder.
std::filesystem::path beside_config(const Context& ctx, const std::string& file) {
    const std::filesystem::path path(file);
    return path.is_absolute() ? path : std::filesystem::path(ctx.source).parent_path() / path;
}

// A file named in the configuration that is not a regular file is refused before it is opened
// (common/regular_file.hpp): a FIFO would block `--check`, and a reload on the thread that also
// takes SIGTERM. `expected` says what the key should name.
Error not_regular(const Context& ctx, const toml::source_region& where, const std::string& key, const std::string& what,
                  std::string_view expected) {
    return ctx.fail(where, key, fmt::format("{} (expected {}); name a regular file", what, expected));
}

// An optional file key of [mqtt] or [sparkplug] (`table_name`: ca_file, ...) that must name a readable regular file. Checked
// with stat() and access(), without opening it.
Result<std::filesystem::path> readable_file(const Context& ctx, const toml::table& table, const std::string& table_name,
                                            std::string_view key, std::string_view expected) {
    auto name = optional_value<std::string>(ctx, table, table_name, key, "a file name (a string)");
    if (!name) return name.error();
    if (!*name) return std::filesystem::path{};
    const auto path = beside_config(ctx, **name);
    const auto where = source_of(table, key);
    if (auto what = not_a_regular_file(path)) {
        return not_regular(ctx, where, key_path(table_name, key), fmt::format("\"{}\" {}", path.string(), *what), expected);
    }
    if (::access(path.c_str(), R_OK) != 0) {
        return ctx.fail(where, key_path(table_name, key),
                        fmt::format("cannot read \"{}\" ({}); let the gateway's user read it",
                                    path.string(), std::error_code(errno, std::generic_category()).message()));
    }
    return path;
}

// The first line of `text`, without its line end.
std::string first_line(const std::string& text) {
    std::string line = text.substr(0, text.find('\n'));
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return line;
}

// Password and token files hold one short line; anything this large is the wrong file.
constexpr std::size_t max_secret_file_size = 64 * 1024;

// [mqtt] (or [sparkplug], [history]) password_file: the password is kept out of the TOML (which
// people share and paste), in a file only its owner may read. `whose`: "broker", "PostgreSQL".
Result<std::string> read_password(const Context& ctx, const toml::table& table, const std::string& table_name,
                                  std::string_view whose = "broker") {
    const std::string key = key_path(table_name, "password_file");
    const std::string expected = fmt::format("a file whose first line is the {} password", whose);
    auto path = readable_file(ctx, table, table_name, "password_file", expected);
    if (!path) return path.error();
    if (path->empty()) return std::string();
    const auto where = source_of(table, "password_file");
    std::error_code error;
    const auto permissions = std::filesystem::status(*path, error).permissions();
    if (!error && (permissions & std::filesystem::perms::others_read) != std::filesystem::perms::none) {
        return ctx.fail(where, key,
                        fmt::format("\"{}\" is readable by every user; make it private (chmod 600 {})", path->string(),
                                    path->string()));
    }
    auto text = read_regular_file(*path, max_secret_file_size);
    if (!text) return not_regular(ctx, where, key, text.error().message, expected);
    std::string password = first_line(*text);  // a trailing newline is not part of it
    if (password.empty()) {
        return ctx.fail(where, key, fmt::format("\"{}\" is empty (expected the password on its first line)",
                                                                path->string()));
    }
    return password;
}

// The broker's TLS files and credentials, the same keys in [mqtt] and [sparkplug].
template <typename BrokerConfig>
void parse_broker_security(const Context& ctx, const toml::table& table, const std::string& table_name, bool tls,
                           BrokerConfig& config) {
    auto ca_file = ctx.kept(readable_file(ctx, table, table_name, "ca_file", "the broker's CA certificate, PEM"));
    auto cert_file = ctx.kept(readable_file(ctx, table, table_name, "cert_file", "the gateway's client certificate, PEM"));
    auto key_file = ctx.kept(readable_file(ctx, table, table_name, "key_file", "the private key of cert_file, PEM"));
    for (const auto key : {"ca_file", "cert_file", "key_file"}) {
        if (!tls && table.get(key)) {
            ctx.note(ctx.fail(source_of(table, key), key_path(table_name, key),
                              fmt::format("only used over TLS; the broker is {} (write mqtts://... to use TLS)", config.broker)));
        }
    }
    // Whether both are written, whatever is wrong with the files they name.
    if (table.contains("cert_file") != table.contains("key_file")) {
        const auto* missing = table.contains("cert_file") ? "key_file" : "cert_file";
        ctx.note(ctx.fail(table.source(), table_name, fmt::format("cert_file and key_file go together: `{}` is missing", missing)));
    }
    if (tls) config.tls = MqttTls{ca_file.value_or(""), cert_file.value_or(""), key_file.value_or("")};
    auto username = ctx.kept(optional_value<std::string>(ctx, table, table_name, "username", "a string such as \"gateway\""));
    if (username && *username) config.username = **username;
    if (auto password = ctx.kept(read_password(ctx, table, table_name))) config.password = std::move(*password);
    if (!config.password.empty() && !table.contains("username")) {
        ctx.note(ctx.fail(source_of(table, "password_file"), key_path(table_name, "password_file"),
                          "a password needs a `username` too"));
    }
}

void parse_mqtt_publishing(const Context& ctx, const toml::table& table, MqttConfig& config) {
    auto republish = ctx.kept(optional_value<std::string>(ctx, table, "mqtt", "republish", "a duration such as \"5m\", or \"off\""));
    if (republish && *republish == "off") {
        config.republish.reset();
    } else if (republish && *republish) {
        auto every = ctx.kept(bounded_duration(ctx, table, "mqtt", "mqtt", "republish",
                                               "e.g. \"5m\"; \"off\": values are then published only when they change"));
        if (every && *every) config.republish = **every;
    }
    auto discovery = ctx.kept(optional_value<std::string>(ctx, table, "mqtt", "discovery", "\"homeassistant\" or \"none\""));
    if (discovery && *discovery == "homeassistant") {
        config.discovery = MqttConfig::Discovery::homeassistant;
    } else if (discovery && *discovery && **discovery != "none") {
        ctx.note(ctx.fail(source_of(table, "discovery"), "mqtt.discovery",
                          fmt::format("{} is not a discovery scheme (expected \"homeassistant\" or \"none\")",
                                      quoted_excerpt(**discovery))));
    }
    auto discovery_prefix =
        ctx.kept(optional_value<std::string>(ctx, table, "mqtt", "discovery_prefix", "a string such as \"homeassistant\""));
    if (discovery_prefix && *discovery_prefix) {
        const auto& text = **discovery_prefix;
        if (valid_prefix(text)) {
            config.discovery_prefix = text;
        } else {
            ctx.note(ctx.fail(source_of(table, "discovery_prefix"), "mqtt.discovery_prefix",
                              fmt::format("{} is not a topic prefix (expected levels joined by '/', none empty, "
                                          "without '+', '#' or spaces, e.g. \"homeassistant\")", quoted_excerpt(text))));
        }
    }
}

// The prefix's last level with anything but letters, digits, '-' and '_' made '_'.
std::string last_level_name(const std::string& prefix) {
    std::string name = prefix.substr(prefix.rfind('/') + 1);
    std::replace_if(name.begin(), name.end(), [](char c) { return !name_character(c); }, '_');
    return name;
}

// `broker` and its security keys, the same in [mqtt] and [sparkplug]. Whether the TLS files
// belong depends on the broker's scheme: with the broker wrong they are not looked at.
template <typename BrokerConfig>
void parse_broker(const Context& ctx, const toml::table& table, const std::string& table_name, BrokerConfig& config) {
    auto broker = ctx.kept(required_string(ctx, table, table_name, "broker", "\"mqtt://127.0.0.1:1883\""));
    if (!broker) return;
    bool tls = false;
    auto address = split_broker(*broker, tls);
    if (!address) {
        ctx.note(ctx.fail(source_of(table, "broker"), key_path(table_name, "broker"),
                          fmt::format("{} is not a broker address (expected mqtt://HOST[:PORT], or mqtts://HOST[:PORT] "
                                      "for TLS, with a port 1..65535, e.g. \"mqtt://127.0.0.1:1883\")", quoted_excerpt(*broker))));
        return;
    }
    config.broker = *broker;
    config.host = std::move(address->host);
    config.port = address->port;
    parse_broker_security(ctx, table, table_name, tls, config);
}

// The dashboard's address as a browser elsewhere on the network reaches it: the listen address,
// or the machine's host name for a wildcard one. Empty for port 0 (any free port, known only
// once the front listens: tests).
std::string dashboard_url(const HttpConfig& http) {
    if (http.port == 0) return {};
    std::string host = http.host;
    if (host.empty() || host == "0.0.0.0" || host == "::") {
        std::array<char, 256> name{};
        if (::gethostname(name.data(), name.size() - 1) != 0 || name[0] == '\0') return {};
        host = name.data();
    }
    const bool ipv6 = host.find(':') != std::string::npos;
    return fmt::format("http://{}{}{}:{}/", ipv6 ? "[" : "", host, ipv6 ? "]" : "", http.port);
}

std::optional<MqttConfig> parse_mqtt(const Context& ctx, const toml::table& root, const std::string& gateway_name) {
    const toml::node* node = root.get("mqtt");
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "mqtt", "expected an [mqtt] table"));
        return std::nullopt;
    }
    check_keys(ctx, *table, "mqtt", "mqtt");
    MqttConfig config;
    parse_broker(ctx, *table, "mqtt", config);
    if (!gateway_name.empty()) config.prefix = "loopwire/" + gateway_name;
    auto prefix = ctx.kept(optional_value<std::string>(ctx, *table, "mqtt", "prefix", "a string such as \"loopwire/plant1\""));
    if (prefix && *prefix) {
        if (valid_prefix(**prefix)) {
            config.prefix = std::move(**prefix);
        } else {
            ctx.note(ctx.fail(source_of(*table, "prefix"), "mqtt.prefix",
                              fmt::format("{} is not a topic prefix (expected levels joined by '/', none empty, "
                                          "without '+', '#' or spaces, not starting with '$', e.g. \"loopwire/plant1\")",
                                          quoted_excerpt(**prefix))));
        }
    }
    config.gateway_name = gateway_name.empty() ? last_level_name(config.prefix) : gateway_name;
    auto writes = ctx.kept(optional_value<bool>(ctx, *table, "mqtt", "writes", "true or false"));
    if (writes && *writes) config.writes = **writes;
    auto client_id = ctx.kept(optional_value<std::string>(ctx, *table, "mqtt", "client_id", "a string such as \"gateway-plant1\""));
    if (client_id && *client_id) {
        // MQTT 3.1.1 (3.1.3.1): brokers must accept 1..23 characters; most take more.
        if ((*client_id)->empty() || (*client_id)->size() > 256) {
            ctx.note(ctx.fail(source_of(*table, "client_id"), "mqtt.client_id", "expected 1..256 characters"));
        } else {
            config.client_id = std::move(**client_id);
        }
    }
    parse_mqtt_publishing(ctx, *table, config);
    // A value is a few bytes; 64 KiB is far beyond any, and still small to hold a few hundred of.
    auto max_payload = ctx.kept(optional_integer(ctx, *table, "mqtt", "mqtt", "max_payload"));
    if (max_payload && *max_payload) config.max_payload = static_cast<std::size_t>(**max_payload);  // 16..65536, checked
    return config;
}

// ---------------------------------------------------------------------------------------------
// [sparkplug]

// A Sparkplug B id (group_id, edge_node_id, primary_host): one topic level (Sparkplug 3.0, 4.1:
// no '+', '/' or '#'), kept to the characters device names have, plus '.', so that it never
// needs escaping in a host application's tag path either.
Result<std::optional<std::string>> sparkplug_id(const Context& ctx, const toml::table& table, std::string_view key,
                                                std::string_view example) {
    auto id = optional_value<std::string>(ctx, table, "sparkplug", key, fmt::format("a string such as {}", example));
    if (!id || !*id) return id;
    const std::string& text = **id;
    const bool valid = !text.empty() && text.size() <= 64 &&
                       std::all_of(text.begin(), text.end(), [](char c) { return name_character(c) || c == '.'; });
    if (!valid) {
        return ctx.fail(source_of(table, key), key_path("sparkplug", key),
                        fmt::format("{} is not a Sparkplug id (expected 1..64 letters, digits, '.', '-' or '_', e.g. {})",
                                    quoted_excerpt(text), example));
    }
    return id;
}

// `state_file`: created when absent; when present it must be a regular file.
Result<std::filesystem::path> sparkplug_state_file(const Context& ctx, const toml::table& table) {
    auto state_file = optional_value<std::string>(ctx, table, "sparkplug", "state_file", "a file name such as \"sparkplug.state\"");
    if (!state_file) return state_file.error();
    if (!*state_file) return std::filesystem::path{};
    if ((*state_file)->empty()) return ctx.fail(source_of(table, "state_file"), "sparkplug.state_file", "expected a file name");
    const std::filesystem::path path = beside_config(ctx, **state_file);
    if (auto what = not_a_regular_file(path); what && *what != "does not exist") {
        return not_regular(ctx, source_of(table, "state_file"), "sparkplug.state_file", fmt::format("\"{}\" {}", path.string(), *what),
                           "the node's small state file, created when absent");
    }
    return path;
}

// `store_and_forward = "10m"`: how long the values the node could not send are kept; "off"
// (the default): none are.
Result<std::optional<std::chrono::milliseconds>> sparkplug_store_and_forward(const Context& ctx, const toml::table& table) {
    auto store = optional_value<std::string>(ctx, table, "sparkplug", "store_and_forward", "a duration such as \"10m\", or \"off\"");
    if (!store) return store.error();
    if (!*store || **store == "off") return std::optional<std::chrono::milliseconds>{};
    auto kept = bounded_duration(ctx, table, "sparkplug", "sparkplug", "store_and_forward",
                                 "e.g. \"10m\"; \"off\": what changes while the broker is away is lost");
    if (!kept) return kept.error();
    return *kept;
}

std::optional<SparkplugConfig> parse_sparkplug(const Context& ctx, const toml::table& root, const std::string& gateway_name) {
    const toml::node* node = root.get("sparkplug");
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "sparkplug", "expected a [sparkplug] table"));
        return std::nullopt;
    }
    check_keys(ctx, *table, "sparkplug", "sparkplug");
    SparkplugConfig config;
    parse_broker(ctx, *table, "sparkplug", config);
    auto group = ctx.kept(sparkplug_id(ctx, *table, "group_id", "\"plant1\""));
    if (group && !*group) ctx.note(ctx.fail(table->source(), "sparkplug", "missing `group_id` (e.g. group_id = \"plant1\")"));
    if (group && *group) config.group_id = std::move(**group);
    auto edge = ctx.kept(sparkplug_id(ctx, *table, "edge_node_id", "\"cabinet1\""));
    config.edge_node_id = edge && *edge ? **edge : gateway_name.empty() ? "loopwire" : gateway_name;
    auto host = ctx.kept(sparkplug_id(ctx, *table, "primary_host", "\"scada\""));
    if (host && *host) config.primary_host = **host;
    auto writes = ctx.kept(optional_value<bool>(ctx, *table, "sparkplug", "writes", "true or false"));
    if (writes && *writes) config.writes = **writes;
    auto client_id =
        ctx.kept(optional_value<std::string>(ctx, *table, "sparkplug", "client_id", "a string such as \"cabinet1-sparkplug\""));
    if (client_id && *client_id && ((*client_id)->empty() || (*client_id)->size() > 256)) {
        ctx.note(ctx.fail(source_of(*table, "client_id"), "sparkplug.client_id", "expected 1..256 characters"));
    } else if (client_id && *client_id) {
        config.client_id = **client_id;
    } else {
        config.client_id = fmt::format("loopwire-sparkplug-{}-{}", config.group_id, config.edge_node_id);
    }
    if (auto state_file = ctx.kept(sparkplug_state_file(ctx, *table))) config.state_file = std::move(*state_file);
    if (auto store = ctx.kept(sparkplug_store_and_forward(ctx, *table))) config.store_and_forward = *store;
    return config;
}

// ---------------------------------------------------------------------------------------------
// [history]

// `keep = "90d"`: how long rows are kept. Less than a minute would delete what the charts of
// the last minutes show.
Result<std::chrono::seconds> history_keep(const Context& ctx, const toml::table& table) {
    auto text = optional_value<std::string>(ctx, table, "history", "keep", "a period string such as \"90d\" or \"12h\"");
    if (!text) return text.error();
    if (!*text) return HistoryConfig{}.keep;
    auto keep = parse_period(**text, "");
    if (!keep) return ctx.fail(source_of(table, "keep"), "history.keep", without_option_name(keep.error().message));
    if (*keep < std::chrono::minutes(1)) {
        return ctx.fail(source_of(table, "keep"), "history.keep", fmt::format("{} is too short: keep at least 1m (e.g. \"90d\")", quoted_excerpt(**text)));
    }
    return *keep;
}

// `heartbeat = "60s"`: every value is written at least this often, so a value that holds
// still draws a line, not a gap.
Result<std::chrono::milliseconds> history_heartbeat(const Context& ctx, const toml::table& table) {
    auto heartbeat = bounded_duration(ctx, table, "history", "history", "heartbeat",
                                      "closer together it would write rows nobody needs; e.g. \"60s\"");
    if (!heartbeat) return heartbeat.error();
    if (!*heartbeat) return HistoryConfig{}.heartbeat;
    return **heartbeat;
}

Result<std::string> forward_target(const Context& ctx, const toml::table& table) {
    auto target = optional_value<std::string>(ctx, table, "history", "forward_to",
                                              "a PostgreSQL connection string such as \"postgresql://gateway@historian/plant\"");
    if (!target) return target.error();
    if (!*target) return std::string();
    if (!postgres::is_conninfo(**target)) {
        return ctx.fail(source_of(table, "forward_to"), "history.forward_to",
                        fmt::format("{} is not a PostgreSQL connection string (expected \"postgresql://USER@HOST:PORT/DATABASE\" "
                                    "or \"host=... dbname=...\")", quoted_excerpt(**target)));
    }
    if (auto valid = postgres::check_conninfo(**target); !valid) {
        return ctx.fail(source_of(table, "forward_to"), "history.forward_to", valid.error().message);
    }
    return std::move(**target);
}

// `forward_to` and its `password_file`: the connection string is checked as libpq reads it
// (without connecting: that is `--check`'s and the forwarder's), the password read now as
// [mqtt]'s is, so that a reload sees a changed one.
void history_forwarding(const Context& ctx, const toml::table& table, HistoryConfig& config) {
    if (auto target = ctx.kept(forward_target(ctx, table))) config.forward_to = std::move(*target);
    auto password = ctx.kept(read_password(ctx, table, "history", "PostgreSQL"));
    if (!password) return;
    if (!password->empty() && !table.contains("forward_to")) {
        ctx.note(ctx.fail(source_of(table, "password_file"), "history.password_file", "only used with `forward_to`"));
    }
    config.password = std::move(*password);
}

// `database`: the SQLite file, resolved against the configuration's folder.
Result<void> history_database(const Context& ctx, const toml::table& table, HistoryConfig& config) {
    auto database = required_string(ctx, table, "history", "database", "\"plant.db\"");
    if (!database) return database.error();
    if (database->empty()) {
        return ctx.fail(source_of(table, "database"), "history.database",
                        "expected the database file's path, e.g. \"plant.db\" (relative to this file's folder)");
    }
    // The historian's string where the local file goes: the SQLite file stays, as the buffer.
    const bool historian = database->rfind("postgresql:", 0) == 0 || database->rfind("postgres:", 0) == 0 ||
                           database->find("host=") != std::string::npos;
    if (historian) {
        return ctx.fail(source_of(table, "database"), "history.database",
                        fmt::format("\"{}\" is a PostgreSQL connection string; database is the gateway's own SQLite "
                                    "file, which buffers what is forwarded: write database = \"plant.db\" and "
                                    "forward_to = \"{}\"",
                                    *database, *database));
    }
    config.database_as_written = *database;
    config.written_at = fmt::format("{}:{}", ctx.source, source_of(table, "database").begin.line);
    const std::filesystem::path path(*database);
    config.database = path.is_absolute() ? path : std::filesystem::path(ctx.source).parent_path() / path;
    // Created when absent; when present it must be a regular file, told before SQLite opens it.
    if (auto what = not_a_regular_file(config.database); what && *what != "does not exist") {
        return not_regular(ctx, source_of(table, "database"), "history.database",
                           fmt::format("\"{}\" {}", config.database.string(), *what),
                           "the SQLite database file, created when absent");
    }
    return {};
}

std::optional<HistoryConfig> parse_history(const Context& ctx, const toml::table& root) {
    const toml::node* node = root.get("history");
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "history", "expected a [history] table"));
        return std::nullopt;
    }
    check_keys(ctx, *table, "history", "history");
    HistoryConfig config;
    ctx.kept(history_database(ctx, *table, config));
    if (auto keep = ctx.kept(history_keep(ctx, *table))) config.keep = *keep;
    if (auto heartbeat = ctx.kept(history_heartbeat(ctx, *table))) config.heartbeat = *heartbeat;
    history_forwarding(ctx, *table, config);
    return config;
}

// ---------------------------------------------------------------------------------------------
// [http]

// The token's file: a regular file, not readable by every user (the token guards the writes),
// whose first line is the token.
Result<std::string> read_token(const Context& ctx, const toml::table& table, const std::string& file) {
    const auto& where = source_of(table, "token_file");
    struct stat status {};
    if (::stat(file.c_str(), &status) != 0) {
        return ctx.fail(where, "http.token_file",
                        fmt::format("cannot read \"{}\": {} (create it with one line, the token, readable by the gateway "
                                    "alone: e.g. `head -c 24 /dev/urandom | base64 > {} && chmod 600 {}`)",
                                    file, std::error_code(errno, std::generic_category()).message(), file, file));
    }
    constexpr std::string_view expected = "a file whose first line is the token";
    if (auto what = not_a_regular_file(file)) {
        return not_regular(ctx, where, "http.token_file", fmt::format("\"{}\" {}", file, *what), expected);
    }
    if ((status.st_mode & S_IROTH) != 0) {
        return ctx.fail(where, "http.token_file",
                        fmt::format("\"{}\" is readable by every user (mode {:04o}); the token guards the writes: "
                                    "`chmod 600 {}`", file, status.st_mode & 07777, file));
    }
    auto text = read_regular_file(file, max_secret_file_size);
    if (!text) return not_regular(ctx, where, "http.token_file", text.error().message, expected);
    std::string token = first_line(*text);
    const auto first = token.find_first_not_of(" \t\r");
    const auto last = token.find_last_not_of(" \t\r");
    token = first == std::string::npos ? std::string() : token.substr(first, last - first + 1);
    if (token.empty()) {
        return ctx.fail(where, "http.token_file", fmt::format("\"{}\" is empty (expected one line, the token)", file));
    }
    if (token.size() < 8 || token.size() > 1024 ||
        std::any_of(token.begin(), token.end(), [](char c) { return c <= ' ' || c == 0x7f; })) {
        return ctx.fail(where, "http.token_file",
                        fmt::format("the token in \"{}\" must be 8..1024 printable characters without spaces", file));
    }
    return token;
}

// certificate and private_key: HTTPS, both or neither. Each a regular file the gateway can read,
// the key not readable by every user (it is the server's identity), and the pair one that loads
// (PEM, the key the certificate's).
Result<void> parse_http_tls(const Context& ctx, const toml::table& table, HttpConfig& config) {
    auto certificate = readable_file(ctx, table, "http", "certificate", "the server's certificate, PEM");
    if (!certificate) return certificate.error();
    auto key = readable_file(ctx, table, "http", "private_key", "the certificate's private key, PEM");
    if (!key) return key.error();
    if (certificate->empty() != key->empty()) {
        const auto* missing = certificate->empty() ? "certificate" : "private_key";
        return ctx.fail(table.source(), "http",
                        fmt::format("certificate and private_key go together (HTTPS needs both): `{}` is missing", missing));
    }
    if (certificate->empty()) return {};
    std::error_code error;
    const auto permissions = std::filesystem::status(*key, error).permissions();
    if (!error && (permissions & std::filesystem::perms::others_read) != std::filesystem::perms::none) {
        return ctx.fail(source_of(table, "private_key"), "http.private_key",
                        fmt::format("\"{}\" is readable by every user; the key is the server's identity: `chmod 600 {}`",
                                    key->string(), key->string()));
    }
    if (auto loaded = check_tls_files(certificate->string(), key->string()); !loaded) {
        // Which file is at fault: the key's when the certificate loaded.
        const bool key_at_fault = loaded.error().message.find("key") != std::string::npos;
        const char* name = key_at_fault ? "private_key" : "certificate";
        return ctx.fail(source_of(table, name), key_path("http", name), loaded.error().message);
    }
    config.certificate = certificate->string();
    config.private_key = key->string();
    return {};
}

// A name the Host header may give: a DNS name or IPv4 address ([A-Za-z0-9.-]), or an IPv6
// address in brackets, without a port (RFC 7230, 5.4: Host is uri-host [ ":" port ]).
bool host_name(std::string_view name) {
    if (name.empty() || name.size() > 255) return false;
    if (name.front() == '[') {
        return name.size() > 2 && name.back() == ']' && std::all_of(name.begin() + 1, name.end() - 1, [](char c) {
                   return std::isxdigit(static_cast<unsigned char>(c)) || c == ':' || c == '.';
               });
    }
    return std::all_of(name.begin(), name.end(),
                       [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-'; });
}

// `hosts = ["gateway.plant.local", "192.168.1.10"]`: the names, in lower case (Host names are
// compared without case, RFC 3986, 3.2.2). Each name is checked, whatever is wrong with another.
std::vector<std::string> http_hosts(const Context& ctx, const toml::table& table) {
    std::vector<std::string> hosts;
    const toml::node* node = table.get("hosts");
    if (!node) return hosts;
    const auto* array = node->as_array();
    constexpr std::string_view example = "[\"gateway.plant.local\", \"192.168.1.10\", \"[fd00::10]\"]";
    if (!array) {
        ctx.note(ctx.fail(node->source(), "http.hosts", fmt::format("expected a list of host names, e.g. {}", example)));
        return hosts;
    }
    for (std::size_t i = 0; i < array->size(); ++i) {
        const toml::node& element = *array->get(i);
        const auto* name = element.as_string();
        if (!name) {
            ctx.note(ctx.fail(element.source(), index_path("http.hosts", i),
                              fmt::format("expected a host name (a string), e.g. {}", example)));
            continue;
        }
        if (!host_name(name->get())) {
            ctx.note(ctx.fail(element.source(), index_path("http.hosts", i),
                              fmt::format("{} is not a host name (expected a name or address as a browser's address bar "
                                          "has it, without a port or scheme, e.g. {})", quoted_excerpt(name->get()), example)));
            continue;
        }
        std::string lower = name->get();
        std::transform(lower.begin(), lower.end(), lower.begin(),
                       [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
        hosts.push_back(std::move(lower));
    }
    return hosts;
}

// The share of `connections` event streams may hold (key `key`): half when not given, and
// always fewer, so that requests find a connection however many dashboards are open. With
// `connections` unknown (its own key is wrong) only the key's range is checked.
Result<unsigned> stream_share(const Context& ctx, const toml::table& table, std::string_view key, std::string_view of,
                              std::optional<unsigned> connections) {
    auto given = optional_integer(ctx, table, "http", "http", key);
    if (!given) return given.error();
    const unsigned limit = connections.value_or(std::numeric_limits<unsigned>::max());
    if (!*given) return limit / 2;
    if (**given >= limit) {
        return ctx.fail(source_of(table, key), fmt::format("http.{}", key),
                        fmt::format("{} event streams leave no connection of [http] {} ({}) for requests: make it "
                                    "at most {}",
                                    **given, of, limit, limit - 1));
    }
    return static_cast<unsigned>(**given);  // 1..10000, checked
}

// The limits that keep a few clients from taking every connection.
void parse_http_limits(const Context& ctx, const toml::table& table, HttpConfig& config) {
    auto read_timeout = ctx.kept(bounded_duration(ctx, table, "http", "http", "read_timeout", "e.g. \"10s\""));
    if (read_timeout && *read_timeout) config.read_timeout = **read_timeout;
    auto send_timeout = ctx.kept(bounded_duration(ctx, table, "http", "http", "send_timeout", "e.g. \"10s\""));
    if (send_timeout && *send_timeout) config.send_timeout = **send_timeout;
    auto header_timeout = ctx.kept(bounded_duration(ctx, table, "http", "http", "header_timeout", "e.g. \"5s\""));
    if (header_timeout && *header_timeout) config.header_timeout = **header_timeout;
    auto max_connections = ctx.kept(optional_integer(ctx, table, "http", "http", "max_connections"));
    if (max_connections && *max_connections) config.max_connections = static_cast<unsigned>(**max_connections);  // 1..10000, checked
    auto per_client = ctx.kept(optional_integer(ctx, table, "http", "http", "max_connections_per_client"));
    if (per_client && *per_client) config.max_connections_per_client = static_cast<unsigned>(**per_client);  // 1..10000, checked
    const auto known = [](const auto& parsed, unsigned value) { return parsed ? std::optional<unsigned>(value) : std::nullopt; };
    auto streams = ctx.kept(stream_share(ctx, table, "max_event_streams", "max_connections",
                                         known(max_connections, config.max_connections)));
    if (streams) config.max_event_streams = *streams;
    auto client_streams = ctx.kept(stream_share(ctx, table, "max_event_streams_per_client", "max_connections_per_client",
                                                known(per_client, config.max_connections_per_client)));
    if (client_streams) config.max_event_streams_per_client = *client_streams;
}

// `token_file`, resolved as [history] database is: a relative path is taken from the
// configuration file's folder. Empty when not given.
Result<void> http_token(const Context& ctx, const toml::table& table, HttpConfig& config) {
    auto token_file = optional_value<std::string>(ctx, table, "http", "token_file", "a string such as \"/etc/loopwire/token\"");
    if (!token_file) return token_file.error();
    if (!*token_file) return {};
    if ((*token_file)->empty()) return ctx.fail(source_of(table, "token_file"), "http.token_file", "expected a file name");
    const std::string file = beside_config(ctx, **token_file).string();
    auto token = read_token(ctx, table, file);
    if (!token) return token.error();
    config.token_file = file;
    config.token = std::move(*token);
    return {};
}

// `users_file`: a regular file, not readable by every user (its hashes are what a guesser
// would work on offline), of NAME:ROLE:HASH lines (gateway/http_users.hpp); its errors name
// the file and line. With users, `open_reads` and `session_timeout` apply.
Result<void> http_users(const Context& ctx, const toml::table& table, HttpConfig& config) {
    auto open_reads = ctx.kept(optional_value<std::string>(ctx, table, "http", "open_reads", "\"loopback\", \"none\" or \"all\""));
    if (open_reads && *open_reads) {
        const std::string& given = **open_reads;
        if (given == "loopback") {
            config.open_reads = HttpConfig::OpenReads::loopback;
        } else if (given == "none") {
            config.open_reads = HttpConfig::OpenReads::none;
        } else if (given == "all") {
            config.open_reads = HttpConfig::OpenReads::all;
        } else {
            ctx.note(ctx.fail(source_of(table, "open_reads"), "http.open_reads",
                              fmt::format("{} is not who reads without logging in (expected \"loopback\", \"none\" or "
                                          "\"all\")", quoted_excerpt(given))));
        }
    }
    auto timeout = ctx.kept(bounded_duration(ctx, table, "http", "http", "session_timeout", "e.g. \"8h\""));
    if (timeout && *timeout) config.session_timeout = **timeout;
    auto users_file = optional_value<std::string>(ctx, table, "http", "users_file", "a string such as \"/etc/loopwire/users\"");
    if (!users_file) return users_file.error();
    if (!*users_file) return {};  // open_reads has no effect without users: it is left alone
    const auto where = source_of(table, "users_file");
    if ((*users_file)->empty()) return ctx.fail(where, "http.users_file", "expected a file name");
    const std::string file = beside_config(ctx, **users_file).string();
    constexpr std::string_view expected = "a file of NAME:ROLE:HASH lines (`loopwire passwd FILE NAME --role ROLE` writes them)";
    struct stat status {};
    if (::stat(file.c_str(), &status) != 0) {
        return ctx.fail(where, "http.users_file",
                        fmt::format("cannot read \"{}\": {} (create it with `loopwire passwd {} NAME --role admin`)", file,
                                    std::error_code(errno, std::generic_category()).message(), file));
    }
    if (auto what = not_a_regular_file(file)) {
        return not_regular(ctx, where, "http.users_file", fmt::format("\"{}\" {}", file, *what), expected);
    }
    if ((status.st_mode & S_IROTH) != 0) {
        return ctx.fail(where, "http.users_file",
                        fmt::format("\"{}\" is readable by every user (mode {:04o}); its hashes guard the API: "
                                    "`chmod 600 {}`", file, status.st_mode & 07777, file));
    }
    auto text = read_regular_file(file, 1024 * 1024);
    if (!text) return not_regular(ctx, where, "http.users_file", text.error().message, expected);
    auto users = parse_users(*text, file);
    if (!users) return ctx.fail(where, "http.users_file", users.error().message);
    if (users->empty()) {
        return ctx.fail(where, "http.users_file",
                        fmt::format("\"{}\" has no user (add one with `loopwire passwd {} NAME --role admin`)", file, file));
    }
    config.users_file = file;
    config.users = std::move(*users);
    return {};
}

// `listen`: false when it is wrong (and said so).
bool http_listen(const Context& ctx, const toml::table& table, HttpConfig& config) {
    auto listen = ctx.kept(optional_value<std::string>(ctx, table, "http", "listen", "a string such as \"127.0.0.1:8080\""));
    if (!listen) return false;
    if (!*listen) return true;
    auto address = split_listen(**listen);
    if (!address) {
        ctx.note(ctx.fail(source_of(table, "listen"), "http.listen",
                          fmt::format("{} is not an address to listen on (expected HOST:PORT with a port 0..65535, "
                                      "0 for any free one, e.g. \"127.0.0.1:8080\" or \"[::1]:8080\")", quoted_excerpt(**listen))));
        return false;
    }
    config.host = std::move(address->host);
    config.port = address->port;
    return true;
}

std::optional<HttpConfig> parse_http(const Context& ctx, const toml::table& root) {
    const toml::node* node = root.get("http");
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "http", "expected an [http] table"));
        return std::nullopt;
    }
    check_keys(ctx, *table, "http", "http");
    HttpConfig config;
    const bool listen_known = http_listen(ctx, *table, config);
    const bool token_known = ctx.kept(http_token(ctx, *table, config));
    const bool users_known = ctx.kept(http_users(ctx, *table, config));
    parse_http_limits(ctx, *table, config);
    ctx.kept(parse_http_tls(ctx, *table, config));
    config.hosts = http_hosts(ctx, *table);
    config.allow = address_list(ctx, *table, "http", "allow");
    if (listen_known && token_known && users_known && !config.loopback() && config.token.empty() && config.users.empty()) {
        ctx.note(ctx.fail(source_of(*table, "listen"), "http.listen",
                          fmt::format("\"{}\" is not a loopback address, so every request needs the token: set "
                                      "http.token_file or http.users_file too (or listen on 127.0.0.1)", config.host)));
    }
    return config;
}

// [opcua] listen: opc.tcp://HOST:PORT (IPv6 in brackets); false when it is wrong (and said so).
bool opcua_listen(const Context& ctx, const toml::table& table, OpcuaConfig& config) {
    auto listen = ctx.kept(optional_value<std::string>(ctx, table, "opcua", "listen", "a string such as \"opc.tcp://127.0.0.1:4840\""));
    if (!listen) return false;
    if (!*listen) return true;
    constexpr std::string_view scheme = "opc.tcp://";
    const std::string_view text = **listen;
    auto address = text.starts_with(scheme) ? split_listen(text.substr(scheme.size())) : std::nullopt;
    if (!address) {
        ctx.note(ctx.fail(source_of(table, "listen"), "opcua.listen",
                          fmt::format("{} is not an OPC UA endpoint to listen on (expected opc.tcp://HOST:PORT with a port "
                                      "0..65535, 0 for any free one, e.g. \"opc.tcp://127.0.0.1:4840\")",
                                      quoted_excerpt(text))));
        return false;
    }
    config.listen = std::string(text);
    config.host = std::move(address->host);
    config.port = address->port;
    return true;
}

std::optional<OpcuaConfig> parse_opcua(const Context& ctx, const toml::table& root, const std::string& gateway_name) {
    const toml::node* node = root.get("opcua");
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "opcua", "expected an [opcua] table"));
        return std::nullopt;
    }
    check_keys(ctx, *table, "opcua", "opcua");
    OpcuaConfig config;
    opcua_listen(ctx, *table, config);
    for (auto [key, flag] : {std::pair{"writes", &config.writes}, std::pair{"anonymous", &config.anonymous}}) {
        auto value = ctx.kept(optional_value<bool>(ctx, *table, "opcua", key, "true or false"));
        if (value && *value) *flag = **value;
    }
    const std::string suffix = gateway_name.empty() ? std::string() : gateway_name;
    config.application_name = suffix.empty() ? "loopwire" : "loopwire " + suffix;
    config.application_uri = suffix.empty() ? "urn:loopwire" : "urn:loopwire:" + suffix;
    for (auto [key, text] : {std::pair{"application_name", &config.application_name},
                             std::pair{"application_uri", &config.application_uri}}) {
        auto value = ctx.kept(optional_value<std::string>(ctx, *table, "opcua", key, "a string"));
        if (!value || !*value) continue;
        if ((*value)->empty()) {
            ctx.note(ctx.fail(source_of(*table, key), key_path("opcua", key), "expected a non-empty string"));
            continue;
        }
        *text = std::move(**value);
    }
    for (auto [key, limit] : {std::pair{"max_sessions", &config.max_sessions},
                              std::pair{"max_subscriptions", &config.max_subscriptions},
                              std::pair{"max_monitored_items", &config.max_monitored_items}}) {
        auto value = ctx.kept(optional_integer(ctx, *table, "opcua", "opcua", key));
        if (value && *value) *limit = static_cast<unsigned>(**value);  // within the schema's range, checked
    }
    return config;
}

// [gateway]: the gateway's own name.
std::string parse_gateway_name(const Context& ctx, const toml::table& root) {
    const toml::node* node = root.get("gateway");
    if (!node) return std::string();
    const auto* table = node->as_table();
    if (!table) {
        ctx.note(ctx.fail(node->source(), "gateway", "expected a [gateway] table"));
        return std::string();
    }
    check_keys(ctx, *table, "gateway", "gateway");
    return ctx.kept(checked_name(ctx, *table, "gateway")).value_or("");
}

Result<toml::table> parse_toml(std::string_view text, const std::string& source) {
#if TOML_EXCEPTIONS
    try {
        return toml::parse(text, std::string_view(source));
    } catch (const toml::parse_error& error) {
        return make_error(ErrorKind::usage, fmt::format("{}:{}:{}: TOML syntax error: {}", source, error.source().begin.line,
                                                        error.source().begin.column, error.description()));
    }
#else
    toml::parse_result parsed = toml::parse(text, std::string_view(source));
    if (!parsed) {
        const auto& error = parsed.error();
        return make_error(ErrorKind::usage, fmt::format("{}:{}:{}: TOML syntax error: {}", source, error.source().begin.line,
                                                        error.source().begin.column, error.description()));
    }
    return std::move(parsed).table();
#endif
}

// The line a mistake is at: each message begins "SOURCE:LINE: " (Context::fail).
toml::source_index line_of(const std::string& source, const Error& mistake) {
    std::string_view after = std::string_view(mistake.message).substr(std::min(source.size() + 1, mistake.message.size()));
    after = after.substr(0, std::min(after.find_first_not_of("0123456789"), std::size_t{9}));
    return static_cast<toml::source_index>(parse_decimal_digits(after).value_or(0));
}

// One mistake is its own message. Several are one a line, in the file's order, then their count
// ("6 mistakes in plant.toml"): what `--check` prints, and why the gateway does not start.
Error all_mistakes(const std::string& source, std::vector<Error> mistakes) {
    if (mistakes.size() == 1) return std::move(mistakes.front());
    std::stable_sort(mistakes.begin(), mistakes.end(),
                     [&source](const Error& a, const Error& b) { return line_of(source, a) < line_of(source, b); });
    std::string message;
    for (const Error& mistake : mistakes) message += mistake.message + "\n";
    message += fmt::format("{} mistakes in {}", mistakes.size(), source);
    return make_error(ErrorKind::usage, std::move(message));
}

}  // namespace


bool HttpConfig::loopback() const {
    return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

bool is_virtual_bus(const transport::LinkUrl& link) { return link.is_serial() && link.path == "virtual"; }

bool reload_needs_restart(const GatewayConfig& running, const GatewayConfig& next) {
    GatewayConfig same_level = next;
    same_level.log.level = running.log.level;
    return !(same_level == running);
}

Result<GatewayConfig> parse_gateway_config(std::string_view text, const std::string& source,
                                           const device::ProfileRegistry& profiles) {
    // A file that is not TOML has no keys to check: its one mistake is all there is to say.
    auto root = parse_toml(text, source);
    if (!root) return root.error();
    std::vector<Error> mistakes;
    const Context ctx{source, profiles, mistakes};
    check_keys(ctx, *root, "", "");
    GatewayConfig config;
    config.source = source;
    Registry registry;
    config.lines = parse_lines(ctx, *root, registry);
    config.modbus_tcp = parse_modbus_tcp(ctx, *root);
    // Modbus TCP clients name devices by unit id alone: two devices on one id only matter when
    // the front serves them (a plant of more than 247 devices runs without it).
    if (config.modbus_tcp.enabled) check_tcp_units(ctx, registry.devices);
    config.log = parse_log(ctx, *root);
    config.name = parse_gateway_name(ctx, *root);
    config.mqtt = parse_mqtt(ctx, *root, config.name);
    config.sparkplug = parse_sparkplug(ctx, *root, config.name);
    config.history = parse_history(ctx, *root);
    // Many gateways share the historian: the name is what keeps their series apart. (A [gateway]
    // table without a valid name has that mistake said already.)
    if (config.history && !config.history->forward_to.empty() && !root->contains("gateway")) {
        ctx.note(ctx.fail(source_of(*root->get("history")->as_table(), "forward_to"), "history.forward_to",
                          "needs [gateway] name: it is part of every series in the shared historian"));
    }
    config.http = parse_http(ctx, *root);
    config.opcua = parse_opcua(ctx, *root, config.name);
    config.alarm_limits = alarms::parse_alarm_limits(*root, source, config.lines, mistakes);
    if (!mistakes.empty()) return all_mistakes(source, std::move(mistakes));
    if (config.mqtt && config.http) config.mqtt->configuration_url = dashboard_url(*config.http);
    return config;
}

Result<GatewayConfig> load_gateway_config(const std::filesystem::path& file, const device::ProfileRegistry& profiles) {
    const std::string source = file.string();
    // Examined before it is opened, and opened without blocking: a FIFO given here, at start or
    // at a reload on SIGHUP, must be an error, never a wait (common/regular_file.hpp).
    auto text = read_regular_file(file, max_file_size);
    if (!text) {
        return make_error(ErrorKind::usage, fmt::format("{}: cannot read the gateway configuration: {}; give the path of "
                                                        "the TOML file (a regular file of at most 1 MiB)",
                                                        source, text.error().message));
    }
    return parse_gateway_config(*text, source, profiles);
}


}  // namespace loopwire::gateway
