#pragma once
// GET /metrics: the gateway's figures in Prometheus's text exposition format (version 0.0.4),
// every name prefixed loopwire_.
#include <string>
#include <vector>

#include "gateway/gateway.hpp"
#include "gateway/history_source.hpp"
#include "gateway/opcua/opcua_figures.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

// A configured device and the line it is on.
struct MetricsDevice {
    std::string name;
    std::string line;
};

// Per line: requests (and of them polls), answers, timeouts, bad replies, garbled frames,
// expired, abandoned and refused requests, busy and open time and their ratio, whether it is up
// and how often it went down, the poll samples its devices missed and how many of them are
// stale now (the line cannot carry its polls). Per device (`devices`, in configured order): its
// status as a 1 among 0s, its polls, failed and missed polls, and the age of its last answered
// poll. Per polled numeric value read by the latest poll: the value in its unit and its age.
// Each named bit of the polled bit fields as 1 or 0. The history store's rows, with one. The
// Modbus TCP front's connections, with `front`; the HTTP server's, with `http`. Every sample carries gateway="GATEWAY" (its
// [gateway] name, when it has one) as its first label.
// The OPC UA front's sessions, monitored items and writes by outcome, with `opcua`.
// The HTTP server's own figures.
struct HttpReport {
    std::uint64_t not_allowed = 0;  // clients closed at accept: outside [http] allow
};

std::string prometheus_text(const std::string& gateway, const std::vector<LineReport>& lines,
                            const std::vector<MetricsDevice>& devices, const std::vector<CachedDevice>& values,
                            const HistorySource* history, const FrontReport* front = nullptr,
                            const HttpReport* http = nullptr, const OpcuaFigures* opcua = nullptr);

}  // namespace loopwire::gateway
