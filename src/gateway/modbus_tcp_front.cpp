#include "gateway/modbus_tcp_front.hpp"

#include <boost/asio/executor_work_guard.hpp>
#include <fmt/format.h>

#include "common/thread_name.hpp"
#include "transport/link_url.hpp"

namespace loopwire::gateway {
namespace {

// Modbus application protocol V1.1b3, 7: "gateway path unavailable", for a unit id no line of
// this gateway leads to.
constexpr std::uint8_t gateway_path_unavailable = 0x0A;
// Ibid.: "gateway target device failed to respond", while the gateway is being reopened.
constexpr std::uint8_t gateway_target_failed = 0x0B;

// Requests one Modbus TCP connection may have waiting for the lines; a client pipelining more
// is not read until it is below (session::TcpClientLimits). With max_connections (64 by
// default) this bounds what the front can put in the lines' queues, which bound themselves too
// (LineSchedulerOptions::max_queued).
constexpr std::size_t requests_per_connection = 16;

// A unit while no gateway serves it: every request answered with exception 0Bh at once, so a
// client retries rather than waits, and nothing reaches a line being closed.
class HeldUnit : public session::UnitHandler {
public:
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override {
        if (broadcast || request_pdu.empty()) return std::nullopt;
        return Bytes{static_cast<std::uint8_t>(request_pdu[0] | 0x80), gateway_target_failed};
    }
};

}  // namespace

Result<std::unique_ptr<ModbusTcpFront>> ModbusTcpFront::open(const ModbusTcpConfig& config, FrontOptions options) {
    auto listener = transport::TcpListener::listen(config.host, config.port);
    if (!listener) {
        return make_error(listener.error().kind,
                          fmt::format("modbus_tcp.listen {}:{}: {}", config.host, config.port, listener.error().message));
    }
    const bool ipv6 = config.host.find(':') != std::string::npos;
    const auto host = ipv6 ? "[" + config.host + "]" : config.host;
    auto link = transport::parse_link_url(fmt::format("tcp://{}:{}", host, (*listener)->port()));
    if (!link) return link.error();
    session::SlaveOptions slave_options;
    slave_options.trace = std::move(options.trace);
    slave_options.unserved_unit_exception = gateway_path_unavailable;
    slave_options.connection_log = std::move(options.connection_log);
    slave_options.tcp.max_connections = config.max_connections;
    slave_options.tcp.idle_timeout = config.idle_timeout;
    slave_options.tcp.max_outstanding_requests = requests_per_connection;
    slave_options.access = {config.allow, config.write_allow};
    auto slave = std::make_unique<session::Slave>(*link, session::UnitMap{}, std::move(slave_options));
    return std::unique_ptr<ModbusTcpFront>(new ModbusTcpFront(config, std::move(*listener), std::move(slave)));
}

ModbusTcpFront::ModbusTcpFront(const ModbusTcpConfig& config, std::unique_ptr<transport::TcpListener> listener,
                               std::unique_ptr<session::Slave> slave)
    : config_(config), listener_(std::move(listener)), slave_(std::move(slave)) {
    thread_ = std::jthread([this](std::stop_token stop) {
        auto served = slave_->serve_listener(*listener_, stop, loop_);
        if (served) return;
        {
            std::lock_guard lock(mutex_);
            error_ = served.error();
        }
        failed_.request_stop();
        // Failed, the front still runs its loop until it is destroyed: an engine on it
        // (loop()) takes itself down through it.
        auto busy = boost::asio::make_work_guard(loop_);
        loop_.restart();
        std::stop_callback on_stop(stop, [this] { loop_.stop(); });
        loop_.run();
    });
    name_thread(thread_.native_handle(), "lw-modbus-tcp");
}

ModbusTcpFront::~ModbusTcpFront() {
    thread_.request_stop();
    thread_.join();
}

bool ModbusTcpFront::listens_as(const ModbusTcpConfig& config) const {
    return config.enabled && config.host == config_.host && config.port == config_.port &&
           config.max_connections == config_.max_connections && config.idle_timeout == config_.idle_timeout &&
           config.allow == config_.allow && config.write_allow == config_.write_allow;
}

void ModbusTcpFront::route_to(session::UnitMap units) { slave_->replace_units(std::move(units)); }

void ModbusTcpFront::hold(const session::UnitMap& units) {
    session::UnitMap held;
    auto handler = std::make_shared<HeldUnit>();
    for (const auto& [unit, routed] : units) held[unit] = handler;
    slave_->replace_units(std::move(held));
}

Error ModbusTcpFront::error() const {
    std::lock_guard lock(mutex_);
    return error_;
}

}  // namespace loopwire::gateway
