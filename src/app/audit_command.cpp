// loopwire audit --database FILE [--from -24h] [--to now] [--device NAME] [--limit N]
//                [--format table|csv|json]
// The audit of writes a gateway keeps in its [history] file: every write from every front
// (HTTP, MQTT, Sparkplug, Modbus TCP) and every reload of its configuration, newest first, as
// GET /api/audit answers it.

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/history_file.hpp"
#include "gateway/history_query.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/http_text.hpp"

namespace loopwire::app {
namespace {

struct AuditCommandOptions {
    std::string database;
    std::string device;
    std::string from = "-24h";
    std::string to = "now";
    std::size_t limit = 1000;
    std::string format = "table";
};

// The options as /api/audit's query, percent-encoded, so that the API's parser checks and reads
// them: the same times and bounds.
std::string as_query(const AuditCommandOptions& options) {
    std::string query = fmt::format("from={}&to={}&limit={}", gateway::percent_encode(options.from), gateway::percent_encode(options.to), options.limit);
    if (!options.device.empty()) query += "&device=" + gateway::percent_encode(options.device);
    return query;
}

void print_table(const std::vector<gateway::AuditRecord>& records) {
    fmt::print("{:<24} {:<10} {:<22} {:<20} {:<32} {:>14} {:>14}  {}\n", "time", "front", "peer", "device", "parameter", "old",
               "new", "outcome");
    for (const auto& record : records) {
        fmt::print("{:<24} {:<10} {:<22} {:<20} {:<32} {:>14} {:>14}  {}\n", gateway::iso_time(record.time),
                   record.origin.front, record.origin.peer, record.device, record.parameter,
                   // A reload has no old value to be unknown: what changed is its new one.
                   record.old_value.empty() && record.origin.front != "reload" ? "?" : record.old_value,
                   record.new_value, record.outcome);
    }
}

int run_audit(const AuditCommandOptions& options) {
    auto query = gateway::audit_query(as_query(options), std::chrono::system_clock::now());
    if (!query) return report_error(query.error());
    auto db = open_history_file("audit", options.database);
    if (!db) return report_error(db.error());
    auto records = gateway::history::run_audit_query(*db, *query);
    if (!records) return report_error(records.error());
    if (options.format == "csv") {
        fmt::print("{}", gateway::audit_csv(*records));
    } else if (options.format == "json") {
        fmt::print("{}\n", gateway::audit_json(*records));
    } else {
        print_table(*records);
    }
    return exit_ok;
}

}  // namespace

void add_audit_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<AuditCommandOptions>();
    auto* command = app.add_subcommand(
        "audit", "Print the audit of writes and reloads a gateway keeps in its history file, newest first");
    command->add_option("--database", options->database, "A gateway's [history] database file")->type_name("FILE")->required();
    command->add_option("--device", options->device, "Only this device's writes (its name in the gateway's configuration)")
        ->type_name("NAME");
    command->add_option("--from", options->from, "Start: ISO 8601 with its zone, or a time before now (-1h, -7d)")
        ->type_name("TIME")
        ->capture_default_str();
    command->add_option("--to", options->to, "End: as --from, or now")->type_name("TIME")->capture_default_str();
    command->add_option("--limit", options->limit, "Records at most, newest first (1..100000)")->type_name("N")->capture_default_str();
    command->add_option("--format", options->format, "table, csv or json")
        ->check(CLI::IsMember({"table", "csv", "json"}))
        ->capture_default_str();
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_audit(*options); });
}

}  // namespace loopwire::app
