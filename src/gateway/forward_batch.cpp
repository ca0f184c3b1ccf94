#include "gateway/forward_batch.hpp"

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

void ForwardBatch::add(std::int64_t series, std::int64_t t, std::optional<double> value, std::optional<std::string_view> text,
                       std::optional<std::string_view> status) {
    fmt::format_to(std::back_inserter(copy_), "{}\t{}\t", series, t);
    if (value) {
        append_float8(copy_, *value);
        minutes_[{series, minute_of(t)}].add(*value);
    } else {
        copy_ += "\\N";
    }
    copy_ += '\t';
    postgres::append_copy_field(copy_, text);
    copy_ += '\t';
    postgres::append_copy_field(copy_, status);
    copy_ += '\n';
    days_.insert(postgres_history::day_of(t));
    ++rows_;
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
