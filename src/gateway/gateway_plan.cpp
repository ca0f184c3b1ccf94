// `loopwire gateway --check`: what the configuration asks of each line, and how much of the
// line's wire time the polls will take.
#include "gateway/gateway_config.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <filesystem>
#include <optional>
#include <sstream>
#include <system_error>

#include <fmt/format.h>

#include "client/monitor_names.hpp"
#include "codec/rtu.hpp"
#include "gateway/history_schema.hpp"
#include "profile/request_planner.hpp"
#include "transport/serial_settings.hpp"

namespace loopwire::gateway {
namespace {

using std::chrono::microseconds;
using std::chrono::milliseconds;

std::string duration_text(milliseconds duration) {
    if (duration.count() % 60000 == 0) return fmt::format("{}m", duration.count() / 60000);
    if (duration.count() % 1000 == 0) return fmt::format("{}s", duration.count() / 1000);
    return fmt::format("{}ms", duration.count());
}


// The device client also reads the words that give a parameter its decimals and unit (DeviceClient::read),
// so they count in the requests a poll costs. The planner reads duplicates once.
std::vector<device::ReadBlock> poll_requests(const DeviceConfig& device, const std::vector<const device::Parameter*>& wanted) {
    const device::Profile& profile = *device.address.profile;
    std::vector<const device::Parameter*> words = wanted;
    for (const device::Parameter* parameter : wanted) {
        std::vector<std::string> sources;
        if (const auto* source = std::get_if<std::string>(&parameter->decimals)) sources.push_back(*source);
        for (const device::UnitRule& rule : parameter->unit_from) sources.push_back(rule.parameter);  // units too
        for (const std::string& source : sources) {
            const device::Parameter* dependency = profile.find(source);
            if (dependency && dependency->readable) words.push_back(dependency);
        }
    }
    return device::plan_reads(profile, words, device.address.address_offset);
}

// RTU frame sizes: unit + function + address + count + CRC for the request; unit + function +
// byte count + data + CRC for the reply.
constexpr unsigned rtu_read_request_bytes = 8;

unsigned rtu_reply_bytes(const device::ReadBlock& block) {
    const unsigned data = codec::is_bit_table(block.table) ? (block.count + 7u) / 8u : 2u * block.count;
    return 5 + data;
}

// ASCII sends each byte but the CRC as two hex characters, an LRC byte (two characters), and
// ':' plus CR LF around them.
unsigned ascii_characters(unsigned rtu_bytes) { return (rtu_bytes - 2 + 1) * 2 + 3; }

// Wire time of one request and its reply. RTU frames are each preceded by a 3.5-character
// silence; ASCII frames are delimited by characters, so only the characters count.
microseconds wire_time(const device::ReadBlock& block, const transport::LinkUrl& link) {
    const codec::CharacterTiming timing{link.serial.baud, link.serial.bits_per_character()};
    unsigned characters = rtu_read_request_bytes + rtu_reply_bytes(block);
    if (link.framing == transport::Framing::ascii) {
        characters = ascii_characters(rtu_read_request_bytes) + ascii_characters(rtu_reply_bytes(block));
        return timing.character_time() * characters;
    }
    return timing.character_time() * characters + 2 * timing.t3_5();
}

// Share of the line's time one device's polls take, in percent.
double device_load_percent(const DeviceConfig& device, const std::vector<device::ReadBlock>& requests,
                           const transport::LinkUrl& link) {
    microseconds per_poll{0};
    for (const device::ReadBlock& block : requests) per_poll += wire_time(block, link);
    const auto interval = std::chrono::duration_cast<microseconds>(device.poll);
    return 100.0 * static_cast<double>(per_poll.count()) / static_cast<double>(interval.count());
}

std::string plural(std::size_t count, std::string_view one, std::string_view many) {
    return fmt::format("{} {}", count, count == 1 ? one : many);
}

void describe_device(std::ostringstream& out, const DeviceConfig& device, const std::vector<device::ReadBlock>& requests,
                     std::size_t parameters) {
    out << fmt::format("  device {}: {}@{}, Modbus TCP unit {}, every {}: {}{} in {} per poll\n", device.name,
                       device.address.profile->id, device.address.unit, device.tcp_unit, duration_text(device.poll),
                       plural(parameters, "parameter", "parameters"), device.parameters.empty() ? " (default watch list)" : "",
                       plural(requests.size(), "request", "requests"));
}

void describe_load(std::ostringstream& out, const transport::LinkUrl& link, double load) {
    if (!link.is_serial()) {
        out << "  no wire-time estimate for TCP links\n";
        return;
    }
    if (link.framing == transport::Framing::linking) {
        out << "  no wire-time estimate for Linking links\n";
        return;
    }
    const bool ascii = link.framing == transport::Framing::ascii;
    out << fmt::format("  estimated line load: {:.1f} % of wire time{}\n", load, ascii ? " (approximate, ASCII framing)" : "");
    if (load > 100.0) {
        out << "  warning: over 100 %: polls will fall behind\n";
    } else if (load > 50.0) {
        // Clients and polls take turns on a line (line_scheduler.hpp): under clients reading
        // without pause the polls get half of it.
        out << "  warning: over 50 %: while Modbus TCP clients keep the line busy the polls get half of it and "
               "will fall behind\n";
    }
}

// A serial port that is not there now is a warning, not an error: the gateway starts with that
// line down and opens it once it appears (gateway/reopening_master.hpp), so an adapter plugged
// in after the gateway started, or a simulator started after it, is fine.
void warn_if_port_missing(std::ostringstream& out, const LineConfig& line) {
    if (line.simulation || !line.link.is_serial()) return;
    std::error_code error;
    if (std::filesystem::exists(line.link.path, error)) return;
    out << fmt::format("  warning: port {} does not exist now; the gateway will start with this line down and open it "
                       "when it appears (retrying after 1 s, then with back-off up to every 30 s)\n",
                       line.link.path);
}

void describe_line(std::ostringstream& out, const LineConfig& line) {
    out << fmt::format("line {}: {} (timeout {}, {})\n", line.name, line.link.to_string(), duration_text(line.timeout),
                       plural(line.retries, "retry", "retries"));
    warn_if_port_missing(out, line);
    if (line.simulation) {
        out << fmt::format("  simulated on a virtual bus inside the gateway: process time x{}, seed {}\n",
                           line.simulation->speed, line.simulation->seed);
    }
    if (line.devices.empty()) out << "  no devices\n";
    double load = 0;
    for (const DeviceConfig& device : line.devices) {
        const auto wanted = polled_parameters(device);
        const auto requests = poll_requests(device, wanted);
        describe_device(out, device, requests, wanted.size());
        load += device_load_percent(device, requests, line.link);
    }
    describe_load(out, line.link, load);
}

void describe_modbus_tcp(std::ostringstream& out, const ModbusTcpConfig& config) {
    if (!config.enabled) {
        out << "Modbus TCP: disabled\n";
        return;
    }
    // An IPv6 address is shown in brackets again, as it would be written in the file.
    const bool ipv6 = config.host.find(':') != std::string::npos;
    out << fmt::format("Modbus TCP: listening on {}{}{}:{}, writes {}\n", ipv6 ? "[" : "", config.host, ipv6 ? "]" : "",
                       config.port, config.writes ? "allowed" : "refused");
    if (config.max_age.count() > 0) {
        out << fmt::format(
            "  reads (function codes 1-4) answered from cache up to {} old; a write through a unit empties "
            "its cache\n",
            duration_text(config.max_age));
    }
    out << fmt::format("  at most {} client(s) at once (the idlest closed for a newcomer), idle ones closed {}\n",
                       config.max_connections,
                       config.idle_timeout.count() > 0 ? "after " + duration_text(config.idle_timeout) : "never");
}

void describe_mqtt(std::ostringstream& out, const std::optional<MqttConfig>& config) {
    if (!config) return;
    out << fmt::format("MQTT: {} under {}/, writes {}\n", config->broker, config->prefix,
                       config->writes ? "allowed" : "refused");
}

void describe_sparkplug(std::ostringstream& out, const std::optional<SparkplugConfig>& config, bool has_history) {
    if (!config) return;
    out << fmt::format("Sparkplug B: {} as edge node spBv1.0/{}/.../{}, {}DCMD writes {}\n", config->broker, config->group_id,
                       config->edge_node_id,
                       config->primary_host.empty() ? "" : fmt::format("births once host {} is online, ", config->primary_host),
                       config->writes ? "allowed" : "refused");
    if (config->store_and_forward) {
        out << fmt::format("  store and forward: data kept for {} while the node is dead, sent after its births as historical\n",
                           duration_text(*config->store_and_forward));
        // Kept in the history file, it survives a restart; without one, in memory only.
        out << (has_history
                    ? "  store and forward: kept in the history file too, so a restart forwards it\n"
                    : "  note: store and forward keeps its data in memory only (no [history]): a restart loses it\n");
    }
}

// Days, hours or minutes, whichever is whole ("90d", "36h").
std::string period_text(std::chrono::seconds period) {
    const auto s = period.count();
    if (s % 86400 == 0) return fmt::format("{}d", s / 86400);
    if (s % 3600 == 0) return fmt::format("{}h", s / 3600);
    if (s % 60 == 0) return fmt::format("{}m", s / 60);
    return fmt::format("{}s", s);
}

void describe_history(std::ostringstream& out, const std::optional<HistoryConfig>& config) {
    if (!config) return;
    out << fmt::format("history: {} (SQLite, WAL mode), every change and a heartbeat each {}, kept {}\n",
                       config->database.string(), duration_text(config->heartbeat), period_text(config->keep));
}

void describe_http(std::ostringstream& out, const std::optional<HttpConfig>& config) {
    if (!config) return;
    const bool ipv6 = config->host.find(':') != std::string::npos;
    if (!config->users.empty()) {
        // The users' rights (gateway/http_users.hpp): said once here, as --check prints the plan.
        out << fmt::format("HTTP API and dashboard: http://{}{}{}:{}/, {} users in {}, reads without a login {}\n",
                           ipv6 ? "[" : "", config->host, ipv6 ? "]" : "", config->port, config->users.size(), config->users_file,
                           config->open_reads == HttpConfig::OpenReads::all    ? "for everyone"
                           : config->open_reads == HttpConfig::OpenReads::none ? "for nobody"
                                                                               : "from loopback");
        return;
    }
    out << fmt::format("HTTP API and dashboard: http://{}{}{}:{}/, reads {}, writes {}\n", ipv6 ? "[" : "", config->host,
                       ipv6 ? "]" : "", config->port, config->loopback() ? "open on loopback" : "need the token",
                       config->token.empty() ? "refused (no http.token_file)"
                                             : fmt::format("need the token in {}", config->token_file));
}

void describe_opcua(std::ostringstream& out, const std::optional<OpcuaConfig>& config) {
    if (!config) return;
    out << fmt::format("OPC UA: {} ({}), {}, at most {} sessions, writes {}\n", config->listen, config->application_uri,
                       config->anonymous ? "anonymous" : "no anonymous", config->max_sessions,
                       config->writes ? "confirmed by the device" : "refused (Bad_NotWritable)");
}

// Said only with [[alarms.limits]]: every device's communication alarms need no word.
void describe_alarms(std::ostringstream& out, const GatewayConfig& config) {
    if (config.alarm_limits.empty()) return;
    out << fmt::format("alarms: {} limit alarm(s), and each device's silent, line_down and wrong_device; journal {}\n",
                       config.alarm_limits.size(), config.history ? "in the history file" : "none (no [history])");
}

}  // namespace

// What one poll asks for: the configured names, or the profile's default watch list.
std::vector<const device::Parameter*> polled_parameters(const DeviceConfig& device) {
    const device::Profile& profile = *device.address.profile;
    if (device.parameters.empty()) return device::default_watch_list(profile);
    auto resolved = device::resolve_parameters(profile, device.parameters);
    return resolved ? *resolved : std::vector<const device::Parameter*>{};  // checked when parsed
}

namespace {

// UNIX 98 pseudo-terminals (/dev/pts/N: majors 136..143, the kernel's devices.txt), which have
// no entry in sysfs.
bool pseudo_terminal(unsigned major_number) { return major_number >= 136 && major_number <= 143; }

// The kernel class of a character device as sysfs names it ("tty", "mem" for /dev/null and
// /dev/zero, "misc", ...); nothing when sysfs does not say (not mounted, or a pseudo-terminal).
std::optional<std::string> device_class(dev_t device) {
    std::error_code error;
    const auto link = std::filesystem::read_symlink(
        fmt::format("/sys/dev/char/{}:{}/subsystem", major(device), minor(device)), error);
    if (error) return std::nullopt;
    return link.filename().string();
}

// What a character device is when it is not a terminal: sysfs's class, or else whether it takes
// a terminal's ioctl (opened without waiting for a carrier, and not made the controlling tty).
// Nothing for a terminal, or when it cannot be told (the line's own open says then).
std::optional<std::string> not_a_terminal(const std::string& path, dev_t device) {
    if (pseudo_terminal(major(device))) return std::nullopt;
    if (const auto kind = device_class(device)) {
        if (*kind == "tty") return std::nullopt;
        return fmt::format("is a character device of the kernel's \"{}\" class (as /dev/null and /dev/zero are)", *kind);
    }
    const int fd = ::open(path.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return std::nullopt;
    const bool terminal = ::isatty(fd) == 1;
    ::close(fd);
    if (terminal) return std::nullopt;
    return "is a character device that is no terminal";
}

// What a serial line's port is when it is there but is no serial port, in words; nothing when it
// is a terminal (a serial adapter's tty, a pseudo-terminal), or not there now (a warning,
// describe_plan: the line starts down until it appears).
std::optional<std::string> not_a_port(const std::string& path) {
    std::error_code error;
    const auto type = std::filesystem::status(path, error).type();
    switch (type) {
        case std::filesystem::file_type::directory: return "is a directory";
        case std::filesystem::file_type::fifo: return "is a FIFO (named pipe)";
        case std::filesystem::file_type::regular: return "is a regular file";
        case std::filesystem::file_type::socket: return "is a socket";
        case std::filesystem::file_type::block: return "is a block device";
        case std::filesystem::file_type::character: {
            struct stat status {};
            if (::stat(path.c_str(), &status) != 0) return std::nullopt;
            return not_a_terminal(path, status.st_rdev);
        }
        default: return std::nullopt;
    }
}

// A serial line whose port exists but is not one (a directory, a FIFO, a file) would stay down
// for ever with the line's log saying why only at info level: refused at --check and start.
Result<void> check_ports(const GatewayConfig& config) {
    for (const LineConfig& line : config.lines) {
        if (line.simulation || !line.link.is_serial()) continue;
        if (auto what = not_a_port(line.link.path)) {
            return make_error(ErrorKind::usage, fmt::format("{}: line {}: {} {}, not a serial port: name the adapter's device "
                                                            "(e.g. /dev/ttyUSB0, or /dev/serial/by-id/...)",
                                                            line.link_written_at.empty() ? config.source : line.link_written_at,
                                                            line.name, line.link.path, *what));
        }
        // rs485 = true on a port that has no kernel RS-485 control would fail at its first open.
        if (line.link.serial.rs485 != transport::Rs485::on) continue;
        if (auto refusal = transport::detail::rs485_unsupported(line.link.path)) {
            return make_error(ErrorKind::usage,
                              fmt::format("{}: line {}: rs485 = true, but the driver of {} {}: use an adapter that switches "
                                          "direction by itself and drop rs485, or set rs485 = \"auto\" to run without it",
                                          line.link_written_at.empty() ? config.source : line.link_written_at, line.name,
                                          line.link.path, *refusal));
        }
    }
    return {};
}

}  // namespace

Result<void> check_environment(const GatewayConfig& config) {
    if (auto ports = check_ports(config); !ports) return ports.error();
    if (!config.history) return {};
    // "plant.db" beside a configuration named without a folder is in the current folder.
    auto folder = config.history->database.parent_path();
    if (folder.empty()) folder = ".";
    const auto fail = [&](const std::string& what) {
        return make_error(ErrorKind::usage, fmt::format("{}: history.database: {}", config.history->written_at, what));
    };
    std::error_code error;
    if (!std::filesystem::exists(folder, error)) {
        return fail(fmt::format("the folder {} does not exist; create it (mkdir -p {}) or name a file in another folder",
                                folder.string(), folder.string()));
    }
    if (!std::filesystem::is_directory(folder, error)) return fail(fmt::format("{} is not a folder", folder.string()));
    // The database and its WAL files are created beside it.
    if (::access(folder.c_str(), W_OK | X_OK) != 0) {
        return fail(fmt::format("the folder {} cannot be written by this user ({}); give it write access or name a file "
                                "in another folder", folder.string(), std::strerror(errno)));
    }
    // A file there already must be a history (a text file passed --check, then failed the start).
    if (auto examined = history::examine(config.history->database); !examined) return fail(examined.error().message);
    return {};
}

std::string describe_plan(const GatewayConfig& config) {
    std::ostringstream out;
    out << fmt::format("{}: {}\n", config.source, plural(config.lines.size(), "line", "lines"));
    for (const LineConfig& line : config.lines) describe_line(out, line);
    describe_modbus_tcp(out, config.modbus_tcp);
    describe_mqtt(out, config.mqtt);
    describe_sparkplug(out, config.sparkplug, config.history.has_value());
    describe_history(out, config.history);
    describe_http(out, config.http);
    describe_opcua(out, config.opcua);
    describe_alarms(out, config);
    return out.str();
}

}  // namespace loopwire::gateway
