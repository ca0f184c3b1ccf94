#include "transport/link_url.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <limits>
#include <optional>
#include <vector>

#include <fmt/format.h>

#include "common/text_parsing.hpp"
#include "transport/serial_settings.hpp"

namespace loopwire::transport {

namespace {

struct Scheme {
    std::string_view name;
    Framing framing;
};

constexpr std::array<Scheme, 5> schemes{{
    {"rtu", Framing::rtu},
    {"ascii", Framing::ascii},
    {"linking", Framing::linking},
    {"tcp", Framing::tcp},
    {"rtu+tcp", Framing::rtu_over_tcp},
}};

constexpr std::string_view scheme_list = "rtu, ascii, linking, tcp, rtu+tcp";
constexpr std::string_view option_list = "baud, parity, data, stop, rs485, rs485_delay_before, rs485_delay_after, guard";
// Names, IPv4 and (inside brackets) IPv6 addresses with an optional %zone.
constexpr std::string_view host_characters =
    "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-._:%";
constexpr std::uint16_t default_tcp_port = 502;  // Modbus/TCP's registered port

std::optional<Framing> framing_of(std::string_view name) {
    for (const auto& scheme : schemes) {
        if (scheme.name == name) return scheme.framing;
    }
    return std::nullopt;
}

// Whole-string unsigned decimal (the project's one number parser) that fits T; nullopt for
// empty text, signs, spaces, hex or overflow.
template <typename T>
std::optional<T> parse_number(std::string_view text) {
    const auto value = parse_decimal_digits(text);
    if (!value || *value > std::numeric_limits<T>::max()) return std::nullopt;
    return static_cast<T>(*value);
}

std::string lower(std::string_view text) {
    std::string out(text);
    std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return out;
}

std::string_view parity_name(Parity parity) {
    switch (parity) {
        case Parity::none: return "none";
        case Parity::even: return "even";
        case Parity::odd: return "odd";
    }
    return "even";
}

std::optional<Parity> parity_of(std::string_view text) {
    const std::string name = lower(text);
    if (name == "none" || name == "n") return Parity::none;
    if (name == "even" || name == "e") return Parity::even;
    if (name == "odd" || name == "o") return Parity::odd;
    return std::nullopt;
}

// Builds errors that quote the whole URL, then say what part was wrong and what would be right.
class UrlParser {
public:
    explicit UrlParser(std::string_view text) : text_(text) {}

    Result<LinkUrl> parse();

private:
    Error fail(const std::string& what) const {
        return make_error(ErrorKind::usage, "link URL '" + std::string(text_) + "': " + what);
    }
    Result<LinkUrl> parse_serial(LinkUrl url, std::string_view rest) const;
    Result<LinkUrl> parse_network(LinkUrl url, std::string_view rest) const;
    Result<void> parse_options(SerialSettings& settings, std::string_view query) const;
    Result<void> apply_option(SerialSettings& settings, std::string_view name, std::string_view value) const;
    Result<void> parse_host_port(LinkUrl& url, std::string_view authority) const;
    Result<std::uint16_t> parse_port(std::string_view text) const;

    std::string_view text_;
};

Result<LinkUrl> UrlParser::parse() {
    if (text_.empty()) return fail("empty; write e.g. rtu:/dev/ttyUSB0 or tcp://127.0.0.1:502");
    const auto colon = text_.find(':');
    if (colon == std::string_view::npos) {
        return fail("missing scheme; start with one of " + std::string(scheme_list) +
                    " (e.g. rtu:/dev/ttyUSB0, tcp://127.0.0.1:502)");
    }
    const std::string_view scheme = text_.substr(0, colon);
    const auto framing = framing_of(scheme);
    if (!framing) {
        return fail("unknown scheme '" + std::string(scheme) + "' (valid: " + std::string(scheme_list) + ")");
    }
    LinkUrl url;
    url.framing = *framing;
    const std::string_view rest = text_.substr(colon + 1);
    return url.is_serial() ? parse_serial(std::move(url), rest) : parse_network(std::move(url), rest);
}

Result<LinkUrl> UrlParser::parse_serial(LinkUrl url, std::string_view rest) const {
    const std::string scheme = framing_name(url.framing);
    if (rest.starts_with("//")) {
        return fail("serial links take a path right after the colon, without '//' (e.g. " + scheme +
                    ":/dev/ttyUSB0)");
    }
    if (url.framing == Framing::linking) {
        // Only the ramp/soak controller speaks Linking; its factory line is 38400 baud, 8 data
        // bits, odd parity, 1 stop bit (its manual, chapter 1, BITS and BAUD defaults).
        url.serial.baud = 38400;
        url.serial.parity = Parity::odd;
    }
    const auto question = rest.find('?');
    url.path = std::string(rest.substr(0, question));
    if (url.path.empty()) {
        return fail("missing serial port path (e.g. " + scheme + ":/dev/ttyUSB0, or " + scheme +
                    ":virtual for an in-process virtual bus)");
    }
    if (question != std::string_view::npos) {
        if (auto ok = parse_options(url.serial, rest.substr(question + 1)); !ok) return ok.error();
    }
    return url;
}

Result<void> UrlParser::parse_options(SerialSettings& settings, std::string_view query) const {
    std::vector<std::string_view> seen;
    for (;;) {
        const auto amp = query.find('&');
        const std::string_view item = query.substr(0, amp);
        const auto equals = item.find('=');
        const std::string_view name = item.substr(0, equals);
        if (item.empty()) return fail("empty option (a stray '?' or '&'); options: " + std::string(option_list));
        if (equals == std::string_view::npos) {
            return fail("option '" + std::string(item) + "' has no value (write name=value; options: " +
                        std::string(option_list) + ")");
        }
        if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
            return fail("option '" + std::string(name) + "' is given twice");
        }
        seen.push_back(name);
        if (auto ok = apply_option(settings, name, item.substr(equals + 1)); !ok) return ok;
        if (amp == std::string_view::npos) return {};
        query.remove_prefix(amp + 1);
    }
}

Result<void> UrlParser::apply_option(SerialSettings& settings, std::string_view name, std::string_view value) const {
    const std::string shown(value);
    if (name == "baud") {
        const auto baud = parse_number<std::uint32_t>(value);
        const auto bauds = detail::supported_bauds();
        if (!baud || std::find(bauds.begin(), bauds.end(), *baud) == bauds.end()) {
            return fail("baud '" + shown + "' is not a supported rate (" + detail::supported_bauds_text() + ")");
        }
        settings.baud = *baud;
    } else if (name == "parity") {
        const auto parity = parity_of(value);
        if (!parity) return fail("parity '" + shown + "' is not valid (none, even, odd, or n, e, o)");
        settings.parity = *parity;
    } else if (name == "data") {
        const auto bits = parse_number<unsigned>(value);
        if (!bits || (*bits != 7 && *bits != 8)) return fail("data bits '" + shown + "' is not valid (7 or 8)");
        settings.data_bits = *bits;
    } else if (name == "stop") {
        const auto bits = parse_number<unsigned>(value);
        if (!bits || (*bits != 1 && *bits != 2)) return fail("stop bits '" + shown + "' is not valid (1 or 2)");
        settings.stop_bits = *bits;
    } else if (name == "rs485") {
        auto rs485 = parse_rs485(value);
        if (!rs485) return fail(rs485.error().message);
        settings.rs485 = *rs485;
    } else if (name == "rs485_delay_before" || name == "rs485_delay_after") {
        auto delay = parse_rs485_delay(value, name);
        if (!delay) return fail(delay.error().message);
        (name == "rs485_delay_before" ? settings.rs485_delay_before : settings.rs485_delay_after) = *delay;
    } else if (name == "guard") {
        auto guard = parse_line_guard(value);
        if (!guard) return fail(guard.error().message);
        settings.guard = *guard;
    } else {
        return fail("unknown option '" + std::string(name) + "' (valid: " + std::string(option_list) + ")");
    }
    return {};
}

Result<LinkUrl> UrlParser::parse_network(LinkUrl url, std::string_view rest) const {
    const std::string scheme = framing_name(url.framing);
    if (!rest.starts_with("//")) {
        return fail(scheme + " links are written " + scheme + "://host[:port] (e.g. " + scheme + "://127.0.0.1:502)");
    }
    const std::string_view authority = rest.substr(2);
    if (authority.find_first_of("/?") != std::string_view::npos) {
        return fail(scheme + " links take no path or options; write " + scheme + "://host[:port]");
    }
    if (auto ok = parse_host_port(url, authority); !ok) return ok.error();
    return url;
}

Result<void> UrlParser::parse_host_port(LinkUrl& url, std::string_view authority) const {
    std::string_view host = authority;
    std::optional<std::string_view> port;
    if (authority.starts_with('[')) {
        const auto close = authority.find(']');
        if (close == std::string_view::npos) return fail("missing ']' after the IPv6 address");
        host = authority.substr(1, close - 1);
        const std::string_view after = authority.substr(close + 1);
        if (!after.empty() && !after.starts_with(':')) {
            return fail("unexpected '" + std::string(after) + "' after the IPv6 address (write [addr]:port)");
        }
        if (!after.empty()) port = after.substr(1);
    } else if (const auto colon = authority.find(':'); colon != std::string_view::npos) {
        if (authority.find(':', colon + 1) != std::string_view::npos) {
            return fail("IPv6 addresses go in brackets (e.g. tcp://[::1]:502)");
        }
        host = authority.substr(0, colon);
        port = authority.substr(colon + 1);
    }
    if (host.empty()) return fail("empty host (write host[:port], e.g. 127.0.0.1:502)");
    if (const auto bad = host.find_first_not_of(host_characters); bad != std::string_view::npos) {
        return fail("host '" + std::string(host) + "' contains '" + host[bad] +
                    "' (a host is a name, an IPv4 address or an IPv6 address in brackets)");
    }
    url.host = std::string(host);
    url.port = default_tcp_port;
    if (port) {
        auto number = parse_port(*port);
        if (!number) return number.error();
        url.port = *number;
    }
    return {};
}

Result<std::uint16_t> UrlParser::parse_port(std::string_view text) const {
    const auto port = parse_number<std::uint16_t>(text);
    if (!port) {
        return fail("bad port number '" + std::string(text) + "' (0..65535; leave it out for " +
                    std::to_string(default_tcp_port) + ")");
    }
    return *port;
}

}  // namespace

std::string framing_name(Framing framing) {
    for (const auto& scheme : schemes) {
        if (scheme.framing == framing) return std::string(scheme.name);
    }
    return "rtu";
}

std::string LinkUrl::to_string() const {
    const std::string scheme = framing_name(framing);
    if (!is_serial()) {
        const bool ipv6 = host.find(':') != std::string::npos;
        return scheme + "://" + (ipv6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
    }
    std::string text = scheme + ":" + path + "?baud=" + std::to_string(serial.baud) +
                       "&parity=" + std::string(parity_name(serial.parity)) +
                       "&data=" + std::to_string(serial.data_bits) + "&stop=" + std::to_string(serial.stop_bits);
    if (serial.rs485 != Rs485::off) text += "&rs485=" + rs485_text(serial.rs485);
    if (serial.rs485_delay_before.count() > 0) text += "&rs485_delay_before=" + std::to_string(serial.rs485_delay_before.count()) + "ms";
    if (serial.rs485_delay_after.count() > 0) text += "&rs485_delay_after=" + std::to_string(serial.rs485_delay_after.count()) + "ms";
    if (serial.guard != LineGuard{}) text += "&guard=" + line_guard_text(serial.guard);
    return text;
}

Result<Rs485> parse_rs485(std::string_view text) {
    const std::string name = lower(text);
    if (name == "1" || name == "true" || name == "on") return Rs485::on;
    if (name == "0" || name == "false" || name == "off") return Rs485::off;
    if (name == "auto") return Rs485::if_supported;
    return make_error(ErrorKind::usage, "rs485 '" + std::string(text) +
                                            "' is not valid (1 or true to enable, 0 or false to disable, auto to enable "
                                            "where the driver supports it)");
}

Result<milliseconds> parse_rs485_delay(std::string_view text, std::string_view option) {
    auto delay = parse_duration(text, option);
    if (!delay) return delay.error();
    if (delay->count() % 1000 != 0 || *delay > std::chrono::seconds(1)) {
        return make_error(ErrorKind::usage, std::string(option) + " '" + std::string(text) +
                                                "' is not valid: the driver takes whole milliseconds, 0ms to 1000ms");
    }
    return std::chrono::duration_cast<milliseconds>(*delay);
}

Result<LineGuard> parse_line_guard(std::string_view text) {
    const auto bad = [&] {
        return make_error(ErrorKind::usage, "guard '" + std::string(text) +
                                                "' is not valid: write characters at the line's speed (\"3.5c\", up to "
                                                "1000c, two decimals at most) or a time (\"5ms\", up to 1s)");
    };
    LineGuard guard;
    if (text.ends_with('c')) {
        const std::string_view number = text.substr(0, text.size() - 1);
        double characters = 0;
        const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), characters, std::chars_format::fixed);
        // Two decimals at most: a guard prints back as written (link URLs round-trip).
        const auto point = number.find('.');
        const bool few_decimals = point == std::string_view::npos || number.size() - point - 1 <= 2;
        if (number.empty() || !std::isdigit(static_cast<unsigned char>(number.front())) || ec != std::errc() ||
            end != number.data() + number.size() || characters > 1000 || !few_decimals) {
            return bad();
        }
        guard.characters = characters;
        return guard;
    }
    auto time = parse_duration(text, "guard");
    if (!time || *time > std::chrono::seconds(1)) return bad();
    guard.time = *time;
    return guard;
}

std::string rs485_text(Rs485 rs485) {
    switch (rs485) {
        case Rs485::off: return "0";
        case Rs485::on: return "1";
        case Rs485::if_supported: return "auto";
    }
    return "0";
}

std::string line_guard_text(LineGuard guard) {
    if (guard.characters > 0) return fmt::format("{:g}c", guard.characters);
    if (guard.time.count() % 1000 == 0) return fmt::format("{}ms", guard.time.count() / 1000);
    return fmt::format("{}us", guard.time.count());
}

Result<LinkUrl> parse_link_url(std::string_view text) { return UrlParser(text).parse(); }

}  // namespace loopwire::transport
