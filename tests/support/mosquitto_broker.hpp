#pragma once
// A real mosquitto broker for the gateway's MQTT tests (the MQTT front, the Sparkplug B node),
// on a loopback port of its own, and a libmosquitto client in the test that watches it as any
// subscriber would and publishes for the test.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <mosquitto.h>

#include "support/eventually.hpp"

extern char** environ;

namespace loopwire::testing {

using namespace std::chrono_literals;

inline constexpr const char* broker_program = "/usr/sbin/mosquitto";
// Generous: CI runs this under ASan and TSan on two loaded cores.
inline constexpr auto deadline = 30s;

// A loopback port held for a broker before it listens: bound with SO_REUSEADDR and never
// listening, so the kernel gives the port to nothing else (no other bind to port 0, no outgoing
// connection's own port) while mosquitto, which binds its listeners with SO_REUSEADDR too, can
// take it. Unlike a port found free and let go, no other process can take it in between.
// (mosquitto cannot be told port 0 and report the port it got.)
class PortReservation {
public:
    PortReservation() : fd_(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
        if (fd_ < 0) throw std::runtime_error("socket");
        const int on = 1;
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t length = sizeof address;
        if (::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on) != 0 ||
            ::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
            ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
            ::close(fd_);
            throw std::runtime_error("cannot reserve a loopback port");
        }
        port_ = ntohs(address.sin_port);
    }
    ~PortReservation() {
        if (fd_ >= 0) ::close(fd_);
    }
    PortReservation(PortReservation&& other) noexcept : fd_(std::exchange(other.fd_, -1)), port_(other.port_) {}
    PortReservation& operator=(PortReservation&& other) noexcept {
        if (this != &other) {
            if (fd_ >= 0) ::close(fd_);
            fd_ = std::exchange(other.fd_, -1);
            port_ = other.port_;
        }
        return *this;
    }
    PortReservation(const PortReservation&) = delete;
    PortReservation& operator=(const PortReservation&) = delete;

    std::uint16_t port() const { return port_; }

private:
    int fd_;
    std::uint16_t port_ = 0;
};

// Whether something listens on 127.0.0.1:port now.
inline bool listening(std::uint16_t port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return false;
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const bool connected = ::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
    ::close(fd);
    return connected;
}

// Readable by all: mosquitto started as root reads its files as the user it drops to.
inline std::filesystem::path temporary_directory() {
    std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-mqtt-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp");
    std::filesystem::permissions(pattern, std::filesystem::perms::owner_all | std::filesystem::perms::group_read | std::filesystem::perms::group_exec | std::filesystem::perms::others_read |
                                 std::filesystem::perms::others_exec);
    return pattern;
}

// A mosquitto broker on a loopback port of its own, nothing kept on disk: anonymous, or with the
// listener settings `settings` (TLS files, a password file) written into its configuration. The
// constructor returns once it listens. Should its port be taken all the same (a program binding
// a fixed port with SO_REUSEADDR), it starts again on a fresh one, a few times.
class Broker {
public:
    explicit Broker(const std::string& settings = "allow_anonymous true\n") : directory_(temporary_directory()) {
        for (int attempt = 1;; ++attempt) {
            if (attempt > 1) reservation_ = PortReservation();
            configure(settings);
            if (try_start()) return;
            if (attempt == start_attempts) throw std::runtime_error("mosquitto did not start:\n" + log());
        }
    }
    // On a port reserved beforehand: a broker that a gateway was told of before it started.
    explicit Broker(PortReservation reservation, const std::string& settings = "allow_anonymous true\n")
        : reservation_(std::move(reservation)), directory_(temporary_directory()) {
        configure(settings);
        start();
    }
    ~Broker() {
        stop();
        std::error_code ignored;
        std::filesystem::remove_all(directory_, ignored);
    }
    Broker(const Broker&) = delete;
    Broker& operator=(const Broker&) = delete;

    // Starts the broker (again, after stop(): the same port, nothing kept of before); returns once
    // it listens.
    void start() {
        if (!try_start()) throw std::runtime_error("mosquitto did not start:\n" + log());
    }
    void stop() {
        if (pid_ <= 0) return;
        ::kill(pid_, SIGKILL);  // as a crash: no goodbye to the clients
        ::waitpid(pid_, nullptr, 0);
        pid_ = -1;
    }
    // SIGHUP: mosquitto reads its password file again.
    void reload() const { ::kill(pid_, SIGHUP); }
    std::uint16_t port() const { return reservation_.port(); }
    std::string log() const {
        std::ifstream in(directory_ / "broker.log");
        return std::string(std::istreambuf_iterator<char>(in), {});
    }

private:
    static constexpr int start_attempts = 5;

    void configure(const std::string& settings) const {
        std::ofstream(directory_ / "mosquitto.conf") << fmt::format(
            "per_listener_settings true\npersistence false\nlistener {} 127.0.0.1\n{}", port(), settings);
    }

    // Spawns mosquitto and waits until it listens (true) or has exited (false: its log says why,
    // a port taken or a setting refused).
    bool try_start() {
        const std::string config = (directory_ / "mosquitto.conf").string();
        const std::string log_file = (directory_ / "broker.log").string();
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_file.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
        std::vector<std::string> words{broker_program, "-c", config};
        std::vector<char*> argv;
        for (auto& word : words) argv.push_back(word.data());
        argv.push_back(nullptr);
        const int rc = posix_spawn(&pid_, broker_program, &actions, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        if (rc != 0) throw std::runtime_error("cannot start mosquitto");
        bool exited = false;
        const bool up = eventually(
            [&] {
                exited = ::waitpid(pid_, nullptr, WNOHANG) == pid_;
                return exited || listening(port());
            },
            deadline);
        if (exited) pid_ = -1;
        if (!up) throw std::runtime_error("mosquitto did not listen in time:\n" + log());
        return !exited;
    }

    PortReservation reservation_;
    std::filesystem::path directory_;
    pid_t pid_ = -1;
};

struct Message {
    std::string payload;
    bool retained = false;
};

// A subscriber to PREFIX/# that keeps every message, and publishes for the test.
struct WatcherOptions {
    std::string topics = "#";
    std::string ca_file;  // set: TLS
    std::string username;
    std::string password;
};

class Watcher {
public:
    explicit Watcher(std::uint16_t port, const WatcherOptions& options = {}) {
        mosquitto_lib_init();
        client_ = mosquitto_new(nullptr, true, this);
        if (!options.ca_file.empty() &&
            mosquitto_tls_set(client_, options.ca_file.c_str(), nullptr, nullptr, nullptr, nullptr) != MOSQ_ERR_SUCCESS) {
            throw std::runtime_error("cannot set TLS");
        }
        if (!options.username.empty()) mosquitto_username_pw_set(client_, options.username.c_str(), options.password.c_str());
        mosquitto_subscribe_callback_set(client_, [](mosquitto*, void* self, int, int, const int*) {
            auto& watcher = *static_cast<Watcher*>(self);
            std::lock_guard lock(watcher.mutex_);
            watcher.subscribed_ = true;
            watcher.arrived_.notify_all();
        });
        mosquitto_message_callback_set(client_, [](mosquitto*, void* self, const mosquitto_message* message) {
            auto& watcher = *static_cast<Watcher*>(self);
            std::lock_guard lock(watcher.mutex_);
            std::string payload(static_cast<const char*>(message->payload),
                                static_cast<std::size_t>(message->payloadlen));
            watcher.arrival_.emplace_back(message->topic, payload);
            watcher.messages_[message->topic].push_back({std::move(payload), message->retain});
            watcher.arrived_.notify_all();
        });
        // The broker may still be starting (one started again after a stop): try until the deadline.
        const auto connected = [&] { return mosquitto_connect(client_, "127.0.0.1", port, 30) == MOSQ_ERR_SUCCESS; };
        if (!eventually(connected, deadline, 50ms)) throw std::runtime_error("the broker did not start");
        // Before the loop's thread starts, and not from a callback: libmosquitto calls those
        // holding a lock that a subscribe or publish there would take out of order.
        if (mosquitto_subscribe(client_, nullptr, options.topics.c_str(), 1) != MOSQ_ERR_SUCCESS) {
            throw std::runtime_error("cannot subscribe");
        }
        mosquitto_loop_start(client_);
        std::unique_lock lock(mutex_);
        if (!arrived_.wait_for(lock, deadline, [this] { return subscribed_; })) throw std::runtime_error("no SUBACK");
    }
    ~Watcher() {
        mosquitto_disconnect(client_);
        mosquitto_loop_stop(client_, false);
        mosquitto_destroy(client_);
    }
    Watcher(const Watcher&) = delete;
    Watcher& operator=(const Watcher&) = delete;

    void publish(const std::string& topic, const std::string& payload, bool retain = false) {
        ASSERT_EQ(mosquitto_publish(client_, nullptr, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, retain),
                  MOSQ_ERR_SUCCESS);
    }

    // The last payload of `topic` once `accept` takes it; nullopt at the deadline.
    std::optional<std::string> wait_for(const std::string& topic, const std::function<bool(const std::string&)>& accept) {
        std::unique_lock lock(mutex_);
        std::optional<std::string> found;
        arrived_.wait_for(lock, deadline, [&] {
            const auto it = messages_.find(topic);
            if (it == messages_.end() || it->second.empty() || !accept(it->second.back().payload)) return false;
            found = it->second.back().payload;
            return true;
        });
        return found;
    }
    std::optional<std::string> wait_for(const std::string& topic, const std::string& payload) {
        return wait_for(topic, [&](const std::string& last) { return last == payload; });
    }
    // The `count`th message of `topic` (from 1), waiting for it.
    std::optional<std::string> nth(const std::string& topic, std::size_t count) {
        std::unique_lock lock(mutex_);
        if (!arrived_.wait_for(lock, deadline, [&] { return messages_[topic].size() >= count; })) return std::nullopt;
        return messages_[topic][count - 1].payload;
    }
    std::size_t count(const std::string& topic) {
        std::lock_guard lock(mutex_);
        return messages_[topic].size();
    }
    // Every topic seen that starts with `head`.
    std::vector<std::string> topics(const std::string& head) {
        std::lock_guard lock(mutex_);
        std::vector<std::string> found;
        for (const auto& [topic, list] : messages_) {
            if (topic.rfind(head, 0) == 0 && !list.empty()) found.push_back(topic);
        }
        return found;
    }

    // Every message of the topics `wanted` takes, as (topic, payload), in the order they arrived
    // (messages_ keeps each topic's alone).
    std::vector<std::pair<std::string, std::string>> arrived(const std::function<bool(const std::string&)>& wanted) {
        std::lock_guard lock(mutex_);
        std::vector<std::pair<std::string, std::string>> found;
        for (const auto& message : arrival_) {
            if (wanted(message.first)) found.push_back(message);
        }
        return found;
    }

private:
    mosquitto* client_ = nullptr;
    std::mutex mutex_;
    std::condition_variable arrived_;
    bool subscribed_ = false;
    std::map<std::string, std::vector<Message>> messages_;
    std::vector<std::pair<std::string, std::string>> arrival_;
};

}  // namespace loopwire::testing
