#pragma once
// Simulated devices served on a link, as `loopwire simulate` serves them: for tests and demos
// of programs that talk to the real controllers.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace loopwire {

struct SimulatorOptions {
    double speed = 1.0;      // the process runs this many times faster than real time
    std::uint64_t seed = 1;  // seeds the simulated measurement noise, so runs repeat exactly
};

class Simulator {
public:
    // Starts serving `devices` ("tc10@3", "ac20@1", "profiles/my_device.json@5") on `url`:
    // "tcp://127.0.0.1:0" (port 0: the system picks a free port, see port() and url()),
    // "rtu+tcp://0.0.0.0:4001", or a serial port "rtu:/dev/ttyS1?baud=9600&parity=none".
    // Serving runs on a thread of its own until stop() or destruction. Throws Failure
    // (Kind::usage for a bad URL or device list, Kind::link when it cannot listen or open).
    static Simulator start(const std::string& url, const std::vector<std::string>& devices,
                           const SimulatorOptions& options = {});

    Simulator(Simulator&&) noexcept;
    Simulator& operator=(Simulator&&) noexcept;
    ~Simulator();  // stops serving

    // The TCP port served on (the one picked for port 0); 0 on a serial port.
    std::uint16_t port() const;
    // The URL a master opens to reach the simulator: with the port picked for port 0.
    std::string url() const;
    // Requests answered so far.
    std::uint64_t requests_served() const;

    // Stops serving and waits for it; throws Failure when serving had stopped on an error (a
    // serial port that went away). Calling it again does nothing.
    void stop();

    struct State;

private:
    explicit Simulator(std::unique_ptr<State> state);
    std::unique_ptr<State> state_;
};

}  // namespace loopwire
