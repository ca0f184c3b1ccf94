#include "gateway/service.hpp"

#include <memory>
#include <utility>

#include <fmt/format.h>

#include "gateway/config_change.hpp"
#include "gateway/http_server.hpp"
#include "gateway/http_sessions.hpp"
#include "gateway/line_keeper.hpp"
#include "gateway/modbus_tcp_front.hpp"
#include "gateway/sparkplug/sparkplug_node.hpp"

namespace loopwire::gateway {
namespace {

// Who asks for a reload, as the audit names it: the signal, sent by `systemctl reload` or kill -HUP.
constexpr const char* reloader = "SIGHUP";

void say(const GatewayLog& log, const std::string& line) {
    if (log) log(line);
}

// The Modbus TCP front `config` asks for: `front` itself when it listens as asked (a reload
// that left [modbus_tcp] alone keeps every client's connection), else a new one (or none).
Result<void> keep_or_open_front(const GatewayConfig& config, const GatewayOptions& options, const ServiceLog& log,
                                std::unique_ptr<ModbusTcpFront>& front) {
    if (front && front->listens_as(config.modbus_tcp) && !front->failed().stop_requested()) {
        const auto open = front->statistics().open;
        say(log.info, fmt::format("Modbus TCP front kept on port {}: {} client connection(s) stay up", front->port(), open));
        return {};
    }
    front.reset();  // before the new one: it may listen on the same port
    if (!config.modbus_tcp.enabled) return {};
    auto opened = ModbusTcpFront::open(config.modbus_tcp, {options.trace, options.debug_log});
    if (!opened) return opened.error();
    front = std::move(*opened);
    return {};
}

// The HTTP API's listening socket `config` asks for: `listener` itself when it listens as asked
// (a reload that left [http] listen alone keeps its port, and the clients that connect meanwhile
// wait in its backlog), else a new one (or none).
Result<void> keep_or_open_http_listener(const GatewayConfig& config, const ServiceLog& log,
                                        std::optional<HttpListener>& listener) {
    if (config.http && listener && listener->listens_as(config.http->host, config.http->port)) {
        say(log.info, fmt::format("HTTP API kept listening on port {}", listener->port()));
        return {};
    }
    listener.reset();  // before the new one: it may listen on the same port
    if (!config.http) return {};
    auto opened = HttpListener::open(config.http->host, config.http->port);
    if (!opened) return opened.error();
    listener.emplace(std::move(*opened));
    return {};
}

// What one call of serve_with_reloads keeps between its rounds.
struct Service {
    GatewayOptions options;
    ConfigReloads& reloads;
    const std::stop_token& stop;
    const ServiceLog& log;
    const ServiceHooks& hooks;
    // The lines kept across reloads that leave them alone; after the front, which routes to them.
    LineKeeper lines;
    std::unique_ptr<ModbusTcpFront> front;  // kept across reloads that leave [modbus_tcp] alone
    std::optional<HttpListener> http_listener;  // kept across reloads that leave [http] listen alone
    KeptSparkplug sparkplug;  // between two rounds whose [sparkplug] is the same; its session ends with the service
    // The HTTP API's sessions and failed logins: a reload logs nobody out.
    std::shared_ptr<HttpLogins> http_logins = std::make_shared<HttpLogins>();

    // Serves `config` until `stop` or a reload is requested; the error when it cannot be opened.
    Result<void> round(const GatewayConfig& config) {
        if (log.set_level) log.set_level(config.log.level);
        const std::stop_token reload = reloads.start_round(config);
        if (auto kept = keep_or_open_front(config, options, log, front); !kept) return kept.error();
        if (auto kept = keep_or_open_http_listener(config, log, http_listener); !kept) return kept.error();
        GatewayOptions round_options = options;
        round_options.front = front.get();
        round_options.lines = &lines;
        round_options.http_listener = http_listener ? &*http_listener : nullptr;
        round_options.sparkplug = &sparkplug;
        round_options.http_logins = http_logins;
        round_options.http_listener_kept = [this] {
            const auto next = reloads.next();
            return next && !stop.stop_requested() && next->http && http_listener &&
                   http_listener->listens_as(next->http->host, next->http->port);
        };
        auto running = Gateway::open(config, round_options);
        if (!running) return running.error();
        if (auto reloaded = reloads.take_reload_record()) (*running)->audit(std::move(*reloaded));
        if (hooks.serving) hooks.serving(config, **running);
        std::stop_source either;
        std::stop_callback on_stop(stop, [&either] { either.request_stop(); });
        std::stop_callback on_reload(reload, [&either] { either.request_stop(); });
        reloads.while_serving([&gateway = **running] { return gateway.reload_http_certificate(); },
                              [&gateway = **running](AuditRecord record) { gateway.audit(std::move(record)); });
        auto served = (*running)->serve(either.get_token());
        reloads.while_serving(nullptr);
        if (auto next = reloads.next(); next && !stop.stop_requested()) (*running)->hand_over_to(*next);
        for (const auto& line : (*running)->report()) say(log.info, describe(line));
        if (config.modbus_tcp.enabled) say(log.info, describe((*running)->front_report()));
        return served;
    }
};

}  // namespace

void ConfigReloads::hangup() {
    auto loaded = load_gateway_config(file_, profiles_);
    if (!loaded) {
        say(log_.warning, fmt::format("configuration not reloaded, the running one is kept: {}", loaded.error().message));
        std::lock_guard lock(mutex_);
        if (audit_) {
            audit_(reload_record(reloader, file_, "none: the file does not load", audit_refused(loaded.error().message)));
        }
        return;
    }
    std::lock_guard lock(mutex_);
    const std::string change = serving_ ? describe_config_change(*serving_, *loaded) : "the whole configuration";
    if (serving_ && !reload_needs_restart(*serving_, *loaded)) {
        if (audit_) audit_(reload_record(reloader, file_, change, std::string(audit_confirmed)));
        // Nothing the gateway runs has changed: everything stays up; a new log level applies now.
        const bool level_changed = serving_->log.level != loaded->log.level;
        serving_->log.level = loaded->log.level;
        if (log_.set_level) log_.set_level(loaded->log.level);
        // The certificate files may have been replaced (a renewal): new connections get theirs.
        if (reread_ && loaded->http && !loaded->http->certificate.empty()) {
            if (auto reread = reread_(); !reread) {
                say(log_.warning, fmt::format("HTTPS certificate not reloaded, the running one is kept: {}",
                                              reread.error().message));
            } else {
                say(log_.info, fmt::format("HTTPS certificate {} re-read for new connections", loaded->http->certificate));
            }
        }
        say(log_.info, fmt::format("configuration {} re-read: {}; lines, listeners, connections and MQTT stay up", file_,
                                   level_changed ? "only the log level changed" : "nothing changed"));
        return;
    }
    next_ = std::move(*loaded);
    // Stamped now: the row says when it was asked for, though the new gateway records it.
    reload_record_ = reload_record(reloader, file_, change, std::string(audit_confirmed));
    reload_record_->time = std::chrono::system_clock::now();
    running_.request_stop();
}

void ConfigReloads::while_serving(std::function<Result<void>()> reread, std::function<void(AuditRecord)> audit) {
    std::lock_guard lock(mutex_);
    reread_ = std::move(reread);
    audit_ = std::move(audit);
}

std::optional<AuditRecord> ConfigReloads::take_reload_record() {
    std::lock_guard lock(mutex_);
    return std::exchange(reload_record_, std::nullopt);
}

void ConfigReloads::reload_refused(const std::string& reason) {
    std::lock_guard lock(mutex_);
    if (reload_record_) reload_record_->outcome = audit_refused(reason);
}

std::stop_token ConfigReloads::start_round(const GatewayConfig& config) {
    std::lock_guard lock(mutex_);
    serving_ = config;
    running_ = std::stop_source();
    return running_.get_token();
}

std::optional<GatewayConfig> ConfigReloads::next() {
    std::lock_guard lock(mutex_);
    return next_;
}

std::optional<GatewayConfig> ConfigReloads::take() {
    std::lock_guard lock(mutex_);
    return std::exchange(next_, std::nullopt);
}

Result<void> serve_with_reloads(GatewayConfig config, const GatewayOptions& options, ConfigReloads& reloads,
                                const std::stop_token& stop, const ServiceLog& log, const ServiceHooks& hooks) {
    Service service{options, reloads, stop, log, hooks, {}, nullptr, std::nullopt, {}};
    GatewayConfig current = std::move(config);
    std::optional<GatewayConfig> previous;
    for (;;) {
        auto served = service.round(current);
        if (!served && !previous) return served.error();
        if (!served) {
            // The new configuration loaded but could not be opened (an address taken, a history
            // database it cannot read; a missing port is only a line that is down): back to the
            // one that ran.
            say(log.warning, fmt::format("the reloaded configuration cannot be served ({}); going back to the previous one",
                                         served.error().message));
            reloads.reload_refused(
                fmt::format("cannot be served ({}); the previous configuration runs again", served.error().message));
            current = std::move(*std::exchange(previous, std::nullopt));
            continue;
        }
        if (stop.stop_requested()) return {};
        if (auto next = reloads.take()) {
            if (hooks.reloading) hooks.reloading();
            say(log.info, fmt::format("configuration {} reloaded", reloads.file()));
            previous = std::exchange(current, std::move(*next));
        }
    }
}

}  // namespace loopwire::gateway
