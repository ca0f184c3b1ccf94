#pragma once
// The simulated devices of several lines, served from one thread: the lines' loop
// (session/line_loop.hpp), the thread that carries a gateway's masters too, so simulating a
// line's devices costs no thread at all (docs/DESIGN.md, gateway: the thread count does not grow
// with the lines).
//
// Each line is a port on its bus and the Slave serving its devices. The port should be attached
// with VirtualBus::Writes::return_at_once, so that a reply on one line never waits for the wire
// time of a reply on another. Each port is a wait on the loop, woken by its bytes or by its next
// deadline (a frame's silence, a reply due), and served through Slave::StreamSteps: the framing
// and reply timing of Slave::serve_stream, on a shared thread.
#include <cstddef>
#include <memory>

#include "common/result.hpp"
#include "session/line_loop.hpp"
#include "session/slave.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::simulation {

class SimulatedLines {
public:
    explicit SimulatedLines(std::shared_ptr<session::LineLoop> loop);
    ~SimulatedLines();  // stops serving: no wait on the loop refers to a line afterwards
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
