#pragma once
// The TCP side of a slave (tcp and rtu+tcp links): every accepted client served on one
// Boost.Asio event loop, so that a slow or hostile client is bounded by its own queue and never
// by the others' latency (DESIGN.md). Per-frame decisions stay in Slave::answer_async.
#include <stop_token>

#include <boost/asio/io_context.hpp>

#include "common/result.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {

class Slave;

// Serves every connection `listener` accepts until `stop` is requested, with the limits in
// slave.options().tcp. The listener stays usable afterwards. Idle costs no wake-ups at all.
// `loop`: the caller's event loop to serve on (Slave::serve_listener); none: one of its own.
Result<void> serve_tcp_clients(Slave& slave, transport::TcpListener& listener, std::stop_token stop,
                               boost::asio::io_context* loop = nullptr);

}  // namespace loopwire::session
