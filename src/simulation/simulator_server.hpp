#pragma once
// Where `loopwire simulate` serves its units, and the serving: a serial port, a pseudo-terminal
// it creates for other programs to open, or a TCP listener; the CLI only parses its options and
// prints what this reports.
#include <cstdint>
#include <memory>
#include <stop_token>
#include <string>

#include "common/result.hpp"
#include "session/slave.hpp"
#include "transport/byte_stream.hpp"
#include "transport/link_url.hpp"
#include "transport/tcp.hpp"

namespace loopwire::device {

// What a simulator serves, and how: the units by id, and the slave's options (its -v trace).
using SimulatedUnitMap = session::UnitMap;
using SimulatorOptions = session::SlaveOptions;

struct SimulatorLink {
    transport::LinkUrl url;
    std::string pty;  // when set: a pseudo-terminal created at this path, framed as `url` says
};

// --link URL or --pty PATH (rtu framing unless --link names another serial one): one of them is
// required, and a pseudo-terminal carries serial framings only.
Result<SimulatorLink> simulator_link(const std::string& link, const std::string& pty);

// The units of one simulator, served by a slave on an open link.
class SimulatorServer {
public:
    // Opens the serial side (a port, or the pseudo-terminal) or the TCP listener. A virtual bus
    // exists only inside one process: asking to serve one is a usage error.
    static Result<std::unique_ptr<SimulatorServer>> open(const SimulatorLink& link, SimulatedUnitMap units,
                                                         SimulatorOptions options);

    // "/dev/pts/3 ..." (the stream's own description) or "listening on port 1502": what was opened.
    std::string opened() const;
    Result<void> serve(std::stop_token stop);
    std::uint64_t requests_served() const { return slave_.requests_served(); }

private:
    SimulatorServer(const transport::LinkUrl& url, SimulatedUnitMap units, SimulatorOptions options)
        : slave_(url, std::move(units), std::move(options)) {}

    session::Slave slave_;
    std::unique_ptr<transport::ByteStream> stream_;       // serial side
    std::unique_ptr<transport::TcpListener> listener_;    // network side
};

}  // namespace loopwire::device
