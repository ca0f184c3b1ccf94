// loopwire alarms --database FILE [--from -24h] [--to now] [--limit N] [--format table|csv|json]
// The alarm journal a gateway keeps in its [history] file: every transition of every alarm,
// newest first, as GET /api/alarms/history answers it.

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/history_file.hpp"
#include "gateway/alarms/alarm_journal.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/http_text.hpp"

namespace loopwire::app {
namespace {

struct AlarmsCommandOptions {
    std::string database;
    std::string from = "-24h";
    std::string to = "now";
    std::size_t limit = 1000;
    std::string format = "table";
};

// The times as the API's query, so that they are read (and checked) as /api/alarms/history reads them.
std::string as_query(const AlarmsCommandOptions& options) {
    return fmt::format("from={}&to={}&limit={}", gateway::percent_encode(options.from), gateway::percent_encode(options.to), options.limit);
}

void print_table(const std::vector<gateway::alarms::JournalRow>& rows) {
    fmt::print("{:<24} {:<32} {:<24} {:>12} {:<8} {:<12} {}\n", "time", "alarm", "state", "value", "severity", "user",
               "message / comment");
    for (const auto& row : rows) {
        const std::string value = row.value ? fmt::format("{}{}{}", *row.value, row.unit.empty() ? "" : " ", row.unit) : "";
        std::string said = row.message;
        if (!row.comment.empty()) said += " / " + row.comment;
        fmt::print("{:<24} {:<32} {:<24} {:>12} {:<8} {:<12} {}\n", gateway::iso_time(row.time), row.id, row.state, value,
                   row.severity, row.user.empty() ? "-" : row.user, said);
    }
}

int run_alarms(const AlarmsCommandOptions& options) {
    auto query = gateway::audit_query(as_query(options), std::chrono::system_clock::now());
    if (!query) return report_error(query.error());
    auto db = open_history_file("alarms", options.database);
    if (!db) return report_error(db.error());
    auto rows = gateway::alarms::read_journal(*db, query->from, query->to, query->limit);
    if (!rows) return report_error(rows.error());
    if (options.format == "csv") {
        fmt::print("{}", gateway::alarms::journal_csv(*rows));
    } else if (options.format == "json") {
        fmt::print("{}\n", gateway::alarms::journal_json(*rows));
    } else {
        print_table(*rows);
    }
    return exit_ok;
}

}  // namespace

void add_alarms_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<AlarmsCommandOptions>();
    auto* command = app.add_subcommand("alarms", "Print the alarm journal a gateway keeps in its history file, newest first");
    command->add_option("--database", options->database, "A gateway's [history] database file")->type_name("FILE")->required();
    command->add_option("--from", options->from, "Start: ISO 8601 with its zone, or a time before now (-1h, -7d)")
        ->type_name("TIME")
        ->capture_default_str();
    command->add_option("--to", options->to, "End: as --from, or now")->type_name("TIME")->capture_default_str();
    command->add_option("--limit", options->limit, "Transitions at most, newest first (1..100000)")
        ->type_name("N")
        ->capture_default_str();
    command->add_option("--format", options->format, "table, csv or json")
        ->check(CLI::IsMember({"table", "csv", "json"}))
        ->capture_default_str();
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_alarms(*options); });
}

}  // namespace loopwire::app
