// Every entry of every profile, for many raw words (boundaries, specials, enum codes, bits):
// decode -> raw_of gives the raw back, and decode -> text -> encode_value gives it back for
// writable entries. Ranges are checked separately at their boundaries.
#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/values.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using ::testing::HasSubstr;
using testing::builtin;
using testing::profile_ids;

std::set<std::uint16_t> raws_to_try(const Parameter& parameter) {
    if (parameter.type == ValueType::boolean) return {0, 1};
    std::set<std::uint16_t> raws{0,     1,     2,     9,     10,    99,    100,   255,   256,   1000,  9999,
                                 10000, 12345, 30000, 32766, 32767, 32768, 32769, 40000, 65000, 65534, 65535};
    for (const SpecialValue& special : parameter.special) raws.insert(static_cast<std::uint16_t>(special.raw & 0xFFFF));
    for (const auto& [key, label] : parameter.enum_labels) raws.insert(static_cast<std::uint16_t>(key & 0xFFFF));
    std::uint16_t all_named = 0;
    for (const auto& [bit, name] : parameter.bit_names) {
        raws.insert(static_cast<std::uint16_t>(1u << bit));
        all_named = static_cast<std::uint16_t>(all_named | (1u << bit));
    }
    raws.insert(all_named);
    return raws;
}

// Every parameter that gives others their decimals, set to `decimals`.
RawValues decimals_known(const Profile& profile, int decimals) {
    RawValues known;
    for (const Parameter& parameter : profile.parameters) {
        if (const auto* source = std::get_if<std::string>(&parameter.decimals)) {
            known[*source] = static_cast<std::uint16_t>(decimals);
        }
    }
    return known;
}

std::uint16_t raw_from_label(const Result<std::uint16_t>& encoded) {
    EXPECT_TRUE(encoded.ok());
    return encoded.ok() ? *encoded : 0xDEAD;
}

void round_trip(const Profile& profile, const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    const std::string where = fmt::format("{} {} raw {}", profile.id, parameter.name, raw);
    const auto decoded = decode_value(parameter, raw, known);
    ASSERT_TRUE(decoded.ok()) << where << ": " << decoded.error().message;
    EXPECT_EQ(decoded->raw, raw) << where;
    const auto back = raw_of(parameter, *decoded, known);
    ASSERT_TRUE(back.ok()) << where << ": " << back.error().message;
    EXPECT_EQ(*back, raw) << where;

    const auto text = format_value(parameter, *decoded, known);
    ASSERT_TRUE(text.ok()) << where << ": " << text.error().message;
    if (!parameter.writable) return;
    Parameter unbounded = parameter;  // range checks are tested at the boundaries below
    unbounded.min.reset();
    unbounded.max.reset();
    const auto encoded = encode_value(unbounded, *text, known);
    if (decoded->status == "unknown-label") {
        // Unlisted codes are not written back; the same text can only be a label (the
        // rampsoak's hex-coded enums print codes such as "1000" for 1000H).
        const auto label = std::find_if(parameter.enum_labels.begin(), parameter.enum_labels.end(),
                                        [&](const auto& entry) { return entry.second == *text; });
        if (label == parameter.enum_labels.end()) {
            EXPECT_FALSE(encoded.ok()) << where << ": an unlisted enum code was written back as " << *text;
        } else {
            EXPECT_EQ(raw_from_label(encoded), static_cast<std::uint16_t>(label->first & 0xFFFF)) << where;
        }
        return;
    }
    ASSERT_TRUE(encoded.ok()) << where << " text \"" << *text << "\": " << encoded.error().message;
    EXPECT_EQ(*encoded, raw) << where << " text \"" << *text << "\"";
}

TEST(ValueRoundTrip, EveryEntryOfEveryProfile) {
    std::size_t checked = 0;
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        for (int decimals = 0; decimals <= 3; ++decimals) {
            const RawValues known = decimals_known(*profile, decimals);
            for (const Parameter& parameter : profile->parameters) {
                for (const std::uint16_t raw : raws_to_try(parameter)) {
                    round_trip(*profile, parameter, raw, known);
                    ++checked;
                }
            }
        }
    }
    EXPECT_GT(checked, 10000u);
}

TEST(ValueRoundTrip, BoolEntriesRefuseRawsAboveOne) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        for (const Parameter& parameter : profile->parameters) {
            if (parameter.type == ValueType::boolean) {
                EXPECT_FALSE(decode_value(parameter, 2, {}).ok()) << parameter.name;
            }
        }
    }
}

// Fixed ranges: the limits themselves are accepted, one step outside is refused naming the limit.
TEST(ValueRoundTrip, FixedRangeBoundaries) {
    std::size_t checked = 0;
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        // dP = 0: the TC10 and rampsoak print dP-dependent ranges in display counts, which
        // equal engineering units only then (profiles/notes/tc10.md, rampsoak.md).
        const RawValues known = decimals_known(*profile, 0);
        for (const Parameter& parameter : profile->parameters) {
            if (!parameter.writable || (parameter.type != ValueType::int16 && parameter.type != ValueType::uint16)) continue;
            // A bound set by another parameter would need that parameter's value too; those
            // are covered by the TC10/AC20 set point tests.
            const auto is_parameter = [](const std::optional<Bound>& bound) {
                return bound && std::holds_alternative<std::string>(*bound);
            };
            if (is_parameter(parameter.min) || is_parameter(parameter.max)) continue;
            const auto decimals = decimals_of(parameter, known);
            ASSERT_TRUE(decimals.ok());
            const double step = 1.0 / std::pow(10.0, *decimals);
            for (const bool upper : {false, true}) {
                const auto& bound = upper ? parameter.max : parameter.min;
                if (!bound || !std::holds_alternative<double>(*bound)) continue;
                const double limit = std::get<double>(*bound);
                const std::string at = fmt::format("{:.{}f}", limit, *decimals);
                const std::string beyond = fmt::format("{:.{}f}", upper ? limit + step : limit - step, *decimals);
                const auto accepted = encode_value(parameter, at, known);
                EXPECT_TRUE(accepted.ok()) << id << " " << parameter.name << " " << at << ": " << accepted.error().message;
                const auto refused = encode_value(parameter, beyond, known);
                ASSERT_FALSE(refused.ok()) << id << " " << parameter.name << " " << beyond;
                if (refused.error().message.find("does not fit") == std::string::npos) {
                    EXPECT_THAT(refused.error().message, HasSubstr(upper ? "above its upper limit" : "below its lower limit"));
                }
                ++checked;
            }
        }
    }
    EXPECT_GT(checked, 50u);
}

}  // namespace
}  // namespace loopwire::device
