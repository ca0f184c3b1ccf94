// loopwire gateway --config FILE [--check] [-v], or --print-config
// One process owns every line of the configuration and shares it: Modbus TCP clients reach the
// devices through it, their requests queued fairly with each other (docs/DESIGN.md, gateway).
// SIGHUP re-reads the configuration: a bad one is reported and the running one kept.
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <optional>
#include <utility>

#include <systemd/sd-daemon.h>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/gateway_log.hpp"
#include "app/stop_signal.hpp"
#include "gateway/config_schema.hpp"
#include "gateway/gateway.hpp"

namespace loopwire::app {
namespace {

struct GatewayCommandOptions {
    std::string config;
    bool check = false;
    bool verbose = false;
    bool print_config = false;
};

spdlog::logger& gateway_log() {
    static const std::shared_ptr<spdlog::logger> logger = make_gateway_logger();
    return *logger;
}

void log_line(const std::string& line) { log_event(gateway_log(), line); }
void log_warning(const std::string& line) { gateway_log().warn(line); }
void log_debug(const std::string& line) { gateway_log().debug(line); }

// Every Modbus TCP and HTTP client costs a descriptor, and the default soft limit (1024) is far
// below what the kernel lets the process have (the hard limit). Raised once at start, so that the
// fronts' own bounds ([modbus_tcp] and [http] max_connections), not the soft limit, decide who
// is served. systemd sets both through LimitNOFILE= (packaging/loopwire-gateway.service).
void raise_descriptor_limit() {
    rlimit limit{};
    if (::getrlimit(RLIMIT_NOFILE, &limit) != 0) {
        log_debug(fmt::format("open files: the limit cannot be read ({})", std::strerror(errno)));
        return;
    }
    if (limit.rlim_cur >= limit.rlim_max) {
        log_debug(fmt::format("open files: at most {} (already the hard limit)", limit.rlim_cur));
        return;
    }
    const rlim_t before = limit.rlim_cur;
    limit.rlim_cur = limit.rlim_max;
    if (::setrlimit(RLIMIT_NOFILE, &limit) != 0) {
        log_debug(fmt::format("open files: at most {}; raising it to the hard limit {} failed ({})", before, limit.rlim_max,
                              std::strerror(errno)));
        return;
    }
    log_debug(fmt::format("open files: limit raised from {} to the hard limit, {}", before, limit.rlim_max));
}

// What SIGHUP hands over to the serving loop: a configuration that loaded, and the request to
// stop the gateway running now so that the loop opens the new one.
class Reloads {
public:
    Reloads(std::string file, const device::ProfileRegistry& profiles) : file_(std::move(file)), profiles_(profiles) {}

    // On the signal thread, which also takes SIGTERM: loading must never wait. It reads only
    // regular files, each examined before it is opened and opened without blocking, so a FIFO
    // or a device named in the new file is an error here, not a hang (common/regular_file.hpp).
    // A configuration that does not load changes nothing.
    void hangup() {
        auto loaded = gateway::load_gateway_config(file_, profiles_);
        if (!loaded) {
            log_warning(fmt::format("configuration not reloaded, the running one is kept: {}", loaded.error().message));
            return;
        }
        std::lock_guard lock(mutex_);
        if (serving_ && !gateway::reload_needs_restart(*serving_, *loaded)) {
            // Nothing the gateway runs has changed: everything stays up; a new log level applies now.
            const bool level_changed = serving_->log.level != loaded->log.level;
            serving_->log.level = loaded->log.level;
            set_log_level(gateway_log(), loaded->log.level);
            log_line(fmt::format("configuration {} re-read: {}; lines, listeners, connections and MQTT stay up", file_,
                                 level_changed ? "only the log level changed" : "nothing changed"));
            return;
        }
        next_ = std::move(*loaded);
        running_.request_stop();
    }

    // A stop token for the gateway about to serve `config`.
    std::stop_token start_round(const gateway::GatewayConfig& config) {
        std::lock_guard lock(mutex_);
        serving_ = config;
        running_ = std::stop_source();
        return running_.get_token();
    }

    // The configuration the next round will serve, if a reload asked for one.
    std::optional<gateway::GatewayConfig> next() {
        std::lock_guard lock(mutex_);
        return next_;
    }

    std::optional<gateway::GatewayConfig> take() {
        std::lock_guard lock(mutex_);
        return std::exchange(next_, std::nullopt);
    }

private:
    std::string file_;
    const device::ProfileRegistry& profiles_;
    std::mutex mutex_;
    std::stop_source running_;
    std::optional<gateway::GatewayConfig> next_;
    std::optional<gateway::GatewayConfig> serving_;  // what the running gateway was opened with
};

void announce(const gateway::GatewayConfig& config, const gateway::Gateway& running) {
    std::size_t devices = 0;
    for (const auto& line : config.lines) devices += line.devices.size();
    if (config.modbus_tcp.enabled) {
        log_line(fmt::format("{} line(s), {} device(s); Modbus TCP on {} (listening on port {}); Ctrl-C to stop",
                             config.lines.size(), devices, config.modbus_tcp.host, running.modbus_tcp_port()));
    } else {
        log_line(fmt::format("{} line(s), {} device(s); Modbus TCP front disabled; Ctrl-C to stop", config.lines.size(), devices));
    }
    if (config.history) log_line(fmt::format("history: recording to {}", config.history->database.string()));
    if (config.http) {
        const bool ipv6 = config.http->host.find(':') != std::string::npos;
        log_line(fmt::format("HTTP API and dashboard on http://{}{}{}:{}/ (writes {})", ipv6 ? "[" : "", config.http->host,
                             ipv6 ? "]" : "", running.http_port(),
                             config.http->token.empty() ? "refused: no http.token_file" : "with the token"));
    }
    // Under systemd (Type=notify, packaging/loopwire-gateway.service) the unit is up once the
    // lines and the listener are open; without $NOTIFY_SOCKET these calls do nothing.
    sd_notifyf(0, "READY=1\nSTATUS=serving %zu line(s), %zu device(s)", config.lines.size(), devices);
}

// The Modbus TCP front `config` asks for: `front` itself when it listens as asked (a reload
// that left [modbus_tcp] alone keeps every client's connection), else a new one (or none).
Result<void> keep_or_open_front(const gateway::GatewayConfig& config, const gateway::GatewayOptions& options,
                                std::unique_ptr<gateway::ModbusTcpFront>& front) {
    if (front && front->listens_as(config.modbus_tcp) && !front->failed().stop_requested()) {
        const auto open = front->statistics().open;
        log_line(fmt::format("Modbus TCP front kept on port {}: {} client connection(s) stay up", front->port(), open));
        return {};
    }
    front.reset();  // before the new one: it may listen on the same port
    if (!config.modbus_tcp.enabled) return {};
    auto opened = gateway::ModbusTcpFront::open(config.modbus_tcp, {options.trace, options.debug_log});
    if (!opened) return opened.error();
    front = std::move(*opened);
    return {};
}

// Serves `config` until `stop` or a reload is requested; the error when it cannot be opened.
Result<void> serve_round(const gateway::GatewayConfig& config, gateway::GatewayOptions options,
                         const std::stop_token& stop, Reloads& reloads, std::unique_ptr<gateway::ModbusTcpFront>& front) {
    set_log_level(gateway_log(), config.log.level);
    const std::stop_token reload = reloads.start_round(config);
    if (auto kept = keep_or_open_front(config, options, front); !kept) return kept.error();
    options.front = front.get();
    auto running = gateway::Gateway::open(config, options);
    if (!running) return running.error();
    announce(config, **running);
    std::stop_source either;
    std::stop_callback on_stop(stop, [&either] { either.request_stop(); });
    std::stop_callback on_reload(reload, [&either] { either.request_stop(); });
    auto served = (*running)->serve(either.get_token());
    if (auto next = reloads.next(); next && !stop.stop_requested()) (*running)->hand_over_to(*next);
    for (const auto& line : (*running)->report()) log_line(gateway::describe(line));
    if (config.modbus_tcp.enabled) log_line(gateway::describe((*running)->front_report()));
    return served;
}

int run_gateway(const GatewayCommandOptions& options, const ProfileOptions& profiles) {
    if (options.print_config) {
        fmt::print("{}", gateway::commented_example_config());
        return exit_ok;
    }
    if (options.config.empty()) {
        return report_error(make_error(ErrorKind::usage, "gateway: --config FILE.toml is required (`loopwire gateway "
                                                         "--print-config > gateway.toml` writes a complete example)"));
    }
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto config = gateway::load_gateway_config(options.config, *registry);
    if (!config) return report_error(config.error());
    if (auto ready = gateway::check_environment(*config); !ready) return report_error(ready.error());
    if (options.check) {
        if (auto reached = gateway::check_history_forwarding(*config); !reached) return report_error(reached.error());
        fmt::print("{}", gateway::describe_plan(*config));
        return exit_ok;
    }
    set_log_level(gateway_log(), config->log.level);
    raise_descriptor_limit();
    Reloads reloads(options.config, *registry);
    StopSignal stop(std::nullopt, [&reloads] { reloads.hangup(); });  // before any thread starts
    gateway::GatewayOptions gateway_options;
    gateway_options.log = log_line;
    gateway_options.debug_log = log_debug;
    if (options.verbose) gateway_options.trace = stderr_trace();
    gateway::GatewayConfig current = std::move(*config);
    std::optional<gateway::GatewayConfig> previous;
    std::unique_ptr<gateway::ModbusTcpFront> front;  // kept across reloads that leave [modbus_tcp] alone
    for (;;) {
        auto served = serve_round(current, gateway_options, stop.token(), reloads, front);
        if (!served && !previous) return report_error(served.error());
        if (!served) {
            // The new configuration loaded but could not be opened (an address taken, a history
            // database it cannot read; a missing port is only a line that is down): back to the
            // one that ran.
            log_warning(fmt::format("the reloaded configuration cannot be served ({}); going back to the previous one",
                                 served.error().message));
            current = std::move(*std::exchange(previous, std::nullopt));
            continue;
        }
        if (stop.token().stop_requested()) break;
        if (auto next = reloads.take()) {
            sd_notify(0, "RELOADING=1");
            log_line(fmt::format("configuration {} reloaded", options.config));
            previous = std::exchange(current, std::move(*next));
        }
    }
    sd_notify(0, "STOPPING=1");
    return exit_ok;
}

}  // namespace

void add_gateway_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<GatewayCommandOptions>();
    auto* command = app.add_subcommand("gateway", "Own the lines of a configuration file and serve them to Modbus TCP clients");
    auto* config = command->add_option("--config", options->config, "Gateway configuration (TOML): lines, devices, the Modbus TCP front")
        ->type_name("FILE.toml");
    auto* check = command->add_flag("--check", options->check, "Check the configuration and print the plan (lines, devices, estimated line load); serve nothing");
    command
        ->add_flag("--print-config", options->print_config,
                   "Print a complete configuration with every key, its meaning, bounds and default (man loopwire-gateway.toml)")
        ->excludes(check)
        ->excludes(config);
    command->add_flag("-v,--verbose", options->verbose, "Print every frame on the lines and the front, with timestamps, on stderr");
    command->footer(std::string("SIGTERM or Ctrl-C stops the gateway once the requests it has taken are answered; SIGHUP re-reads "
                                "the configuration (a configuration with errors is reported and the running one kept).\n\n") +
                    exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_gateway(*options, profiles); });
}

}  // namespace loopwire::app
