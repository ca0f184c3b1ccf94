// loopwire devices [--json] and loopwire describe DEVICE [--group G] [--json]: what loopwire
// knows about each device, straight from its profile; with --link URL [--unit N], describe also
// reads what the unit says of itself (Read Device Identification, 43/14).
#include <algorithm>
#include <functional>
#include <optional>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/master_options.hpp"
#include "client/device_identity.hpp"
#include "profile/name_matching.hpp"
#include "profile/value_format.hpp"
#include "profile/profile.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::app {
namespace {

// Each profile with where it came from: "built-in" or the file it was loaded from.
int run_devices(const device::ProfileRegistry& profiles, bool json) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const auto& entry : profiles.profiles()) {
        const auto& p = *entry.profile;
        if (json) {
            list.push_back({{"id", p.id}, {"title", p.title}, {"protocols", p.protocols}, {"manual", p.manual_document},
                            {"parameters", p.parameters.size()}, {"source", entry.origin}});
        } else {
            fmt::print("{:<10} {} ({}; {} parameters) [{}]\n", p.id, p.title, fmt::join(p.protocols, ", "), p.parameters.size(),
                       entry.origin);
        }
    }
    if (json) fmt::print("{}\n", list.dump());
    return exit_ok;
}

std::string bound_text(const std::optional<device::Bound>& bound) {
    if (!bound) return "";
    if (const auto* number = std::get_if<double>(&*bound)) return fmt::format("{}", *number);
    return std::get<std::string>(*bound);
}

nlohmann::ordered_json bound_json(const std::optional<device::Bound>& bound) {
    if (!bound) return nullptr;
    if (const auto* number = std::get_if<double>(&*bound)) return *number;
    return {{"parameter", std::get<std::string>(*bound)}};
}

nlohmann::ordered_json parameter_json(const device::Parameter& p) {
    nlohmann::ordered_json out{{"name", p.name}, {"mnemonic", p.mnemonic}, {"group", p.group}, {"table", device::table_name(p.table)},
                               {"address", p.address}, {"access", device::access_text(p)}, {"unit", p.unit},
                               {"min", bound_json(p.min)}, {"max", bound_json(p.max)}, {"description", p.description}, {"source", p.source}};
    if (p.range_in_counts) out["range_counts"] = true;  // fixed min/max are display counts
    if (const auto* fixed = std::get_if<int>(&p.decimals)) out["decimals"] = *fixed;
    else out["decimals"] = {{"parameter", std::get<std::string>(p.decimals)}};
    if (!p.enum_labels.empty()) {
        nlohmann::ordered_json labels = nlohmann::ordered_json::object();
        for (const auto& [raw, label] : p.enum_labels) labels[std::to_string(raw)] = label;
        out["enum"] = labels;
    }
    if (!p.unit_from.empty()) {
        nlohmann::ordered_json rules = nlohmann::ordered_json::array();
        for (const auto& rule : p.unit_from) {
            nlohmann::ordered_json units = nlohmann::ordered_json::object();
            for (const auto& [raw, unit] : rule.units) units[std::to_string(raw)] = unit;
            rules.push_back({{"parameter", rule.parameter}, {"units", units}});
        }
        out["unit_from"] = rules;
    }
    if (!p.unitless.empty()) out["unitless"] = p.unitless;
    if (!p.write_modes.empty()) out["write_modes"] = p.write_modes;
    if (p.ram_only) out["storage"] = "ram";
    if (!p.note.empty()) out["note"] = p.note;
    return out;
}

// Ignoring case, and with the manual's non-ASCII letters typed in ASCII (ac20 --group Alrm).
bool in_group(const device::Parameter& p, const std::string& group) {
    return group.empty() || device::same_name(group, p.group);
}

// "St.Pn (5), Alrñ (10), ...": every group with how many parameters it holds.
std::string groups_text(const device::Profile& p) {
    std::vector<std::string> listed;
    for (const auto& group : device::group_names(p)) {
        const auto members = std::count_if(p.parameters.begin(), p.parameters.end(),
                                           [&](const device::Parameter& q) { return q.group == group; });
        listed.push_back(fmt::format("{} ({})", group, members));
    }
    return fmt::format("{}", fmt::join(listed, ", "));
}

// What the unit on the link says of itself: null where it does not implement it.
Result<nlohmann::ordered_json> read_identity(const MasterCommandOptions& link) {
    // Unit 0 broadcasts, and nobody answers a broadcast.
    if (link.unit == 0) return make_error(ErrorKind::usage, "describe --link asks one unit: give --unit 1 to 255, not 0 (broadcast)");
    auto master = link.open();
    if (!master) return master.error();
    auto identity = device::read_device_identity(**master, static_cast<std::uint8_t>(link.unit));
    if (!identity) return identity.error();
    if (!*identity) return nlohmann::ordered_json(nullptr);
    return device::identity_json(**identity);
}

void print_identity(const MasterCommandOptions& link, const nlohmann::ordered_json& identity) {
    if (identity.is_null()) {
        fmt::print("unit {} does not implement Read Device Identification (function 43/14): it answered exception 01h "
                   "(illegal function)\n", link.unit);
        return;
    }
    fmt::print("unit {} at {} identifies itself (function 43/14):\n", link.unit, link.link);
    for (const auto& [name, value] : identity.items()) fmt::print("  {:<20} {}\n", name, value.get<std::string>());
}

int run_describe(const device::ProfileRegistry& profiles, const std::string& id, const std::string& group, bool json,
                 const nlohmann::ordered_json* identity) {
    auto profile = profiles.find(id);
    if (!profile) return report_error(profile.error());
    const auto& p = **profile;
    std::vector<const device::Parameter*> shown;
    for (const auto& parameter : p.parameters) {
        if (in_group(parameter, group)) shown.push_back(&parameter);
    }
    if (shown.empty()) {
        return report_error(make_error(ErrorKind::usage, fmt::format("{} has no group '{}'; its groups: {}", id, group,
                                                                     fmt::join(device::group_names(p), ", "))));
    }
    if (json) {
        nlohmann::ordered_json list = nlohmann::ordered_json::array();
        for (const auto* parameter : shown) list.push_back(parameter_json(*parameter));
        nlohmann::ordered_json aliases = nlohmann::ordered_json::object();
        for (const auto& [alias, name] : p.aliases) aliases[alias] = name;
        nlohmann::ordered_json out{{"id", p.id}, {"title", p.title}, {"aliases", aliases}, {"groups", device::group_names(p)}};
        if (identity) out["device_identity"] = *identity;
        out["parameters"] = list;
        fmt::print("{}\n", out.dump());
        return exit_ok;
    }
    fmt::print("{} — {}\n{:<34} {:<8} {:<8} {:>5} {:<3} {:<6} {:<24} {}\n", p.id, p.title, "name", "mnemonic", "table", "addr", "acc", "unit", "range", "meaning");
    for (const auto* q : shown) {
        const std::string range = (q->min || q->max) ? bound_text(q->min) + ".." + bound_text(q->max) : "";
        fmt::print("{:<34} {:<8} {:<8} {:>5} {:<3} {:<6} {:<24} {}\n", q->name, q->mnemonic, device::table_name(q->table), q->address,
                   device::access_text(*q), q->unit, range, q->description.substr(0, 60));
    }
    if (!p.aliases.empty() && group.empty()) {
        std::vector<std::string> aliases;
        for (const auto& [alias, name] : p.aliases) aliases.push_back(fmt::format("{} = {}", alias, name));
        fmt::print("also named: {}\n", fmt::join(aliases, ", "));
    }
    if (group.empty()) fmt::print("groups (--group G shows one): {}\n", groups_text(p));
    return exit_ok;
}

// Both commands load the registry when they run: --profile may come after their name, and is
// only parsed by then.
int with_registry(const ProfileOptions& profiles, const std::function<int(const device::ProfileRegistry&)>& run) {
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    return run(*registry);
}

}  // namespace

void add_profile_commands(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto json = std::make_shared<bool>(false);
    auto* devices = app.add_subcommand("devices", "List the device profiles loopwire knows");
    devices->add_flag("--json", *json, "Print the list as JSON");
    devices->callback([json, &exit_code, &profiles] {
        exit_code = with_registry(profiles, [&](const device::ProfileRegistry& registry) { return run_devices(registry, *json); });
    });

    struct DescribeOptions {
        std::string id;
        std::string group;
        MasterCommandOptions link;  // --link, --unit, --timeout, --retries, -v, --json
    };
    auto options = std::make_shared<DescribeOptions>();
    auto* describe = app.add_subcommand("describe", "Print a device's register map: names, mnemonics, addresses, access, units, "
                                                    "ranges; with --link, what the unit says of itself (function 43/14)");
    describe->add_option("device", options->id, "Profile id (see `loopwire devices`; --profile FILE.json adds a profile); "
                                                "optional with --link");
    describe->add_option("--group", options->group, "Only this group or menu");
    options->link.add_to(*describe);
    describe->get_option("--link")->required(false)->description(
        "Also read the unit's Read Device Identification (VendorName, ProductCode, ...) on this link URL");
    describe->callback([options, &exit_code, &profiles] {
        const bool linked = !options->link.link.empty();
        if (!linked && options->id.empty()) {
            exit_code = report_error(make_error(ErrorKind::usage, "describe needs a DEVICE (see `loopwire devices`), or --link URL "
                                                                  "to ask a unit what it is"));
            return;
        }
        std::optional<nlohmann::ordered_json> identity;
        if (linked) {
            auto read = read_identity(options->link);
            if (!read) {
                exit_code = report_error(read.error());
                return;
            }
            identity = std::move(*read);
        }
        const bool as_json = options->link.json;
        if (options->id.empty()) {
            if (as_json) fmt::print("{}\n", nlohmann::ordered_json{{"unit", options->link.unit}, {"device_identity", *identity}}.dump());
            else print_identity(options->link, *identity);
            exit_code = exit_ok;
            return;
        }
        if (identity && !as_json) print_identity(options->link, *identity);
        exit_code = with_registry(profiles, [&](const device::ProfileRegistry& registry) {
            return run_describe(registry, options->id, options->group, as_json, identity ? &*identity : nullptr);
        });
    });
}

}  // namespace loopwire::app
