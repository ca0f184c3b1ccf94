#include "gateway/forward_batch.hpp"

#include <bit>
#include <cmath>
#include <iterator>
#include <vector>

#include <fmt/format.h>

#include "gateway/postgres_history_schema.hpp"

namespace loopwire::gateway {
namespace {

constexpr std::int64_t minute_ms = 60000;

// PostgreSQL's order of float8: NaN after every number, equal to itself.
bool before(double a, double b) {
    if (std::isnan(a)) return false;
    if (std::isnan(b)) return true;
    return a < b;
}

std::int64_t minute_of(std::int64_t t) { return t / minute_ms - ((t % minute_ms != 0 && t < 0) ? 1 : 0); }

// COPY's binary format: a signature, flags and the length of an extension area (none), then
// tuples of a field count and, per field, its length (-1: NULL) and bytes, all in network order;
// a count of -1 ends it.
constexpr std::string_view copy_signature{"PGCOPY\n\xff\r\n\0", 11};

template <typename Unsigned>
void put_big_endian(std::string& out, Unsigned value) {
    for (int shift = 8 * (static_cast<int>(sizeof(Unsigned)) - 1); shift >= 0; shift -= 8) {
        out += static_cast<char>((value >> shift) & 0xff);
    }
}

void put_length(std::string& out, std::int32_t length) { put_big_endian(out, static_cast<std::uint32_t>(length)); }

void put_int8(std::string& out, std::int64_t value) {
    put_length(out, 8);
    put_big_endian(out, static_cast<std::uint64_t>(value));
}

void put_text(std::string& out, const std::optional<std::string_view>& text) {
    if (!text) return put_length(out, -1);
    put_length(out, static_cast<std::int32_t>(text->size()));
    out += *text;
}

}  // namespace

void MinuteRollup::add(double value) {
    if (n == 0 || before(value, lo)) lo = value;
    if (n == 0 || before(hi, value)) hi = value;
    total = n == 0 ? value : total + value;
    ++n;
}

void append_float8(std::string& out, double value) {
    if (std::isnan(value)) {
        out += "NaN";
    } else if (std::isinf(value)) {
        out += value > 0 ? "Infinity" : "-Infinity";
    } else {
        fmt::format_to(std::back_inserter(out), "{}", value);
    }
}

ForwardBatch::ForwardBatch() {
    copy_ = copy_signature;
    put_big_endian(copy_, std::uint32_t{0});  // flags: no OIDs
    put_big_endian(copy_, std::uint32_t{0});  // no header extension
}

void ForwardBatch::add(std::int64_t series, std::int64_t t, std::optional<double> value, std::optional<std::string_view> text,
                       std::optional<std::string_view> status) {
    put_big_endian(copy_, std::uint16_t{5});
    put_int8(copy_, series);
    put_int8(copy_, t);
    if (value) {
        put_length(copy_, 8);
        put_big_endian(copy_, std::bit_cast<std::uint64_t>(*value));  // float8: IEEE 754, as the server's
        minutes_[{series, minute_of(t)}].add(*value);
    } else {
        put_length(copy_, -1);
    }
    put_text(copy_, text);
    put_text(copy_, status);
    days_.insert(postgres_history::day_of(t));
    ++rows_;
}

std::string ForwardBatch::copy_data() const {
    std::string data = copy_;
    put_big_endian(data, std::uint16_t{0xffff});  // the trailer: a field count of -1
    return data;
}

postgres::Parameters ForwardBatch::minute_columns() const {
    std::vector<std::optional<std::string>> series, minute, lo, hi, total, n;
    const auto number = [](double value) {
        std::string text;
        append_float8(text, value);
        return text;
    };
    for (const auto& [key, rollup] : minutes_) {
        series.emplace_back(std::to_string(key.first));
        minute.emplace_back(std::to_string(key.second));
        lo.emplace_back(number(rollup.lo));
        hi.emplace_back(number(rollup.hi));
        total.emplace_back(number(rollup.total));
        n.emplace_back(std::to_string(rollup.n));
    }
    return {postgres::array_literal(series), postgres::array_literal(minute), postgres::array_literal(lo),
            postgres::array_literal(hi),     postgres::array_literal(total),  postgres::array_literal(n)};
}

}  // namespace loopwire::gateway
