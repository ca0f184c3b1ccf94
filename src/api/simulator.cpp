#include <loopwire/simulator.hpp>

#include <thread>

#include <fmt/format.h>

#include "api/device_spec.hpp"
#include "api/failure_translation.hpp"
#include "devices/registry.hpp"
#include "session/slave.hpp"
#include "transport/link_url.hpp"
#include "transport/serial_port.hpp"
#include "transport/tcp.hpp"

namespace loopwire {

struct Simulator::State {
    transport::LinkUrl link;
    std::unique_ptr<transport::TcpListener> listener;  // tcp and rtu+tcp links
    std::unique_ptr<transport::ByteStream> stream;     // serial links
    std::unique_ptr<session::Slave> slave;
    Result<void> outcome;  // how serving ended; read only after the thread is joined
    bool stopped = false;
    // Last member, so it is stopped and joined before anything it uses is destroyed.
    std::jthread thread;
};

namespace {

session::UnitMap simulated_units(const std::vector<std::string>& devices, const transport::LinkUrl& link,
                                 const SimulatorOptions& options) {
    if (devices.empty()) {
        throw Failure(Failure::Kind::usage, "name the devices to simulate, e.g. {\"tc10@3\"}");
    }
    session::UnitMap units;
    device::SimulationEnvironment environment;
    environment.speed = options.speed;
    environment.seed = options.seed;
    for (const std::string& text : devices) {
        auto address = api::value_or_throw(api::resolve_device(text));
        if (units.contains(address.unit)) {
            throw Failure(Failure::Kind::usage, fmt::format("unit {} is given twice ('{}'); each unit id can be served once",
                                                            address.unit, text));
        }
        units[address.unit] = device::models::make_simulated_device(
            address.profile, environment.on_line(address.unit, link));
    }
    return units;
}

void open_side(Simulator::State& state) {
    if (!state.link.is_serial()) {
        state.listener = api::value_or_throw(transport::TcpListener::listen(state.link.host, state.link.port));
        return;
    }
    if (state.link.path == "virtual") {
        throw Failure(Failure::Kind::usage, "a virtual bus exists only inside the command line's own process; "
                                            "serve on tcp://127.0.0.1:0 instead");
    }
    state.stream = api::value_or_throw(transport::open_serial_port(state.link.path, state.link.serial));
}

}  // namespace

Simulator::Simulator(std::unique_ptr<State> state) : state_(std::move(state)) {}
Simulator::Simulator(Simulator&&) noexcept = default;
Simulator& Simulator::operator=(Simulator&&) noexcept = default;
Simulator::~Simulator() = default;

Simulator Simulator::start(const std::string& url, const std::vector<std::string>& devices, const SimulatorOptions& options) {
    auto state = std::make_unique<State>();
    state->link = api::value_or_throw(transport::parse_link_url(url));
    auto units = simulated_units(devices, state->link, options);
    // Listening (or opening the port) happens here, so a master may connect as soon as
    // start() returns and a port in use is reported to the caller, not lost in the thread.
    open_side(*state);
    state->slave = std::make_unique<session::Slave>(state->link, std::move(units));
    State& serving = *state;
    state->thread = std::jthread([&serving](std::stop_token stop) {
        serving.outcome = serving.listener ? serving.slave->serve_listener(*serving.listener, std::move(stop))
                                           : serving.slave->serve_stream(*serving.stream, std::move(stop));
    });
    return Simulator(std::move(state));
}

std::uint16_t Simulator::port() const { return state_->listener ? state_->listener->port() : 0; }

std::string Simulator::url() const {
    transport::LinkUrl served = state_->link;
    if (state_->listener) served.port = state_->listener->port();
    return served.to_string();
}

std::uint64_t Simulator::requests_served() const { return state_->slave->requests_served(); }

void Simulator::stop() {
    if (!state_ || state_->stopped) return;
    state_->thread.request_stop();
    if (state_->thread.joinable()) state_->thread.join();
    state_->stopped = true;
    api::throw_if_failed(state_->outcome);
}

}  // namespace loopwire
