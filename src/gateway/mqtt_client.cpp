#include "gateway/mqtt_client.hpp"

#include <array>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <system_error>

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <fmt/format.h>
#include <mosquitto.h>

namespace loopwire::gateway::mqtt {

void init_library_once() {
    static std::once_flag once;
    std::call_once(once, [] { mosquitto_lib_init(); });
}

Wakeup::Wakeup() : fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
    if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "eventfd for an MQTT network thread");
}

Wakeup::~Wakeup() { ::close(fd_); }

void Wakeup::notify() const {
    const std::uint64_t one = 1;
    (void)!::write(fd_, &one, sizeof one);  // a full counter is still readable: nothing lost
}

void Wakeup::drain() const {
    std::uint64_t count = 0;
    (void)!::read(fd_, &count, sizeof count);
}

void configure_security(mosquitto* client, const std::optional<MqttTls>& tls, const std::string& username,
                        const std::string& password, const std::function<void(const std::string&)>& say) {
    if (tls) {
        const std::string ca = tls->ca_file.string();
        const std::string cert = tls->cert_file.string();
        const std::string key = tls->key_file.string();
        const int rc = mosquitto_tls_set(client, ca.empty() ? nullptr : ca.c_str(), ca.empty() ? "/etc/ssl/certs" : nullptr,
                                         cert.empty() ? nullptr : cert.c_str(), key.empty() ? nullptr : key.c_str(), nullptr);
        if (rc != MOSQ_ERR_SUCCESS) say(fmt::format("cannot use the TLS files: {}", mosquitto_strerror(rc)));
    }
    if (!username.empty()) {
        const int rc = mosquitto_username_pw_set(client, username.c_str(), password.empty() ? nullptr : password.c_str());
        if (rc != MOSQ_ERR_SUCCESS) say(fmt::format("cannot use the credentials: {}", mosquitto_strerror(rc)));
    }
}

void send_without_delay(mosquitto* client) { (void)mosquitto_int_option(client, MOSQ_OPT_TCP_NODELAY, 1); }

int turn(mosquitto* client, const Wakeup& wakeup, std::chrono::milliseconds idle) {
    const int socket = mosquitto_socket(client);
    if (socket < 0) return MOSQ_ERR_NO_CONN;
    const auto want_write = static_cast<short>(mosquitto_want_write(client) ? POLLOUT : 0);
    std::array<pollfd, 2> watched{{{socket, static_cast<short>(POLLIN | want_write), 0}, {wakeup.fd(), POLLIN, 0}}};
    if (::poll(watched.data(), watched.size(), static_cast<int>(idle.count())) < 0 && errno != EINTR) return MOSQ_ERR_ERRNO;
    if (watched[1].revents & POLLIN) wakeup.drain();
    int rc = MOSQ_ERR_SUCCESS;
    if (watched[0].revents & (POLLIN | POLLHUP | POLLERR)) rc = mosquitto_loop_read(client, 1);
    if (rc == MOSQ_ERR_SUCCESS && mosquitto_socket(client) >= 0 && mosquitto_want_write(client)) {
        rc = mosquitto_loop_write(client, 1);
    }
    return rc == MOSQ_ERR_SUCCESS ? mosquitto_loop_misc(client) : rc;
}

void pause(const std::stop_token& stop, std::chrono::milliseconds delay) {
    std::mutex m;
    std::condition_variable_any woken;
    std::unique_lock lock(m);
    woken.wait_for(lock, stop, delay, [] { return false; });
}

std::string connect_failure(int rc) {
    return rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : std::string(mosquitto_strerror(rc));
}

std::string handshake_failure(int rc) {
    return fmt::format("the connection was made but ended before the broker accepted it ({}): is this port an MQTT broker "
                       "(not TLS, not another service)?; retrying in the background",
                       connect_failure(rc));
}

}  // namespace loopwire::gateway::mqtt
