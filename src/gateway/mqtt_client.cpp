#include "gateway/mqtt_client.hpp"

#include <mutex>

#include <fmt/format.h>
#include <mosquitto.h>

#include "common/peer_text.hpp"

namespace loopwire::gateway::mqtt {

void init_library_once() {
    static std::once_flag once;
    std::call_once(once, [] { mosquitto_lib_init(); });
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

std::string retained_command_refusal(std::string_view topic) {
    return fmt::format(
        "published with the retain flag; nothing was written: a retained command would be written again at "
        "every reconnection, so commands are taken live only. Publish it without retain, and clear the "
        "retained copy (an empty retained message on {})",
        quoted_excerpt(topic));
}

std::string handshake_failure(const std::string& why) {
    return fmt::format("the connection was made but ended before the broker accepted it ({}): is this port an MQTT broker "
                       "(not TLS, not another service)?; retrying in the background",
                       why);
}

}  // namespace loopwire::gateway::mqtt
