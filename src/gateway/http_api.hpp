#pragma once
// The gateway's HTTP API (docs/DESIGN.md, gateway): what each route answers, in JSON, on the
// server of gateway/http_server.hpp.
//   GET  /api/devices                 the devices, with their line, unit and status
//   GET  /api/devices/NAME            one device: its parameters with values, units and ranges
//   POST /api/devices/NAME/write      {"PARAMETER": "text", ...} with the token; as `write` checks
//   POST /api/login                   {"user", "password"} (JSON or a form): a session cookie,
//                                     and the CSRF token its writes send as X-CSRF-Token
//   POST /api/logout, GET /api/session  end it; who is logged in (401: nobody)
//   GET  /api/events                  server-sent events: the full picture, then each change
//   GET  /api/history?device=...      downsampled series from the history store, JSON or CSV;
//                                     &gateway=NAME: another gateway's, from the shared historian
//   GET  /api/audit?from=&to=&device= the audit of writes from every front, newest first
//   GET  /api/alarms, /api/alarms/history, POST /api/alarms/NAME/ack, ... (alarms/alarm_http.hpp)
//   GET  /metrics                     Prometheus text: the lines' and devices' figures
//   GET  /, /assets/*                 the dashboard (gateway/dashboard_assets.hpp)
// Errors are {"error": "..."} with a status that fits.
// Who may do what ([http] users_file, token_file, open_reads): docs/security.md and
// gateway/http_users.hpp.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gateway/alarms/alarm_service.hpp"
#include "gateway/device_writer.hpp"
#include "gateway/gateway.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/history_source.hpp"
#include "gateway/http_server.hpp"
#include "gateway/http_sessions.hpp"
#include "gateway/opcua/opcua_figures.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

// What the API reads and writes through; each must outlive it.
struct HttpApiSources {
    ValueCache* cache = nullptr;
    const DeviceWriter* writer = nullptr;
    std::function<std::vector<LineReport>()> lines;  // the lines' figures, for /metrics
    std::function<FrontReport()> front;               // the Modbus TCP front's; none: not shown
    std::function<std::uint64_t()> http_not_allowed;  // clients the HTTP server closed at accept
    const HistorySource* history = nullptr;           // none: /api/history answers 404
    std::function<OpcuaFigures()> opcua = {};         // the OPC UA front's; none: not shown
    std::function<void(const std::string&)> log = {};  // failed logins, at warning; none: not logged
    // Sessions and failed logins kept across reloads (gateway/http_sessions.hpp); none: the API's own.
    std::shared_ptr<HttpLogins> logins = {};
    alarms::AlarmService* alarms = nullptr;           // /api/alarms (gateway/alarms/alarm_http.hpp)
};

class HttpApi final : public HttpHandler {
public:
    HttpApi(const GatewayConfig& config, HttpApiSources sources);
    ~HttpApi() override;
    HttpOutcome handle(const HttpRequest& request) override;

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
