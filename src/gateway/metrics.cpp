#include "gateway/metrics.hpp"

#include <algorithm>
#include <functional>
#include <iterator>
#include <variant>

#include <fmt/format.h>

#include "client/device_status.hpp"
#include "client/monitor_state.hpp"
#include "profile/value_format.hpp"

namespace loopwire::gateway {
namespace {

// A label value with backslash, double quote and line feed escaped (exposition format, "Text
// format details").
std::string label(const std::string& text) {
    std::string out;
    for (const char c : text) {
        if (c == '\\') out += "\\\\";
        else if (c == '"') out += "\\\"";
        else if (c == '\n') out += "\\n";
        else out += c;
    }
    return out;
}

void family(std::string& out, const char* name, const char* type, const char* help) {
    out += fmt::format("# HELP loopwire_{} {}\n# TYPE loopwire_{} {}\n", name, help, name, type);
}

// [history] forward_to: what waits in the local outbox, and what the historian took.
void history_forwarding(std::string& out, const ForwardStats& forward) {
    family(out, "history_forward_waiting_rows", "gauge", "Rows recorded locally and not yet acknowledged by PostgreSQL.");
    out += fmt::format("loopwire_history_forward_waiting_rows {}\n", forward.waiting_rows);
    family(out, "history_forwarded_rows_total", "counter", "Rows PostgreSQL acknowledged since the gateway started.");
    out += fmt::format("loopwire_history_forwarded_rows_total {}\n", forward.forwarded_total);
    family(out, "history_forward_oldest_waiting_seconds", "gauge", "Age of the oldest row still waiting; 0 when none wait.");
    out += fmt::format("loopwire_history_forward_oldest_waiting_seconds {}\n", forward.oldest_waiting_seconds);
    family(out, "history_forward_errors_total", "counter", "Failed attempts to reach or write PostgreSQL (each retry counts).");
    out += fmt::format("loopwire_history_forward_errors_total {}\n", forward.errors_total);
}

template <typename Value>
void sample(std::string& out, const char* name, const std::string& labels, Value value) {
    out += fmt::format("loopwire_{}{{{}}} {}\n", name, labels, value);
}

double seconds(std::chrono::microseconds time) { return static_cast<double>(time.count()) / 1e6; }

// The statuses a device can have (client/device_status.hpp): each gets its sample, 1 for the
// current one, so that a query can select on status without the series coming and going. In
// the order the samples have always come in.
constexpr device::DeviceStatus device_statuses[] = {device::DeviceStatus::ok,       device::DeviceStatus::partial,
                                                    device::DeviceStatus::no_reply, device::DeviceStatus::line_down,
                                                    device::DeviceStatus::stale,    device::DeviceStatus::waiting,
                                                    device::DeviceStatus::wrong_device};
constexpr bool each_status_once() {
    for (const device::DeviceStatus status : device::all_device_statuses) {
        if (std::count(std::begin(device_statuses), std::end(device_statuses), status) != 1) return false;
    }
    return std::size(device_statuses) == std::size(device::all_device_statuses);
}
static_assert(each_status_once(), "every status has its sample, once");

// The Modbus TCP front's connections ([modbus_tcp] max_connections and idle_timeout at work).
void front_connections(std::string& out, const FrontReport& front) {
    const struct {
        const char* name;
        const char* help;
        std::uint64_t value;
    } counters[] = {
        {"modbus_tcp_connections_accepted_total", "Modbus TCP connections accepted.", front.accepted},
        {"modbus_tcp_connections_not_allowed_total",
         "Modbus TCP clients closed at accept: their address is outside [modbus_tcp] allow.", front.not_allowed},
        {"modbus_tcp_connections_evicted_total", "Idle Modbus TCP connections closed to admit a new client at max_connections.",
         front.evicted},
        {"modbus_tcp_connections_refused_total", "New Modbus TCP clients closed at once: every connection had a request in progress.",
         front.refused},
        {"modbus_tcp_connections_idle_closed_total", "Modbus TCP connections closed after idle_timeout.", front.idle_closed},
    };
    for (const auto& counter : counters) {
        family(out, counter.name, "counter", counter.help);
        out += fmt::format("loopwire_{} {}\n", counter.name, counter.value);
    }
    family(out, "modbus_tcp_connections_open", "gauge", "Modbus TCP connections open now.");
    out += fmt::format("loopwire_modbus_tcp_connections_open {}\n", front.open);
}

// [opcua]: the front's sessions and monitored items now, and its writes by outcome.
void opcua_figures(std::string& out, const OpcuaFigures& opcua) {
    family(out, "opcua_sessions", "gauge", "OPC UA sessions open now.");
    out += fmt::format("loopwire_opcua_sessions {}\n", opcua.sessions);
    family(out, "opcua_monitored_items", "gauge", "OPC UA monitored items over every subscription now.");
    out += fmt::format("loopwire_opcua_monitored_items {}\n", opcua.monitored_items);
    family(out, "opcua_writes_total", "counter",
           "OPC UA writes: confirmed by the device, or refused (checks, a silent device, the device's refusal, no answer).");
    out += fmt::format("loopwire_opcua_writes_total{{outcome=\"confirmed\"}} {}\n", opcua.writes_confirmed);
    out += fmt::format("loopwire_opcua_writes_total{{outcome=\"refused\"}} {}\n", opcua.writes_refused);
}

// Each configured device's cached state, in configured order; null when never polled.
std::vector<const CachedDevice*> cached_devices(const std::vector<MetricsDevice>& devices, const std::vector<CachedDevice>& values) {
    std::vector<const CachedDevice*> found;
    for (const auto& device : devices) {
        auto it = std::find_if(values.begin(), values.end(), [&](const CachedDevice& c) { return c.name == device.name; });
        found.push_back(it == values.end() ? nullptr : &*it);
    }
    return found;
}

// Polls that could not keep their rate, per line: the samples its devices missed, and how
// many of its devices are stale now.
void poll_shortfall(std::string& out, const std::vector<LineReport>& lines, const std::vector<MetricsDevice>& devices,
                    const std::vector<const CachedDevice*>& found) {
    family(out, "line_polls_missed_total", "counter",
           "Poll samples of the line's devices skipped because the sample before ran past its interval.");
    for (const auto& line : lines) {
        std::uint64_t missed = 0;
        for (std::size_t i = 0; i < devices.size(); ++i) {
            if (devices[i].line == line.name && found[i]) missed += found[i]->state.missed;
        }
        sample(out, "line_polls_missed_total", fmt::format("line=\"{}\"", label(line.name)), missed);
    }
    family(out, "line_devices_stale", "gauge", "Devices on the line whose poll is more than two intervals overdue now.");
    for (const auto& line : lines) {
        unsigned stale = 0;
        for (std::size_t i = 0; i < devices.size(); ++i) {
            if (devices[i].line == line.name && found[i] && found[i]->state.status == device::DeviceStatus::stale) {
                ++stale;
            }
        }
        sample(out, "line_devices_stale", fmt::format("line=\"{}\"", label(line.name)), stale);
    }
}

// Every polled value that is a number read in the latest poll (status ok): what a dashboard
// draws without a second path to the devices. A value that failed, went stale, is in a special
// state or is a label has no sample: absent, never its old number.
void process_values(std::string& out, const std::vector<MetricsDevice>& devices, const std::vector<const CachedDevice*>& found) {
    struct Shown {
        std::string labels;
        double value;
        double age;
    };
    std::vector<Shown> shown;
    for (std::size_t i = 0; i < devices.size(); ++i) {
        if (!found[i]) continue;
        for (const auto& value : found[i]->state.values) {
            // The view every front shows (client/resolved_value.hpp): its status, unit and age as
            // of the cache's view, on the clock the polls run on.
            const device::ResolvedValue resolved = resolved_view(*found[i], value);
            if (!resolved.number || resolved.status != "ok") continue;
            shown.push_back({fmt::format("device=\"{}\",parameter=\"{}\",unit=\"{}\"", label(devices[i].name),
                                         label(value.parameter->name), label(resolved.unit)),
                             *resolved.number, resolved.age.value_or(0.0)});
        }
    }
    family(out, "value", "gauge",
           "Each polled numeric value in engineering units, as the latest poll read it; absent when that poll did not "
           "read it or it went stale.");
    for (const auto& one : shown) sample(out, "value", one.labels, one.value);
    family(out, "value_age_seconds", "gauge", "Time since the value was read.");
    for (const auto& one : shown) sample(out, "value_age_seconds", one.labels, one.age);
}

// Each named bit of the polled bit fields (a TC10's alarm status word, an AC20's alarm contacts)
// as 1 or 0: what an alerting rule selects on (`loopwire_bit{bit="alarm_1"} == 1`).
void bit_values(std::string& out, const std::vector<MetricsDevice>& devices, const std::vector<const CachedDevice*>& found) {
    family(out, "bit", "gauge",
           "Each named bit of a polled bit field (alarms, states), 1 or 0, as the latest poll read it; absent when that "
           "poll did not read it or it went stale.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        if (!found[i]) continue;
        for (const auto& value : found[i]->state.values) {
            if (!value.last || device::value_status(found[i]->state, value) != "ok") continue;
            const auto* bits = std::get_if<std::map<std::string, bool>>(&value.last->value);
            if (!bits) continue;
            for (const auto& [bit, on] : *bits) {
                sample(out, "bit",
                       fmt::format("device=\"{}\",parameter=\"{}\",bit=\"{}\"", label(devices[i].name),
                                   label(value.parameter->name), label(bit)),
                       on ? 1 : 0);
            }
        }
    }
}

// Every sample labelled with the gateway's name, first, so that many gateways can be scraped
// into one Prometheus and told apart without relabelling. A gateway without a [gateway] name
// has none (an empty label is no label to Prometheus).
std::string with_gateway_label(const std::string& text, const std::string& gateway) {
    if (gateway.empty()) return text;
    const std::string first = fmt::format("gateway=\"{}\"", label(gateway));
    std::string out;
    out.reserve(text.size() + text.size() / 8);
    std::size_t start = 0;
    while (start < text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        const std::string_view line(text.data() + start, end - start);
        const std::size_t name_end = line.find_first_of("{ ");
        if (line.empty() || line.front() == '#' || name_end == std::string_view::npos) {
            out += line;
        } else if (line[name_end] == '{') {
            out += fmt::format("{}{{{},{}", line.substr(0, name_end), first, line.substr(name_end + 1));
        } else {
            out += fmt::format("{}{{{}}}{}", line.substr(0, name_end), first, line.substr(name_end));
        }
        out += '\n';
        start = end + 1;
    }
    return out;
}

}  // namespace

std::string prometheus_text(const std::string& gateway, const std::vector<LineReport>& lines,
                            const std::vector<MetricsDevice>& devices, const std::vector<CachedDevice>& values,
                            const HistorySource* history, const FrontReport* front, const HttpReport* http,
                            const OpcuaFigures* opcua) {
    std::string out;
    struct LineCounter {
        const char* name;
        const char* help;
        std::function<std::uint64_t(const LineReport&)> value;
    };
    const LineCounter counters[] = {
        {"line_requests_total", "Requests put on the line.", [](const LineReport& r) { return r.statistics.sent; }},
        {"line_polls_total", "Of those, the gateway's own polls.", [](const LineReport& r) { return r.statistics.polls_sent; }},
        {"line_answered_total", "Replies received, exception replies included.", [](const LineReport& r) { return r.statistics.answered; }},
        {"line_timeouts_total", "Requests that got no reply in time.", [](const LineReport& r) { return r.statistics.timeouts; }},
        {"line_bad_replies_total", "Malformed or mismatched replies.", [](const LineReport& r) { return r.statistics.bad_replies; }},
        {"line_garbled_total", "Runs of bytes the master discarded: bad CRC or LRC, broken frames, noise.",
         [](const LineReport& r) { return r.garbled; }},
        {"line_expired_total", "Requests dropped unsent because their deadline passed.", [](const LineReport& r) { return r.statistics.expired; }},
        {"line_backed_off_total", "Polls held back while their unit backed off after a poll timed out.",
         [](const LineReport& r) { return r.statistics.backed_off; }},
        {"line_down_total", "Times the line went down: its port hung up or failed, or could not be opened at start.",
         [](const LineReport& r) { return r.link_health.down_periods; }},
        {"line_reopen_attempts_total", "Tries to open the line again while it was down, failed or not.",
         [](const LineReport& r) { return r.link_health.reopen_attempts; }},
        {"line_refused_while_down_total", "Requests failed at once, never sent, because the line was down.",
         [](const LineReport& r) { return r.link_health.refused_while_down; }},
        {"line_abandoned_total", "Requests dropped unsent because their client had gone (a closed connection).",
         [](const LineReport& r) { return r.statistics.abandoned; }},
        {"line_refused_busy_total", "Requests refused with exception 06h (server device busy): the line's queue was full.",
         [](const LineReport& r) { return r.statistics.refused_busy; }},
    };
    for (const auto& counter : counters) {
        family(out, counter.name, "counter", counter.help);
        for (const auto& line : lines) sample(out, counter.name, fmt::format("line=\"{}\"", label(line.name)), counter.value(line));
    }
    family(out, "line_busy_seconds_total", "counter", "Time the line carried a request, from sending to its outcome.");
    for (const auto& line : lines) {
        sample(out, "line_busy_seconds_total", fmt::format("line=\"{}\"", label(line.name)), seconds(line.statistics.busy));
    }
    family(out, "line_open_seconds_total", "counter", "Time the line has been open.");
    for (const auto& line : lines) {
        sample(out, "line_open_seconds_total", fmt::format("line=\"{}\"", label(line.name)), seconds(line.statistics.open));
    }
    family(out, "line_busy_ratio", "gauge", "Share of the open time the line was busy, since the gateway started.");
    for (const auto& line : lines) {
        const auto open = line.statistics.open.count();
        const double ratio = open > 0 ? static_cast<double>(line.statistics.busy.count()) / static_cast<double>(open) : 0.0;
        sample(out, "line_busy_ratio", fmt::format("line=\"{}\"", label(line.name)), ratio);
    }
    family(out, "line_up", "gauge", "1 while the line's port is open, 0 while it is down and being reopened.");
    for (const auto& line : lines) sample(out, "line_up", fmt::format("line=\"{}\"", label(line.name)), line.link_health.up ? 1 : 0);
    family(out, "line_down_seconds_total", "counter", "Time the line has spent down.");
    for (const auto& line : lines) {
        sample(out, "line_down_seconds_total", fmt::format("line=\"{}\"", label(line.name)), seconds(line.link_health.down_time));
    }
    family(out, "line_queued", "gauge", "Requests waiting for the line now.");
    for (const auto& line : lines) sample(out, "line_queued", fmt::format("line=\"{}\"", label(line.name)), line.statistics.queued);

    const auto found = cached_devices(devices, values);
    poll_shortfall(out, lines, devices, found);

    family(out, "device_status", "gauge", "1 for the device's status now (ok, partial, no-reply, line-down, stale, waiting, wrong-device), 0 for the others.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        const device::DeviceStatus status = found[i] ? found[i]->state.status : device::DeviceStatus::waiting;
        for (const device::DeviceStatus candidate : device_statuses) {
            sample(out, "device_status",
                   fmt::format("device=\"{}\",status=\"{}\"", label(devices[i].name), device::status_text(candidate)),
                   status == candidate ? 1 : 0);
        }
    }
    family(out, "device_polls_total", "counter", "Polls of the device.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        sample(out, "device_polls_total", fmt::format("device=\"{}\"", label(devices[i].name)), found[i] ? found[i]->state.polls : 0u);
    }
    family(out, "device_poll_errors_total", "counter", "Polls of the device that failed.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        sample(out, "device_poll_errors_total", fmt::format("device=\"{}\"", label(devices[i].name)),
               found[i] ? found[i]->state.errors : 0u);
    }
    family(out, "device_polls_missed_total", "counter", "Poll samples skipped because the sample before ran past its interval.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        sample(out, "device_polls_missed_total", fmt::format("device=\"{}\"", label(devices[i].name)),
               found[i] ? found[i]->state.missed : 0u);
    }
    family(out, "device_poll_age_seconds", "gauge",
           "Time since the device's last poll that answered; absent before one and while its polls get no answer.");
    for (std::size_t i = 0; i < devices.size(); ++i) {
        if (!found[i] || !found[i]->since_answered) continue;
        sample(out, "device_poll_age_seconds", fmt::format("device=\"{}\"", label(devices[i].name)),
               static_cast<double>(found[i]->since_answered->count()) / 1e3);
    }
    process_values(out, devices, found);
    bit_values(out, devices, found);
    if (history) {
        family(out, "history_rows_written_total", "counter", "Rows the history store committed since the gateway started.");
        out += fmt::format("loopwire_history_rows_written_total {}\n", history->rows_written());
        if (const auto forward = history->forward_stats()) history_forwarding(out, *forward);
    }
    if (front) front_connections(out, *front);
    if (http) {
        family(out, "http_connections_not_allowed_total", "counter",
               "HTTP clients closed at accept: their address is outside [http] allow.");
        out += fmt::format("loopwire_http_connections_not_allowed_total {}\n", http->not_allowed);
    }
    if (opcua) opcua_figures(out, *opcua);
    return with_gateway_label(out, gateway);
}

}  // namespace loopwire::gateway
