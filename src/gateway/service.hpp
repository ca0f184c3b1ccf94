#pragma once
// The life of `loopwire gateway` around one Gateway: serving a configuration until stopped, and
// SIGHUP's reload: a configuration that loads and changes what runs replaces the running one
// (the Modbus TCP front kept when [modbus_tcp] is unchanged, the HTTP API's listening socket when
// [http] listen is, the lines it leaves alone), one that changes nothing the
// gateway runs is applied in place, and one that does not load or cannot be served is reported
// while the previous one goes on. The command only sets up the log, signals and service manager.
#include <functional>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>

#include "common/result.hpp"
#include "gateway/gateway.hpp"
#include "gateway/gateway_config.hpp"

namespace loopwire::gateway {

// Where the service tells what it does. Any of them may be called from the signal thread.
struct ServiceLog {
    GatewayLog info;
    GatewayLog warning;
    GatewayLog debug;
    std::function<void(LogConfig::Level)> set_level;  // the level a configuration asks for, applied now
};

// What SIGHUP hands over to the serving loop: a configuration that loaded, and the request to
// stop the gateway running now so that the loop opens the new one.
class ConfigReloads {
public:
    ConfigReloads(std::string file, const device::ProfileRegistry& profiles, ServiceLog log)
        : file_(std::move(file)), profiles_(profiles), log_(std::move(log)) {}

    // On the signal thread, which also takes SIGTERM: loading must never wait. It reads only
    // regular files, each examined before it is opened and opened without blocking, so a FIFO
    // or a device named in the new file is an error here, not a hang (common/regular_file.hpp).
    // A configuration that does not load changes nothing.
    void hangup();

    // A stop token for the gateway about to serve `config`, stopped when a reload needs a restart.
    std::stop_token start_round(const GatewayConfig& config);

    // The configuration the next round will serve, if a reload asked for one.
    std::optional<GatewayConfig> next();
    // The same, taken: the next reload starts afresh.
    std::optional<GatewayConfig> take();

    const std::string& file() const { return file_; }

    // While a gateway serves: what re-reads the files its configuration names but does not hold
    // (the HTTPS certificate), for a reload that changes nothing else, and its audit, which
    // records each reload that does not restart it (gateway/config_change.hpp). None between
    // gateways.
    void while_serving(std::function<Result<void>()> reread, std::function<void(AuditRecord)> audit = {});

    // The audit record of the reload that asked for the next round, for that round's gateway to
    // record once open (its history file is the new configuration's); refused with `reason`
    // when the round cannot be opened, for the previous configuration's gateway to record.
    std::optional<AuditRecord> take_reload_record();
    void reload_refused(const std::string& reason);

private:
    std::string file_;
    const device::ProfileRegistry& profiles_;
    ServiceLog log_;
    std::mutex mutex_;
    std::stop_source running_;
    std::optional<GatewayConfig> next_;
    std::optional<GatewayConfig> serving_;  // what the running gateway was opened with
    std::function<Result<void>()> reread_;  // while_serving's
    std::function<void(AuditRecord)> audit_;    // while_serving's
    std::optional<AuditRecord> reload_record_;  // of the reload that asked for next_
};

struct ServiceHooks {
    // Each time a gateway is open and serving (the first time, and after each reload): for the
    // announcement and a service manager's readiness.
    std::function<void(const GatewayConfig&, const Gateway&)> serving;
    // A reloaded configuration is about to replace the running one.
    std::function<void()> reloading;
};

// Serves `config` until `stop`, replacing it with each configuration `reloads` hands over. An
// error only when `config` itself cannot be served; a reloaded configuration that cannot be is
// logged, and the one before it served again.
Result<void> serve_with_reloads(GatewayConfig config, const GatewayOptions& options, ConfigReloads& reloads,
                                const std::stop_token& stop, const ServiceLog& log, const ServiceHooks& hooks);

}  // namespace loopwire::gateway
