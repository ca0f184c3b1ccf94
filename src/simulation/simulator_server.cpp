#include "simulation/simulator_server.hpp"

#include <fmt/format.h>

#include "transport/pseudo_terminal.hpp"
#include "transport/serial_port.hpp"

namespace loopwire::device {
namespace {

Result<std::unique_ptr<transport::ByteStream>> open_serial_side(const SimulatorLink& link) {
    if (!link.pty.empty()) return transport::create_pseudo_terminal(link.pty, link.url.serial);
    if (link.url.path == "virtual") {
        return make_error(ErrorKind::usage, "a virtual bus exists only inside one process; use --pty PATH to let other programs reach the simulator");
    }
    return transport::open_serial_port(link.url.path, link.url.serial);
}

}  // namespace

Result<SimulatorLink> simulator_link(const std::string& link, const std::string& pty) {
    if (link.empty() && pty.empty()) {
        return make_error(ErrorKind::usage, "say where to serve: --link URL (serial port or tcp://host:port) or --pty PATH");
    }
    auto url = transport::parse_link_url(link.empty() ? "rtu:" + pty : link);
    if (!url) return url.error();
    if (!pty.empty() && !url->is_serial()) {
        return make_error(ErrorKind::usage, "--pty makes a pseudo-terminal, which carries serial framings (rtu, ascii, linking), not " + transport::framing_name(url->framing));
    }
    return SimulatorLink{*url, pty};
}

Result<std::unique_ptr<SimulatorServer>> SimulatorServer::open(const SimulatorLink& link, SimulatedUnitMap units,
                                                               SimulatorOptions options) {
    std::unique_ptr<SimulatorServer> server(new SimulatorServer(link.url, std::move(units), std::move(options)));
    if (link.url.is_serial()) {
        auto stream = open_serial_side(link);
        if (!stream) return stream.error();
        server->stream_ = std::move(*stream);
    } else {
        auto listener = transport::TcpListener::listen(link.url.host, link.url.port);
        if (!listener) return listener.error();
        server->listener_ = std::move(*listener);
    }
    return server;
}

std::string SimulatorServer::opened() const {
    if (stream_) return stream_->describe();
    return fmt::format("listening on port {}", listener_->port());
}

Result<void> SimulatorServer::serve(std::stop_token stop) {
    if (stream_) return slave_.serve_stream(*stream_, std::move(stop));
    return slave_.serve_listener(*listener_, std::move(stop));
}

}  // namespace loopwire::device
