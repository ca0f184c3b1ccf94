// The real profiles' content: names and mnemonics unique (or glitch-noted), and the structs of
// profile.hpp holding exactly what the JSON says.
#include <map>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;
using testing::profile_ids;
using testing::profile_path;
using testing::read_json;
using Json = nlohmann::json;

std::string lowered(std::string text) {
    for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return text;
}

TEST(ProfileContent, NamesAreUniqueEvenIgnoringCase) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        std::set<std::string> names;
        for (const Parameter& parameter : profile->parameters) {
            EXPECT_TRUE(names.insert(lowered(parameter.name)).second) << id << ": " << parameter.name;
        }
    }
}

// A mnemonic printed twice in one table is a manual glitch (TC10 'SSC' for two rows, 'rV' for
// the §5.1 and §5.2 copies of the measured value); the profile must say so in a note.
TEST(ProfileContent, MnemonicsAreUniquePerTableOrGlitchNoted) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        std::map<std::pair<Table, std::string>, std::vector<const Parameter*>> by_mnemonic;
        for (const Parameter& parameter : profile->parameters) {
            if (!parameter.mnemonic.empty()) by_mnemonic[{parameter.table, lowered(parameter.mnemonic)}].push_back(&parameter);
        }
        for (const auto& [key, entries] : by_mnemonic) {
            if (entries.size() < 2) continue;
            const bool noted = std::any_of(entries.begin(), entries.end(),
                                           [](const Parameter* parameter) { return !parameter->note.empty(); });
            EXPECT_TRUE(noted) << id << ": mnemonic " << key.second << " is used " << entries.size()
                               << " times in " << table_name(key.first) << " without a note";
        }
    }
}

TEST(ProfileContent, AddressesAreUniquePerTableOrGlitchNoted) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        std::map<std::pair<Table, int>, const Parameter*> seen;
        for (const Parameter& parameter : profile->parameters) {
            const auto [it, inserted] = seen.emplace(std::make_pair(parameter.table, int{parameter.address}), &parameter);
            if (!inserted) {
                EXPECT_FALSE(parameter.note.empty() || it->second->note.empty())
                    << id << ": " << parameter.name << " and " << it->second->name << " share an address";
            }
        }
    }
}

std::string access_of(const Parameter& parameter) {
    return std::string(parameter.readable ? "r" : "") + (parameter.writable ? "w" : "");
}

void expect_bound(const std::optional<Bound>& bound, const Json& range, const char* key, const std::string& where) {
    if (!range.contains(key)) {
        EXPECT_FALSE(bound.has_value()) << where;
        return;
    }
    ASSERT_TRUE(bound.has_value()) << where;
    if (range.at(key).is_object()) {
        EXPECT_EQ(std::get<std::string>(*bound), range.at(key).at("parameter")) << where;
    } else {
        EXPECT_DOUBLE_EQ(std::get<double>(*bound), range.at(key).get<double>()) << where;
    }
}

void expect_specials(const Parameter& parameter, const Json& entry, const Json& word_specials, const std::string& where) {
    Json expected = entry.value("special", Json::array());
    if (parameter.table == Table::holding_registers || parameter.table == Table::input_registers) {
        for (const Json& special : word_specials) expected.push_back(special);  // after its own
    }
    ASSERT_EQ(parameter.special.size(), expected.size()) << where;
    for (std::size_t k = 0; k < expected.size(); ++k) {
        EXPECT_EQ(parameter.special[k].raw, expected[k].at("raw").get<int>()) << where;
        EXPECT_EQ(parameter.special[k].state, expected[k].at("state")) << where;
    }
}

void expect_same(const Parameter& parameter, const Json& entry, const Json& word_specials) {
    const std::string where = parameter.name;
    EXPECT_EQ(parameter.name, entry.at("name")) << where;
    EXPECT_EQ(parameter.mnemonic, entry.value("mnemonic", "")) << where;
    EXPECT_EQ(table_name(parameter.table), entry.at("table")) << where;
    EXPECT_EQ(parameter.address, entry.at("address").get<int>()) << where;
    EXPECT_EQ(access_of(parameter), entry.at("access")) << where;
    const Json decimals = entry.value("decimals", Json(0));
    if (decimals.is_object()) {
        EXPECT_EQ(std::get<std::string>(parameter.decimals), decimals.at("parameter")) << where;
    } else {
        EXPECT_EQ(std::get<int>(parameter.decimals), decimals.get<int>()) << where;
    }
    EXPECT_EQ(parameter.enum_labels.size(), entry.value("enum", Json::object()).size()) << where;
    EXPECT_EQ(parameter.bit_names.size(), entry.value("bits", Json::object()).size()) << where;
    EXPECT_EQ(parameter.ram_only, entry.value("storage", "") == "ram") << where;
    EXPECT_EQ(parameter.hidden, entry.value("hidden", false)) << where;
    EXPECT_EQ(parameter.write_modes, entry.value("write_modes", std::vector<std::string>())) << where;
    const Json range = entry.value("range", Json::object());
    expect_bound(parameter.min, range, "min", where);
    expect_bound(parameter.max, range, "max", where);
    expect_specials(parameter, entry, word_specials, where);
}

TEST(ProfileContent, StructsHoldWhatTheJsonSays) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        const Json document = read_json(profile_path(id));
        const Json& entries = document.at("parameters");
        ASSERT_EQ(profile->parameters.size(), entries.size());
        for (std::size_t i = 0; i < entries.size(); ++i) {
            expect_same(profile->parameters[i], entries[i], document.value("word_specials", Json::array()));
        }
    }
}

TEST(ProfileContent, BoundSourcesDescribeEveryBoundingParameter) {
    std::size_t bounds = 0;
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        for (const Parameter& parameter : profile->parameters) {
            std::size_t named = 0;
            for (const auto& bound : {parameter.min, parameter.max}) {
                if (!bound || !std::holds_alternative<std::string>(*bound)) continue;
                ++named;
                const std::string& name = std::get<std::string>(*bound);
                ASSERT_TRUE(parameter.bound_sources.contains(name)) << id << " " << parameter.name;
                const Parameter& source = testing::parameter(*profile, name);
                const BoundSource& described = parameter.bound_sources.at(name);
                EXPECT_EQ(described.type, source.type);
                EXPECT_EQ(described.decimals, source.decimals);
                EXPECT_EQ(described.special.size(), source.special.size());
                EXPECT_EQ(described.unit, source.unit);
            }
            EXPECT_LE(parameter.bound_sources.size(), named) << parameter.name;
            bounds += named;
        }
    }
    EXPECT_GT(bounds, 20u);
}

TEST(ProfileContent, Ac20LineAddressingAndLimits) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_TRUE(ac20->unmapped_reads_answered);
    EXPECT_EQ(ac20->limits.read_registers, 20u);
    EXPECT_EQ(ac20->limits.read_bits, 24u);
    ASSERT_EQ(ac20->numberings.size(), 1u);
    EXPECT_EQ(ac20->numberings[0].name, "jbus");
    EXPECT_EQ(ac20->numberings[0].offset, 1);
    EXPECT_EQ(ac20->numberings[0].selected_by_parameter, "serial_interface_protocol");
    EXPECT_EQ(ac20->numberings[0].selected_by_value, 2);
    EXPECT_EQ(ac20->default_parity, "even");
    EXPECT_EQ(ac20->exception_names.at(10), "The bit or word indicated cannot be modified");
    ASSERT_EQ(ac20->identification.size(), 1u);
    EXPECT_EQ(ac20->identification[0].parameter, "manufacturer_trade_mark");
    EXPECT_EQ(ac20->identification[0].equals, 50);
}

TEST(ProfileContent, Ac20WordSpecialsFollowEachWordsOwnAndSkipBits) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    for (const Parameter& parameter : ac20->parameters) {
        if (parameter.table == Table::coils) {
            EXPECT_TRUE(parameter.special.empty()) << parameter.name;
            continue;
        }
        ASSERT_GE(parameter.special.size(), 2u) << parameter.name;
        const auto& last_two = std::vector<SpecialValue>(parameter.special.end() - 2, parameter.special.end());
        EXPECT_EQ(last_two[0].raw, 32768);
        EXPECT_EQ(last_two[0].state, "not-available");
        EXPECT_EQ(last_two[1].state, "dont-care");
    }
}

TEST(ProfileContent, Tc10MirrorAndRampsoakLimits) {
    const auto tc10 = builtin("tc10");
    const auto rampsoak = builtin("rampsoak");
    ASSERT_TRUE(tc10 && rampsoak);
    ASSERT_EQ(tc10->mirrors.size(), 1u);
    EXPECT_EQ(tc10->mirrors[0].first, 640);
    EXPECT_EQ(tc10->mirrors[0].last, 796);
    EXPECT_EQ(tc10->mirrors[0].offset, 9600);
    EXPECT_FALSE(tc10->unmapped_reads_answered);
    EXPECT_EQ(tc10->limits.read_registers, 16u);
    EXPECT_EQ(rampsoak->limits.read_registers, 8u);
    EXPECT_EQ(rampsoak->default_baud, 38400u);
    EXPECT_EQ(rampsoak->default_parity, "odd");
    EXPECT_EQ(rampsoak->protocols, (std::vector<std::string>{"rtu", "ascii", "linking"}));
}

}  // namespace
}  // namespace loopwire::device
