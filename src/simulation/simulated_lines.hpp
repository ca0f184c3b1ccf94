#pragma once
// The simulated devices of several lines, served from one thread. A gateway simulates the
// devices of each of its virtual lines (rtu:virtual); one thread answers them all, however many
// lines there are, rather than a thread per line (docs/DESIGN.md, gateway: the thread count
// does not grow with the lines).
//
// Each line is a port on its bus and the Slave serving its devices. The port should be attached
// with VirtualBus::Writes::return_at_once, so that a reply on one line never waits for the wire
// time of a reply on another. The thread waits in ppoll() on every port's poll handle, the next
// frame deadline and the next reply due, and serves each port through Slave::StreamSteps: the
// framing and reply timing of Slave::serve_stream, on a shared thread.
#include <cstddef>
#include <memory>

#include "common/result.hpp"
#include "session/slave.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::simulation {

class SimulatedLines {
public:
    SimulatedLines();
    ~SimulatedLines();  // stops serving and joins the thread
    SimulatedLines(const SimulatedLines&) = delete;
    SimulatedLines& operator=(const SimulatedLines&) = delete;

    // Serves `devices` on `port` from now on; from any thread. A port without a poll handle
    // cannot be waited on with the others: ErrorKind::usage.
    Result<void> add(std::unique_ptr<transport::ByteStream> port, std::unique_ptr<session::Slave> devices);

    // Lines served, and how many of them stopped on a stream error (their port failed).
    std::size_t lines() const;
    std::size_t failed() const;

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::simulation
