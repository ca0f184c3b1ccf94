#pragma once
// GET /metrics: the gateway's figures in Prometheus's text exposition format (version 0.0.4),
// every name prefixed loopwire_.
#include <string>
#include <vector>

#include "gateway/gateway.hpp"
#include "gateway/history_source.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

// Per line: requests, answers, timeouts, bad replies, garbled frames, expired, abandoned and
// refused requests, busy and open time and their ratio. Per device (`devices`, in configured
// order): its status as a 1 among 0s, its polls and failed polls. The history store's rows,
// with one. The Modbus TCP front's connections, with `front`.
std::string prometheus_text(const std::vector<LineReport>& lines, const std::vector<std::string>& devices,
                            const std::vector<CachedDevice>& values, const HistorySource* history,
                            const FrontReport* front = nullptr);

}  // namespace loopwire::gateway
