// loopwire history --database URL|FILE [--gateway NAME] --device NAME [--parameters a,b]
//                  [--from -1h] [--to now] [--points N] [--format table|csv]
// The recorded history of one device, cut into buckets as GET /api/history cuts it: from the
// shared PostgreSQL historian (any gateway that forwards to it, --gateway required), or from a
// gateway's own SQLite file.
#include <filesystem>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "gateway/history_query.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"
#include "gateway/http_text.hpp"
#include "gateway/postgres_history_query.hpp"

namespace loopwire::app {
namespace {

struct HistoryCommandOptions {
    std::string database;
    std::string gateway;
    std::string device;
    std::string parameters;
    std::string from = "-1h";
    std::string to = "now";
    std::size_t points = 500;
    std::string format = "table";
};

// The options as /api/history's query, percent-encoded, so that the API's parser checks and
// reads them: the same times ("-1h", ISO 8601 with its zone, "now") and the same bounds.
std::string as_query(const HistoryCommandOptions& options) {
    std::string query = fmt::format("device={}&from={}&to={}&points={}", gateway::percent_encode(options.device), gateway::percent_encode(options.from),
                                    gateway::percent_encode(options.to), options.points);
    if (!options.parameters.empty()) query += "&parameters=" + gateway::percent_encode(options.parameters);
    return query;
}

Result<std::vector<gateway::HistorySeries>> ask(const HistoryCommandOptions& options, const gateway::HistoryQuery& query) {
    if (gateway::postgres::is_conninfo(options.database)) {
        if (options.gateway.empty()) {
            return make_error(ErrorKind::usage, "history: --gateway NAME is required with a PostgreSQL database (it holds many "
                                                "gateways' history)");
        }
        // The password as libpq finds it: in the URL, or PGPASSFILE (~/.pgpass).
        auto db = gateway::postgres::Connection::connect(options.database, std::nullopt, 10);
        if (!db) return db.error();
        return gateway::postgres_history::run_query(*db, options.gateway, query);
    }
    if (!options.gateway.empty()) {
        return make_error(ErrorKind::usage, "history: --gateway is for a PostgreSQL database; a gateway's own file holds only "
                                            "its history");
    }
    std::error_code error;
    if (!std::filesystem::is_regular_file(options.database, error)) {
        return make_error(ErrorKind::usage, fmt::format("history: {} is not a history file (a [history] database) nor a "
                                                        "postgresql:// URL", options.database));
    }
    auto db = gateway::history::open_for_reading(options.database);
    if (!db) return db.error();
    return gateway::history::run_query(*db, query);
}

// Each series in time order: the value in force at the start (recorded before --from; no
// bucket, so no count), then its buckets and gaps as they come, as the CSV has them.
void print_table(const std::vector<gateway::HistorySeries>& series) {
    fmt::print("{:<24} {:<8} {:<24} {:>12} {:>12} {:>12} {:>6}\n", "parameter", "unit", "time", "min", "max", "mean", "count");
    for (const auto& one : series) {
        gateway::visit_in_time_order(
            one, {[&](const gateway::HistoryBefore& before) {
                      fmt::print("{:<24} {:<8} {:<24} {:>12g} in force at the start (the last value recorded before it)\n",
                                 one.parameter, one.unit, gateway::iso_time(before.time), before.value);
                  },
                  [&](const gateway::HistoryBucket& bucket) {
                      fmt::print("{:<24} {:<8} {:<24} {:>12g} {:>12g} {:>12g} {:>6}\n", one.parameter, one.unit,
                                 gateway::iso_time(bucket.start), bucket.min, bucket.max, bucket.mean, bucket.count);
                  },
                  [&](const gateway::HistoryGap& gap) {
                      fmt::print("{:<24} {:<8} no value from {} to {}\n", one.parameter, one.unit, gateway::iso_time(gap.start),
                                 gap.end ? gateway::iso_time(*gap.end) : "now");
                  }});
    }
}

int run_history(const HistoryCommandOptions& options) {
    auto parsed = gateway::history_query(as_query(options), std::chrono::system_clock::now());
    if (!parsed) return report_error(parsed.error());
    auto series = ask(options, parsed->query);
    if (!series) return report_error(series.error());
    if (options.format == "csv") {
        fmt::print("{}", gateway::history_csv(*series));
    } else {
        print_table(*series);
    }
    return exit_ok;
}

}  // namespace

void add_history_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<HistoryCommandOptions>();
    auto* command = app.add_subcommand("history", "Print a device's recorded history, from a gateway's file or the shared "
                                                  "PostgreSQL historian");
    command->add_option("--database", options->database, "A postgresql:// URL (or host=... dbname=...) of the historian, or a "
                                                         "gateway's [history] database file")
        ->type_name("URL|FILE")
        ->required();
    command->add_option("--gateway", options->gateway, "The gateway whose device it is ([gateway] name); with a PostgreSQL database")
        ->type_name("NAME");
    command->add_option("--device", options->device, "The device's name in the gateway's configuration")->type_name("NAME")->required();
    command->add_option("--parameters", options->parameters, "Parameters as recorded, comma-separated (default: every one)")
        ->type_name("A,B");
    command->add_option("--from", options->from, "Start: ISO 8601 with its zone, or a time before now (-1h, -7d)")
        ->type_name("TIME")
        ->capture_default_str();
    command->add_option("--to", options->to, "End: as --from, or now")->type_name("TIME")->capture_default_str();
    command->add_option("--points", options->points, "Buckets per parameter at most (1..10000)")->type_name("N")->capture_default_str();
    command->add_option("--format", options->format, "table or csv")->check(CLI::IsMember({"table", "csv"}))->capture_default_str();
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_history(*options); });
}

}  // namespace loopwire::app
