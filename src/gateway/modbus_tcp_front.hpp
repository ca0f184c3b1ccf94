#pragma once
// The gateway's Modbus TCP front (docs/DESIGN.md, gateway): the listener and the slave that
// serves the lines' units to TCP clients, on an event loop and a thread of its own. It outlives
// the gateway that routes to it: a reload that reopens the gateway with [modbus_tcp] unchanged
// keeps the front, and with it every client's connection; the gateway opened
// next routes the units to its own lines (route_to).
//
// A gateway given a front to keep runs its engine on the front's loop (loop(), gateway/engine.hpp):
// one thread then carries the clients, the polls and the writes by name, and is named lw-engine
// from then on (lw-modbus-tcp while it serves the clients alone). The loop runs for as
// long as the front exists, even after the front failed, so an engine on it never waits in vain.
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <stop_token>
#include <thread>

#include <boost/asio/io_context.hpp>

#include "common/result.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "session/slave.hpp"
#include "session/trace.hpp"
#include "transport/tcp.hpp"

namespace loopwire::gateway {

struct FrontOptions {
    session::TraceSink trace;  // every frame the front takes and answers (-v)
    // Connections closed by the front's limits, which come by the thousand under a flood.
    GatewayLog connection_log;
};

class ModbusTcpFront {
public:
    // Listens at `config`'s address and serves at once: until the first route_to, every
    // request is answered with exception 0Ah (no path to a unit yet).
    static Result<std::unique_ptr<ModbusTcpFront>> open(const ModbusTcpConfig& config, FrontOptions options = {});
    ~ModbusTcpFront();  // closes the listener and every connection
    ModbusTcpFront(const ModbusTcpFront&) = delete;
    ModbusTcpFront& operator=(const ModbusTcpFront&) = delete;

    // Whether this front is the one `config` asks for: the same address, connection limits and
    // allow lists (a narrowed list closes the connections it no longer admits).
    // What the units do with requests (writes, max_age) is the routed gateway's.
    bool listens_as(const ModbusTcpConfig& config) const;

    std::uint16_t port() const { return listener_->port(); }

    // The event loop the front serves on, for a gateway's engine to run on too; it runs until the
    // front is destroyed.
    boost::asio::io_context& loop() { return loop_; }

    // Requests from now on go to `units` (a gateway's forwarding units, by TCP unit id); the
    // ones already handed to the previous units are answered by them.
    void route_to(session::UnitMap units);
    // Between two gateways: each of `units`' ids is answered with exception 0Bh (gateway target
    // device failed to respond) and nothing reaches a line, until the next route_to.
    void hold(const session::UnitMap& units);

    // Stopped when the front stopped serving by itself (it failed): why, from error().
    std::stop_token failed() const { return failed_.get_token(); }
    Error error() const;

    session::TcpConnectionStatistics statistics() const { return slave_->tcp_statistics(); }

private:
    ModbusTcpFront(const ModbusTcpConfig& config, std::unique_ptr<transport::TcpListener> listener,
                   std::unique_ptr<session::Slave> slave);

    ModbusTcpConfig config_;
    std::unique_ptr<transport::TcpListener> listener_;
    std::unique_ptr<session::Slave> slave_;
    std::stop_source failed_;
    mutable std::mutex mutex_;
    Error error_{ErrorKind::link, ""};  // the thread's, guarded by `mutex_`
    // After the slave: handlers still queued when the loop ends (the connections they hold)
    // go while the slave is there.
    boost::asio::io_context loop_{1};
    std::jthread thread_;  // last: stops and joins before the loop, the slave and the listener go
};

}  // namespace loopwire::gateway
