#include "session/master.hpp"

#include "transport/serial_port.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {

Result<std::unique_ptr<Master>> open_master(const transport::LinkUrl& link, MasterOptions options) {
    if (link.is_serial()) {
        if (link.path == "virtual") {
            return make_error(ErrorKind::usage,
                              "'" + link.to_string() + "' is an in-process virtual bus: only "
                              "`loopwire demo` and tests can reach it; name a serial port, a "
                              "pseudo-terminal or a TCP address instead");
        }
        auto stream = transport::open_serial_port(link.path, link.serial);
        if (!stream) return stream.error();
        return make_serial_master(std::move(*stream), link, std::move(options));
    }
    auto stream = transport::connect_tcp(link.host, link.port, options.timeout);
    if (!stream) return stream.error();
    if (link.framing == transport::Framing::rtu_over_tcp) {
        return make_serial_master(std::move(*stream), link, std::move(options));
    }
    return make_tcp_master(std::move(*stream), link, std::move(options));
}

}  // namespace loopwire::session
