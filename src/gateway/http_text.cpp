#include "gateway/http_text.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/peer_text.hpp"
#include "common/text_parsing.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono;

std::optional<int> digits(std::string_view text, std::size_t at, std::size_t count) {
    if (at + count > text.size()) return std::nullopt;
    int value = 0;
    for (std::size_t i = at; i < at + count; ++i) {
        if (text[i] < '0' || text[i] > '9') return std::nullopt;
        value = value * 10 + (text[i] - '0');
    }
    return value;
}

int hex_digit(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

// A CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180, 2).
std::string csv_field(const std::string& text) {
    if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
    std::string quoted = "\"";
    for (const char c : text) {
        if (c == '"') quoted += '"';
        quoted += c;
    }
    return quoted + "\"";
}

}  // namespace

std::string iso_time(system_clock::time_point time) {
    const auto ms = floor<milliseconds>(time);
    const auto day = floor<days>(ms);
    const year_month_day date{day};
    const hh_mm_ss clock{ms - day};
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", static_cast<int>(date.year()),
                       static_cast<unsigned>(date.month()), static_cast<unsigned>(date.day()), clock.hours().count(),
                       clock.minutes().count(), clock.seconds().count(), clock.subseconds().count());
}

std::optional<system_clock::time_point> parse_iso_time(std::string_view text) {
    const auto y = digits(text, 0, 4), mo = digits(text, 5, 2), d = digits(text, 8, 2);
    const auto h = digits(text, 11, 2), mi = digits(text, 14, 2), s = digits(text, 17, 2);
    if (!y || !mo || !d || !h || !mi || !s || text[4] != '-' || text[7] != '-' || text[13] != ':' || text[16] != ':') return std::nullopt;
    if (text[10] != 'T' && text[10] != 't' && text[10] != ' ') return std::nullopt;
    const year_month_day date{year{*y}, month{static_cast<unsigned>(*mo)}, day{static_cast<unsigned>(*d)}};
    if (!date.ok() || *h > 23 || *mi > 59 || *s > 60) return std::nullopt;
    // The clock counts nanoseconds in 64 bits: 1677 to 2262. Outside the years below a time
    // wrapped round (year 1 came back as 1754) instead of being refused.
    if (*y < earliest_year || *y > latest_year) return std::nullopt;
    std::size_t at = 19;
    nanoseconds fraction{0};
    if (at < text.size() && (text[at] == '.' || text[at] == ',')) {
        ++at;
        long long scale = 100000000;
        const std::size_t first = at;
        while (at < text.size() && text[at] >= '0' && text[at] <= '9') {
            fraction += nanoseconds((text[at] - '0') * scale);
            scale /= 10;
            ++at;
        }
        if (at == first) return std::nullopt;
    }
    minutes offset{0};
    if (at < text.size() && (text[at] == 'Z' || text[at] == 'z')) {
        ++at;
    } else if (at < text.size() && (text[at] == '+' || text[at] == '-')) {
        const auto oh = digits(text, at + 1, 2), om = digits(text, at + 4, 2);
        if (!oh || !om || text[at + 3] != ':' || *oh > 23 || *om > 59) return std::nullopt;
        offset = hours(*oh) + minutes(*om);
        if (text[at] == '-') offset = -offset;
        at += 6;
    } else {
        return std::nullopt;  // no zone
    }
    if (at != text.size()) return std::nullopt;
    const auto local = sys_days{date} + hours(*h) + minutes(*mi) + seconds(*s) + fraction;
    return time_point_cast<system_clock::duration>(local - offset);
}

std::string percent_encode(std::string_view text) {
    std::string out;
    for (const char c : text) {
        const auto byte = static_cast<unsigned char>(c);
        const bool plain = std::isalnum(byte) || c == '-' || c == '.' || c == '_' || c == ':' || c == ',';
        out += plain ? std::string(1, c) : fmt::format("%{:02X}", byte);
    }
    return out;
}

std::optional<std::string> percent_decode(std::string_view text, bool plus_is_space) {
    std::string out;
    out.reserve(text.size());
    for (std::size_t i = 0; i < text.size(); ++i) {
        if (text[i] == '%') {
            if (i + 2 >= text.size()) return std::nullopt;
            const int high = hex_digit(text[i + 1]), low = hex_digit(text[i + 2]);
            if (high < 0 || low < 0) return std::nullopt;
            out += static_cast<char>(high * 16 + low);
            i += 2;
        } else if (plus_is_space && text[i] == '+') {
            out += ' ';
        } else {
            out += text[i];
        }
    }
    return out;
}

std::map<std::string, std::string> parse_query(std::string_view query) {
    std::map<std::string, std::string> values;
    while (!query.empty()) {
        const auto amp = query.find('&');
        const std::string_view pair = query.substr(0, amp);
        query = amp == std::string_view::npos ? std::string_view() : query.substr(amp + 1);
        if (pair.empty()) continue;
        const auto equals = pair.find('=');
        auto name = percent_decode(pair.substr(0, equals), true);
        auto value = percent_decode(equals == std::string_view::npos ? std::string_view() : pair.substr(equals + 1), true);
        if (name && value) values[*name] = *value;
    }
    return values;
}

namespace {

// A time of the history query: ISO 8601 with its zone, "now", or "-PERIOD" before now ("-1h",
// "-30m", "-7d": parse_period's forms), as Grafana and the dashboard's range buttons say it.
std::optional<system_clock::time_point> query_time(std::string_view text, system_clock::time_point now) {
    if (text == "now") return now;
    if (text.starts_with('-')) {
        auto before = parse_period(text.substr(1), "time");
        // A century back at most: further, the clock's nanoseconds would wrap round.
        if (!before || *before > hours(24 * 365 * 100)) return std::nullopt;
        return now - *before;
    }
    return parse_iso_time(text);
}

}  // namespace

namespace {

// What a gateway's and a device's name take (gateway_config.cpp): the names the historian can hold.
bool is_name(std::string_view name) {
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
    });
}

}  // namespace

Result<ParsedHistoryQuery> history_query(std::string_view text, system_clock::time_point now) {
    const auto values = parse_query(text);
    for (const auto& [name, value] : values) {
        if (name != "device" && name != "parameters" && name != "from" && name != "to" && name != "points" && name != "format" &&
            name != "gateway") {
            return make_error(ErrorKind::usage, fmt::format("unknown query parameter \"{}\" (allowed: device, parameters, from, to, "
                                                            "points, format, gateway)", name));
        }
    }
    ParsedHistoryQuery parsed;
    auto device = values.find("device");
    if (device == values.end() || device->second.empty()) {
        return make_error(ErrorKind::usage, "missing device=NAME (e.g. /api/history?device=furnace&parameters=measured_value)");
    }
    parsed.query.device = device->second;
    if (auto gateway = values.find("gateway"); gateway != values.end()) {
        // Checked here, not by the historian: what it would say of bytes that are no text in
        // its encoding is its own words, and a name no gateway can have is the asker's mistake.
        if (!is_name(gateway->second)) {
            return make_error(ErrorKind::usage, fmt::format("gateway={} is not a gateway's name (letters, digits, '-' and '_' "
                                                            "only, as [gateway] name; GET /api/history/gateways lists them)",
                                                            quoted_excerpt(gateway->second)));
        }
        if (!is_name(parsed.query.device)) {
            return make_error(ErrorKind::usage, fmt::format("device={} is not a device's name (letters, digits, '-' and '_' "
                                                            "only, as a device's name in the configuration)",
                                                            quoted_excerpt(parsed.query.device)));
        }
        parsed.query.gateway = gateway->second;
    }
    if (auto list = values.find("parameters"); list != values.end()) {
        std::string_view rest = list->second;
        while (!rest.empty()) {
            const auto comma = rest.find(',');
            const std::string_view one = rest.substr(0, comma);
            // Each once: asked twice, a series would be answered twice.
            auto& asked = parsed.query.parameters;
            if (!one.empty() && std::find(asked.begin(), asked.end(), one) == asked.end()) asked.emplace_back(one);
            rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
        }
    }
    parsed.query.to = now;
    for (const char* name : {"from", "to"}) {
        auto it = values.find(name);
        if (it == values.end()) continue;
        auto time = query_time(it->second, now);
        if (!time) {
            return make_error(ErrorKind::usage, fmt::format("{}=\"{}\" is not a time: give it in ISO 8601 with its zone "
                                                            "(2026-12-02T08:00:00Z, 2026-12-02T09:00:00+01:00) between the "
                                                            "years {} and {}, as a time before now (-1h, -30m, -7d; at most a "
                                                            "century) or as now",
                                                            name, it->second, earliest_year, latest_year));
        }
        (std::string_view(name) == "from" ? parsed.query.from : parsed.query.to) = *time;
    }
    if (values.find("from") == values.end()) parsed.query.from = parsed.query.to - hours(1);
    if (parsed.query.from >= parsed.query.to) {
        return make_error(ErrorKind::usage, fmt::format("from ({}) must be before to ({})", iso_time(parsed.query.from),
                                                        iso_time(parsed.query.to)));
    }
    if (auto points = values.find("points"); points != values.end()) {
        const auto number = parse_decimal_digits(points->second);
        if (!number || *number < 1 || *number > 10000) {
            return make_error(ErrorKind::usage, fmt::format("points=\"{}\" must be a whole number 1..10000", points->second));
        }
        parsed.query.points = static_cast<std::size_t>(*number);
    }
    if (auto format = values.find("format"); format != values.end()) {
        if (format->second != "csv" && format->second != "json") {
            return make_error(ErrorKind::usage, fmt::format("format=\"{}\": expected json (the default) or csv", format->second));
        }
        parsed.csv = format->second == "csv";
    }
    return parsed;
}

void visit_in_time_order(const HistorySeries& series, const HistoryRowVisitor& visit) {
    if (series.before) visit.before(*series.before);
    auto gap = series.gaps.begin();
    for (const auto& bucket : series.buckets) {
        while (gap != series.gaps.end() && gap->start < bucket.start) visit.gap(*gap++);
        visit.bucket(bucket);
    }
    while (gap != series.gaps.end()) visit.gap(*gap++);
}

std::string history_csv(const std::vector<HistorySeries>& series) {
    std::string out = "parameter,unit,time,min,max,mean,count,kind,until\r\n";
    for (const auto& one : series) {
        const std::string name = csv_field(one.parameter) + "," + csv_field(one.unit);
        visit_in_time_order(one, {[&](const HistoryBefore& before) {
                                      out += fmt::format("{},{},{},{},{},,before,\r\n", name, iso_time(before.time), before.value,
                                                         before.value, before.value);
                                  },
                                  [&](const HistoryBucket& bucket) {
                                      out += fmt::format("{},{},{},{},{},{},bucket,\r\n", name, iso_time(bucket.start), bucket.min,
                                                         bucket.max, bucket.mean, bucket.count);
                                  },
                                  [&](const HistoryGap& gap) {
                                      out += fmt::format("{},{},,,,,gap,{}\r\n", name, iso_time(gap.start),
                                                         gap.end ? iso_time(*gap.end) : "");
                                  }});
    }
    return out;
}

Result<AuditQuery> audit_query(std::string_view text, system_clock::time_point now) {
    const auto values = parse_query(text);
    for (const auto& [name, value] : values) {
        if (name != "device" && name != "from" && name != "to" && name != "limit") {
            return make_error(ErrorKind::usage,
                              fmt::format("unknown query parameter \"{}\" (allowed: from, to, device, limit)", name));
        }
    }
    AuditQuery query;
    query.to = now;
    for (const char* name : {"from", "to"}) {
        auto it = values.find(name);
        if (it == values.end()) continue;
        auto time = query_time(it->second, now);
        if (!time) {
            return make_error(ErrorKind::usage, fmt::format("{}=\"{}\" is not a time: give it in ISO 8601 with its zone "
                                                            "(2026-12-02T08:00:00Z), as a time before now (-1h, -7d) or as now",
                                                            name, printable_excerpt(it->second)));
        }
        (std::string_view(name) == "from" ? query.from : query.to) = *time;
    }
    if (values.find("from") == values.end()) query.from = query.to - hours(24);
    if (query.from > query.to) {
        return make_error(ErrorKind::usage, fmt::format("from ({}) must not be after to ({})", iso_time(query.from),
                                                        iso_time(query.to)));
    }
    if (auto device = values.find("device"); device != values.end()) query.device = device->second;
    if (auto limit = values.find("limit"); limit != values.end()) {
        const auto number = parse_decimal_digits(limit->second);
        if (!number || *number < 1 || *number > max_audit_limit) {
            return make_error(ErrorKind::usage, fmt::format("limit=\"{}\" must be a whole number 1..{}",
                                                            printable_excerpt(limit->second), max_audit_limit));
        }
        query.limit = static_cast<std::size_t>(*number);
    }
    return query;
}

std::string audit_json(const std::vector<AuditRecord>& records) {
    auto list = nlohmann::ordered_json::array();
    for (const auto& record : records) {
        list.push_back({{"time", iso_time(record.time)}, {"front", record.origin.front}, {"peer", record.origin.peer},
                        {"user", record.origin.user}, {"device", record.device}, {"parameter", record.parameter},
                        {"old_value", record.old_value}, {"new_value", record.new_value}, {"outcome", record.outcome}});
    }
    // Bytes a peer sent that are no UTF-8 (a Modbus client's values never are text) as U+FFFD.
    return nlohmann::ordered_json{{"records", std::move(list)}}.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string audit_csv(const std::vector<AuditRecord>& records) {
    std::string out = "time,front,peer,user,device,parameter,old_value,new_value,outcome\r\n";
    for (const auto& record : records) {
        out += fmt::format("{},{},{},{},{},{},{},{},{}\r\n", iso_time(record.time), csv_field(record.origin.front),
                           csv_field(record.origin.peer), csv_field(record.origin.user), csv_field(record.device),
                           csv_field(record.parameter), csv_field(record.old_value), csv_field(record.new_value),
                           csv_field(record.outcome));
    }
    return out;
}

}  // namespace loopwire::gateway
