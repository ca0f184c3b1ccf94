// The gateway's HTTP API (gateway/http_api.hpp, gateway/http_server.hpp): an in-process gateway
// on a simulated line, asked over real sockets on 127.0.0.1 by a small client written here, as
// curl or a browser would: every route, the refusals (token, range, mode, malformed bodies,
// sizes), a stalled client that must not hold up others, the event stream seeing a write, and
// /metrics read by Prometheus's own parser. The history route is checked against a history
// source written here that records the question it was asked.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <sstream>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "gateway/engine.hpp"
#include "gateway/gateway.hpp"
#include "gateway/http_api.hpp"
#include "gateway/http_server.hpp"
#include "gateway/metrics.hpp"
#include "support/eventually.hpp"
#include "support/silenced_unit.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using loopwire::testing::eventually;
using namespace std::chrono_literals;
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using Json = nlohmann::json;

// Generous: CI runs this under ASan and TSan on two loaded cores.
constexpr auto deadline = 30s;
const std::string token = "test-token-5f1c2a9b";

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

// --- a small HTTP client --------------------------------------------------------------------

class Socket {
public:
    // `receive_buffer`: a small one makes a client that does not read fall behind sooner.
    // `from`: the loopback address the client connects from (all of 127.0.0.0/8 is loopback
    // on Linux), so one test can be several clients.
    explicit Socket(std::uint16_t port, int receive_buffer = 0, const char* from = nullptr)
        : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
        if (fd_ < 0) throw std::runtime_error("socket");
        if (receive_buffer > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
        if (from) {
            sockaddr_in source{};
            source.sin_family = AF_INET;
            ::inet_pton(AF_INET, from, &source.sin_addr);
            if (::bind(fd_, reinterpret_cast<sockaddr*>(&source), sizeof source) != 0) throw std::runtime_error("bind");
        }
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_port = htons(port);
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) throw std::runtime_error("connect");
    }
    ~Socket() { ::close(fd_); }
    Socket(const Socket&) = delete;
    Socket& operator=(const Socket&) = delete;

    // False once the server has closed the connection.
    bool send(const std::string& bytes) {
        std::size_t sent = 0;
        while (sent < bytes.size()) {
            const auto n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
            if (n <= 0) return false;  // the server closed: what it answered is still there to read
            sent += static_cast<std::size_t>(n);
        }
        return true;
    }

    // Whatever arrives within `wait`; none when the server closed the connection with nothing
    // more to read, "" when nothing came in time.
    std::optional<std::string> receive(std::chrono::milliseconds wait) {
        pollfd ready{fd_, POLLIN, 0};
        if (::poll(&ready, 1, static_cast<int>(wait.count())) <= 0) return std::string();
        char buffer[65536];
        const auto n = ::recv(fd_, buffer, sizeof buffer, 0);
        if (n <= 0) return std::nullopt;
        return std::string(buffer, static_cast<std::size_t>(n));
    }

    // What arrives until `marker` has come, within the deadline (a failure if it does not).
    std::string receive_until(const std::string& marker) {
        std::string all;
        const auto give_up = std::chrono::steady_clock::now() + deadline;
        while (all.find(marker) == std::string::npos && std::chrono::steady_clock::now() < give_up) {
            auto some = receive(100ms);
            if (!some) break;
            all += *some;
        }
        if (all.find(marker) == std::string::npos) ADD_FAILURE() << "\"" << marker << "\" did not come; got:\n" << all;
        return all;
    }

    // Everything until the server closes (the requests below ask it to), within the deadline.
    std::string receive_all() {
        std::string all;
        const auto give_up = std::chrono::steady_clock::now() + deadline;
        while (std::chrono::steady_clock::now() < give_up) {
            auto some = receive(100ms);
            if (!some) return all;
            all += *some;
        }
        ADD_FAILURE() << "the server did not close the connection within " << deadline.count() << " s; got:\n" << all;
        return all;
    }

private:
    int fd_;
};

struct Reply {
    unsigned status = 0;
    std::map<std::string, std::string> headers;  // names in lower case
    std::string body;

    Json json() const {
        auto parsed = Json::parse(body, nullptr, false);
        EXPECT_FALSE(parsed.is_discarded()) << "not JSON: " << body;
        return parsed;
    }
    std::string header(const std::string& name) const {
        auto it = headers.find(name);
        return it == headers.end() ? std::string() : it->second;
    }
};

Reply parse_reply(const std::string& raw) {
    Reply reply;
    const auto end = raw.find("\r\n\r\n");
    if (end == std::string::npos || raw.size() < 12) {
        ADD_FAILURE() << "not an HTTP response: " << raw;
        return reply;
    }
    reply.status = static_cast<unsigned>(std::stoul(raw.substr(9, 3)));
    std::size_t at = raw.find("\r\n") + 2;
    while (at < end) {
        const auto line_end = raw.find("\r\n", at);
        const std::string line = raw.substr(at, line_end - at);
        const auto colon = line.find(':');
        std::string name = line.substr(0, colon);
        for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        reply.headers[name] = line.substr(line.find_first_not_of(' ', colon + 1));
        at = line_end + 2;
    }
    reply.body = raw.substr(end + 4);
    return reply;
}

// `host`: the Host header's value; empty sends none.
Reply request_to_host(std::uint16_t port, const std::string& host, const std::string& method, const std::string& target,
                      const std::string& body = {}, const std::vector<std::string>& headers = {}) {
    Socket socket(port);
    std::string text = fmt::format("{} {} HTTP/1.1\r\n{}Connection: close\r\n", method, target,
                                   host.empty() ? std::string() : "Host: " + host + "\r\n");
    for (const auto& header : headers) text += header + "\r\n";
    if (!body.empty() || method == "POST") text += fmt::format("Content-Type: application/json\r\nContent-Length: {}\r\n", body.size());
    text += "\r\n" + body;
    socket.send(text);
    return parse_reply(socket.receive_all());
}

Reply request(std::uint16_t port, const std::string& method, const std::string& target, const std::string& body = {},
              const std::vector<std::string>& headers = {}) {
    return request_to_host(port, "127.0.0.1", method, target, body, headers);
}

Reply get(std::uint16_t port, const std::string& target) { return request(port, "GET", target); }

Reply post_write(std::uint16_t port, const std::string& device, const std::string& body, const std::string& with_token = token) {
    std::vector<std::string> headers;
    if (!with_token.empty()) headers.push_back("Authorization: Bearer " + with_token);
    return request(port, "POST", "/api/devices/" + device + "/write", body, headers);
}

// --- the gateway ----------------------------------------------------------------------------

class TokenFile {
public:
    explicit TokenFile(const std::string& content, fs::perms perms = fs::perms::owner_read | fs::perms::owner_write) {
        std::string pattern = (fs::temp_directory_path() / "loopwire-http-XXXXXX").string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp");
        directory_ = pattern;
        std::ofstream(directory_ / "token") << content << "\n";
        fs::permissions(path(), perms);
    }
    ~TokenFile() {
        std::error_code ignored;
        fs::remove_all(directory_, ignored);
    }
    fs::path path() const { return directory_ / "token"; }

private:
    fs::path directory_;
};

std::unique_ptr<Gateway> open_gateway(const std::string& http_table) {
    const std::string text = R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"
retries = 1

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "100ms"
parameters = ["measured_value", "set_point", "set_point_low_limit", "set_point_high_limit"]

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "200ms"

[modbus_tcp]
enabled = false

)toml" + http_table;
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    if (!config) throw std::runtime_error(config.error().message);
    auto gateway = Gateway::open(*config);
    if (!gateway) throw std::runtime_error(gateway.error().message);
    return std::move(*gateway);
}

class HttpApiTest : public ::testing::Test {
protected:
    HttpApiTest()
        : gateway_(open_gateway(fmt::format("[http]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\nread_timeout = \"1s\"\n"
                                            "hosts = [\"Gateway.Plant.Local\", \"192.168.1.10\"]\n",
                                            token_file_.path().string()))),
          port_(gateway_->http_port()) {}

    // Asks until `done` holds for the reply (the polls take a moment to find values).
    Reply get_until(const std::string& target, const std::function<bool(const Reply&)>& done) {
        Reply reply;
        const auto answered = [&] {
            reply = get(port_, target);
            return done(reply);
        };
        if (!eventually(answered, deadline, 50ms)) {
            ADD_FAILURE() << "GET " << target << " never gave what was waited for; last: " << reply.status << " " << reply.body;
        }
        return reply;
    }

    // Until the oven's set point reads `value` in GET /api/devices/oven (a poll after a write).
    void wait_for_oven_set_point(double value) {
        get_until("/api/devices/oven", [value](const Reply& r) {
            auto device = Json::parse(r.body, nullptr, false);
            if (device.is_discarded() || !device.contains("parameters")) return false;
            for (const auto& p : device.at("parameters")) {
                if (p.at("name") == "set_point") return p.at("value") == value;
            }
            return false;
        });
    }

    static Json parameter(const Json& device, const std::string& name) {
        for (const auto& p : device.at("parameters")) {
            if (p.at("name") == name) return p;
        }
        ADD_FAILURE() << "no parameter " << name;
        return Json::object();
    }

    TokenFile token_file_{token};
    std::unique_ptr<Gateway> gateway_;
    std::uint16_t port_;
};

TEST_F(HttpApiTest, ListsTheDevicesWithProfileLineUnitAndStatus) {
    ASSERT_NE(port_, 0);
    const Reply reply = get_until("/api/devices", [](const Reply& r) {
        auto list = Json::parse(r.body, nullptr, false);
        return r.status == 200 && list.is_array() && list.size() == 2 && list[0].value("status", "") == "ok";
    });
    EXPECT_THAT(reply.header("content-type"), HasSubstr("application/json"));
    const Json list = reply.json();
    ASSERT_EQ(list.size(), 2u);
    EXPECT_EQ(list[0].at("name"), "oven");
    EXPECT_EQ(list[0].at("device"), "tc10");
    EXPECT_EQ(list[0].at("line"), "sim");
    EXPECT_EQ(list[0].at("unit"), 3);
    EXPECT_EQ(list[1].at("name"), "furnace");
    EXPECT_EQ(list[1].at("device"), "ac20");
    EXPECT_EQ(list[1].at("unit"), 1);
}

TEST_F(HttpApiTest, ADeviceShowsItsParametersWithValuesUnitsRangesAndGroups) {
    const Reply reply = get_until("/api/devices/oven", [](const Reply& r) {
        auto device = Json::parse(r.body, nullptr, false);
        if (r.status != 200 || device.is_discarded()) return false;
        for (const auto& p : device.at("parameters")) {
            if (p.at("name") == "measured_value") return p.at("value").is_number();
        }
        return false;
    });
    const Json device = reply.json();
    EXPECT_EQ(device.at("name"), "oven");
    EXPECT_EQ(device.at("device"), "tc10");
    EXPECT_EQ(device.at("status"), "ok");
    EXPECT_FALSE(device.at("groups").empty());
    const Json measured = parameter(device, "measured_value");
    EXPECT_EQ(measured.at("status"), "ok");
    EXPECT_EQ(measured.at("writable"), false);
    EXPECT_TRUE(measured.at("polled").get<bool>());
    EXPECT_FALSE(measured.at("text").get<std::string>().empty());
    EXPECT_TRUE(measured.at("age").is_number());
    EXPECT_LT(measured.at("age").get<double>(), 10.0);
    EXPECT_TRUE(measured.contains("unit"));
    EXPECT_TRUE(measured.contains("mnemonic"));
    EXPECT_TRUE(measured.contains("group"));
    // The unit its temperature_unit word gives, as the events and MQTT say it.
    EXPECT_EQ(measured.at("unit"), "°C");
    const Json set_point = parameter(device, "set_point");
    EXPECT_EQ(set_point.at("writable"), true);
    EXPECT_EQ(set_point.at("unit"), "°C");
    // Bounded by SP.LL and SP.HL: numbers when the gateway polls them, else their names.
    const Json high_limit = parameter(device, "set_point_high_limit");
    ASSERT_TRUE(high_limit.at("value").is_number()) << high_limit;
    EXPECT_EQ(set_point.at("max"), high_limit.at("value"));
    EXPECT_EQ(set_point.at("min"), parameter(device, "set_point_low_limit").at("value"));
    // A bound word neither polled nor bounding a polled value is not read: its name stays.
    EXPECT_EQ(parameter(device, "alarm_1_threshold").at("max").at("parameter"), "alarm_1_high_limit");
    // Display counts scaled by the decimal point the polls read (dP 0 on the simulated TC10).
    const Json band = parameter(device, "proportional_band");
    EXPECT_EQ(band.at("max"), 9999.0) << band;
    EXPECT_FALSE(band.contains("range_counts")) << "scaled, yet said to be in counts: " << band;
    EXPECT_TRUE(set_point.contains("decimals"));
    // Parameters not polled are listed too, to be written, without a value.
    bool unpolled = false;
    for (const auto& p : device.at("parameters")) {
        if (!p.at("polled").get<bool>()) {
            unpolled = true;
            EXPECT_TRUE(p.at("value").is_null()) << p;
            EXPECT_EQ(p.at("status"), "not-polled") << p;
        }
    }
    EXPECT_TRUE(unpolled);

    const Reply unknown = get(port_, "/api/devices/kiln");
    EXPECT_EQ(unknown.status, 404u);
    EXPECT_THAT(unknown.json().at("error").get<std::string>(), HasSubstr("no device \"kiln\""));
}

TEST_F(HttpApiTest, AWriteWithTheTokenReachesTheDevice) {
    const Reply written = post_write(port_, "oven", R"({"set_point": "200"})");
    ASSERT_EQ(written.status, 200u) << written.body;
    EXPECT_EQ(written.json(), Json::parse(R"({"written": {"set_point": "200"}})"));
    wait_for_oven_set_point(200.0);
}

// Node-RED and scripts send numbers: 210 is written as "210" would be, and a number the
// parameter cannot take is refused by the profile's checks as its text would be.
TEST_F(HttpApiTest, AWriteTakesJsonNumbersAsWellAsText) {
    const Reply written = post_write(port_, "oven", R"({"set_point": 210})");
    ASSERT_EQ(written.status, 200u) << written.body;
    EXPECT_EQ(written.json(), Json::parse(R"({"written": {"set_point": "210"}})"));
    wait_for_oven_set_point(210.0);
    const Reply out_of_range = post_write(port_, "oven", R"({"set_point": 99999})");
    EXPECT_EQ(out_of_range.status, 422u) << out_of_range.body;
    const Reply fraction = post_write(port_, "oven", R"({"set_point": 200.123456})");
    EXPECT_EQ(fraction.status, 422u) << fraction.body;
    // Numbers JSON writes with an exponent are read as their digits, and refused for what is
    // wrong with them, never as "not a number".
    for (const char* body : {R"({"set_point": 1e308})", R"({"set_point": 1e21})", R"({"set_point": 18446744073709551616})",
                             R"({"set_point": 0.00000001})"}) {
        const Reply refused = post_write(port_, "oven", body);
        EXPECT_EQ(refused.status, 422u) << body << ": " << refused.body;
        EXPECT_THAT(refused.body, Not(HasSubstr("not a number"))) << body;
    }
    const Reply tiny = post_write(port_, "oven", R"({"set_point": 0.00000001})");
    EXPECT_THAT(tiny.body, HasSubstr("0.00000001 has 8 decimals"));
}

TEST_F(HttpApiTest, WritesWithoutTheRightTokenAreRefused) {
    const Reply none = post_write(port_, "oven", R"({"set_point": "200"})", "");
    EXPECT_EQ(none.status, 401u);
    EXPECT_THAT(none.json().at("error").get<std::string>(), HasSubstr("Authorization: Bearer"));
    EXPECT_EQ(none.header("www-authenticate"), "Bearer");
    const Reply wrong = post_write(port_, "oven", R"({"set_point": "200"})", "not-the-token");
    EXPECT_EQ(wrong.status, 401u);
    EXPECT_THAT(wrong.json().at("error").get<std::string>(), HasSubstr("wrong token"));
}

TEST_F(HttpApiTest, WritesTheDeviceWouldRefuseAreRefusedInWords) {
    const Reply range = post_write(port_, "oven", R"({"set_point": "99999"})");
    EXPECT_EQ(range.status, 422u) << range.body;
    EXPECT_FALSE(range.json().at("error").get<std::string>().empty());
    const Reply read_only = post_write(port_, "oven", R"({"measured_value": "1"})");
    EXPECT_EQ(read_only.status, 422u) << read_only.body;
    const Reply unknown = post_write(port_, "oven", R"({"no_such_parameter": "1"})");
    EXPECT_EQ(unknown.status, 422u) << unknown.body;
    // The AC20 starts in local mode and takes its set point only in remote (AC20 manual, Note 5).
    const Reply mode = post_write(port_, "furnace", R"({"main_set_point": "1.00"})");
    EXPECT_EQ(mode.status, 409u) << mode.body;
    EXPECT_THAT(mode.json().at("error").get<std::string>(), HasSubstr("remote"));
    const Reply no_device = post_write(port_, "kiln", R"({"set_point": "1"})");
    EXPECT_EQ(no_device.status, 404u) << no_device.body;
}

TEST_F(HttpApiTest, MalformedAndOversizedBodiesAreRefused) {
    const Reply not_json = post_write(port_, "oven", R"({"set_point": )");
    EXPECT_EQ(not_json.status, 400u);
    EXPECT_THAT(not_json.json().at("error").get<std::string>(), HasSubstr("not JSON"));
    const Reply boolean = post_write(port_, "oven", R"({"set_point": true})");
    EXPECT_EQ(boolean.status, 400u);
    EXPECT_EQ(boolean.json().at("error").get<std::string>(),
              "the value of \"set_point\": expected a number or a string as it would be typed (150, \"on\"), not boolean");
    const Reply nested = post_write(port_, "oven", R"({"set_point": {"value": 200}})");
    EXPECT_EQ(nested.status, 400u);
    EXPECT_THAT(nested.json().at("error").get<std::string>(), HasSubstr("not object"));
    EXPECT_EQ(post_write(port_, "oven", R"(["set_point", "200"])").status, 400u);
    EXPECT_EQ(post_write(port_, "oven", "{}").status, 400u);
    const Reply large = post_write(port_, "oven", R"({"set_point": ")" + std::string(70000, '1') + "\"}");
    EXPECT_EQ(large.status, 413u);
    EXPECT_THAT(large.json().at("error").get<std::string>(), HasSubstr("larger than"));
    // The gateway goes on answering.
    EXPECT_EQ(get(port_, "/api/devices").status, 200u);
}

TEST_F(HttpApiTest, MethodsAndPathsOutsideTheApiAreRefused) {
    for (const char* method : {"DELETE", "OPTIONS", "PUT"}) {
        const Reply reply = request(port_, method, "/api/devices");
        EXPECT_EQ(reply.status, 405u) << method;
        EXPECT_EQ(reply.header("allow"), "GET, HEAD") << method;
    }
    EXPECT_EQ(request(port_, "GET", "/api/devices/oven/write").status, 405u);
    EXPECT_EQ(request(port_, "GET", "/api/devices/oven/write").header("allow"), "POST");
    const Reply unknown = get(port_, "/api/nothing");
    EXPECT_EQ(unknown.status, 404u);
    EXPECT_THAT(unknown.json().at("error").get<std::string>(), HasSubstr("no such resource"));
    Socket garbage(port_);
    garbage.send("NOT HTTP AT ALL\r\n\r\n");
    EXPECT_EQ(parse_reply(garbage.receive_all()).status, 400u);
}

TEST_F(HttpApiTest, TheDashboardIsServedWithItsTypeAndETag) {
    const Reply page = get(port_, "/");
    ASSERT_EQ(page.status, 200u);
    EXPECT_EQ(page.header("content-type"), "text/html; charset=utf-8");
    EXPECT_THAT(page.body, HasSubstr("<html"));
    const std::string etag = page.header("etag");
    ASSERT_FALSE(etag.empty());
    EXPECT_EQ(page.header("cache-control"), "no-cache");
    const Reply again = request(port_, "GET", "/", {}, {"If-None-Match: " + etag});
    EXPECT_EQ(again.status, 304u);
    EXPECT_TRUE(again.body.empty());
    EXPECT_EQ(get(port_, "/assets/nothing.js").status, 404u);
}

TEST_F(HttpApiTest, AStalledClientIsClosedWithoutHoldingUpOthers) {
    Socket stalled(port_);
    stalled.send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n");  // and no more
    const auto before = std::chrono::steady_clock::now();
    EXPECT_EQ(get(port_, "/api/devices").status, 200u);
    EXPECT_LT(std::chrono::steady_clock::now() - before, 5s);
    // read_timeout = "1s": closed after it, with nothing sent.
    std::optional<std::string> received = std::string();
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    while (received && received->empty() && std::chrono::steady_clock::now() < give_up) received = stalled.receive(100ms);
    EXPECT_FALSE(received) << "the stalled connection was not closed";
    EXPECT_GT(std::chrono::steady_clock::now() - before, 900ms);
}

TEST_F(HttpApiTest, OnlyTheGatewaysOwnHostNamesAreAnswered) {
    // A page of another site that points its name at this address (DNS rebinding) sends its
    // own name: refused, saying which names are answered and how to add one.
    const Reply evil = request_to_host(port_, "evil.example", "GET", "/api/devices");
    EXPECT_EQ(evil.status, 421u) << evil.body;
    const std::string message = evil.json().at("error").get<std::string>();
    EXPECT_THAT(message, HasSubstr("\"evil.example\""));
    EXPECT_THAT(message, HasSubstr("localhost, 127.0.0.1, [::1]"));
    EXPECT_THAT(message, HasSubstr("[http] hosts"));
    EXPECT_EQ(request_to_host(port_, fmt::format("evil.example:{}", port_), "GET", "/").status, 421u);
    EXPECT_EQ(request_to_host(port_, "127.0.0.1.evil.example", "GET", "/metrics").status, 421u);
    // Not even with the token: the rebinding page cannot have it, but nothing is written either way.
    const Reply write = request_to_host(port_, "evil.example", "POST", "/api/devices/oven/write", R"({"set_point": "201"})",
                                        {"Authorization: Bearer " + token});
    EXPECT_EQ(write.status, 421u);

    // The listen address with its port, the loopback names, and the names of [http] hosts, in
    // any case, with or without a port.
    for (const std::string& host : {fmt::format("127.0.0.1:{}", port_), std::string("127.0.0.1"), std::string("localhost"),
                                   fmt::format("LocalHost:{}", port_), fmt::format("[::1]:{}", port_),
                                   std::string("gateway.plant.local"), std::string("GATEWAY.plant.local:8080"),
                                   std::string("192.168.1.10")}) {
        EXPECT_EQ(request_to_host(port_, host, "GET", "/api/devices").status, 200u) << "Host: " << host;
    }
    // Malformed, or none at all (HTTP/1.1 requires it).
    EXPECT_EQ(request_to_host(port_, "localhost:http", "GET", "/api/devices").status, 421u);
    const Reply none = request_to_host(port_, "", "GET", "/api/devices");
    EXPECT_EQ(none.status, 400u);
    EXPECT_THAT(none.json().at("error").get<std::string>(), HasSubstr("no Host header"));
}

TEST_F(HttpApiTest, TextAClientSentIsEscapedInTheAnswer) {
    // A name in the path that is not UTF-8, and a JSON key of the body: echoed in the error as
    // valid JSON, not thrown on.
    const Reply path = get(port_, "/api/devices/%FF%FE");
    EXPECT_EQ(path.status, 404u);
    EXPECT_FALSE(Json::parse(path.body, nullptr, false).is_discarded()) << path.body;
    const Reply body = post_write(port_, "oven", R"({"set\u0000point\u001b[2J": true})");
    EXPECT_EQ(body.status, 400u);
    EXPECT_FALSE(Json::parse(body.body, nullptr, false).is_discarded()) << body.body;
}

// Reads server-sent events until one satisfies `wanted`.
std::optional<Json> next_event(Socket& stream, std::string& buffer, const std::function<bool(const Json&)>& wanted) {
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    while (std::chrono::steady_clock::now() < give_up) {
        for (auto end = buffer.find("\n\n"); end != std::string::npos; end = buffer.find("\n\n")) {
            const std::string event = buffer.substr(0, end);
            buffer.erase(0, end + 2);
            if (event.rfind("data: ", 0) != 0) continue;
            auto json = Json::parse(event.substr(6), nullptr, false);
            EXPECT_FALSE(json.is_discarded()) << event;
            if (!json.is_discarded() && wanted(json)) return json;
        }
        auto some = stream.receive(100ms);
        if (!some) return std::nullopt;
        buffer += *some;
    }
    return std::nullopt;
}

TEST_F(HttpApiTest, TheEventStreamGivesTheFullPictureThenAWritesChange) {
    Socket stream(port_);
    stream.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept: text/event-stream\r\n\r\n");
    std::string buffer;
    const auto first = stream.receive(deadline);
    ASSERT_TRUE(first && !first->empty());
    buffer = *first;
    const auto headers_end = buffer.find("\r\n\r\n");
    ASSERT_NE(headers_end, std::string::npos);
    const Reply head = parse_reply(buffer.substr(0, headers_end + 4));
    EXPECT_EQ(head.status, 200u);
    EXPECT_EQ(head.header("content-type"), "text/event-stream");
    buffer.erase(0, headers_end + 4);

    const auto set_point = next_event(stream, buffer, [](const Json& e) {
        return e.at("device") == "oven" && e.at("parameter") == "set_point" && e.at("value").is_number();
    });
    ASSERT_TRUE(set_point) << "no set_point in the stream";
    for (const char* key : {"device", "parameter", "value", "text", "unit", "status", "error", "time"}) {
        EXPECT_TRUE(set_point->contains(key)) << key << " in " << *set_point;
    }
    const double before = set_point->at("value").get<double>();
    const std::string target = before == 180.0 ? "170" : "180";
    ASSERT_EQ(post_write(port_, "oven", fmt::format(R"({{"set_point": "{}"}})", target)).status, 200u);
    const auto changed = next_event(stream, buffer, [&](const Json& e) {
        return e.at("device") == "oven" && e.at("parameter") == "set_point" && e.at("value") == std::stod(target);
    });
    ASSERT_TRUE(changed) << "the write's change did not come through the stream";
    EXPECT_EQ(changed->at("status"), "ok");
    EXPECT_THAT(changed->at("time").get<std::string>(), ::testing::EndsWith("Z"));
}

TEST_F(HttpApiTest, MetricsAreInPrometheusTextFormat) {
    const Reply metrics = get_until("/metrics", [](const Reply& r) {
        return r.body.find("loopwire_device_status{device=\"oven\",status=\"ok\"} 1") != std::string::npos;
    });
    EXPECT_THAT(metrics.header("content-type"), HasSubstr("text/plain; version=0.0.4"));
    EXPECT_THAT(metrics.body, HasSubstr("loopwire_line_requests_total{line=\"sim\"}"));
    EXPECT_THAT(metrics.body, HasSubstr("# TYPE loopwire_line_busy_ratio gauge"));
    // The process values themselves, each in its unit, with its age.
    EXPECT_THAT(metrics.body, HasSubstr("loopwire_value{device=\"oven\",parameter=\"measured_value\",unit=\"°C\"} "));
    EXPECT_THAT(metrics.body, HasSubstr("loopwire_value_age_seconds{device=\"oven\",parameter=\"measured_value\",unit=\"°C\"} "));
    // Read by the Prometheus client library's own parser, which refuses what is not the format.
    const fs::path file = fs::temp_directory_path() / fmt::format("loopwire-metrics-{}.txt", ::getpid());
    std::ofstream(file) << metrics.body;
    const std::string check = fmt::format(
        "/usr/bin/python3 -c 'import sys\n"
        "try:\n from prometheus_client.parser import text_string_to_metric_families\n"
        "except ImportError:\n sys.exit(77)\n"
        "families = {{f.name: f for f in text_string_to_metric_families(open(sys.argv[1]).read())}}\n"
        "assert families[\"loopwire_line_requests\"].type == \"counter\", families.keys()\n"
        "assert any(s.value > 0 for s in families[\"loopwire_line_requests\"].samples)\n"
        "statuses = [s for s in families[\"loopwire_device_status\"].samples if s.value == 1]\n"
        "assert len(statuses) == 2, statuses\n"
        "assert families[\"loopwire_line_busy_ratio\"].type == \"gauge\"\n"
        "assert any(s.labels[\"parameter\"] == \"measured_value\" for s in families[\"loopwire_value\"].samples)\n' {}",
        file.string());
    const int status = std::system(check.c_str());
    fs::remove(file);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 77) GTEST_SKIP() << "python3-prometheus-client is not installed";
    EXPECT_EQ(status, 0) << "Prometheus's parser refused /metrics:\n" << metrics.body;
}

TEST_F(HttpApiTest, WithoutHistoryTheHistoryRouteSaysSo) {
    const Reply reply = get(port_, "/api/history?device=oven");
    EXPECT_EQ(reply.status, 404u);
    EXPECT_THAT(reply.json().at("error").get<std::string>(), HasSubstr("no [history] configured"));
}

TEST(HttpApiWithoutToken, WritesAreRefusedSayingHowToEnableThem) {
    auto gateway = open_gateway("[http]\nlisten = \"127.0.0.1:0\"\n");
    const Reply reply = post_write(gateway->http_port(), "oven", R"({"set_point": "200"})");
    EXPECT_EQ(reply.status, 403u);
    EXPECT_THAT(reply.json().at("error").get<std::string>(), HasSubstr("token_file"));
    EXPECT_EQ(get(gateway->http_port(), "/api/devices").status, 200u);  // reads on loopback need none
}

// Two lines: the oven on one, the kiln (unit 4) on the other, which the test can silence.
std::unique_ptr<Gateway> open_two_lines(const std::string& token_path, support::SilencedUnit& kiln) {
    const std::string text = fmt::format(R"toml(
[[lines]]
name = "fast"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "100ms"
parameters = ["measured_value", "set_point"]

[[lines]]
name = "slow"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "4s"
retries = 0

[[lines.devices]]
name = "kiln"
device = "tc10@4"
poll = "150ms"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
token_file = "{}"
)toml", token_path);
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    if (!config) throw std::runtime_error(config.error().message);
    GatewayOptions options;
    options.virtual_bus_faults = kiln.injector();
    auto gateway = Gateway::open(*config, std::move(options));
    if (!gateway) throw std::runtime_error(gateway.error().message);
    return std::move(*gateway);
}

TEST(HttpApiLines, AWriteToOneLineIsAnsweredWhileAnotherLineHoldsItsWrites) {
    TokenFile token_file(token);
    support::SilencedUnit kiln(4);
    auto gateway = open_two_lines(token_file.path().string(), kiln);
    const std::uint16_t port = gateway->http_port();
    const auto status_of = [port](const std::string& device) {
        const Reply reply = get(port, "/api/devices/" + device);
        return reply.status == 200 ? Json::parse(reply.body, nullptr, false).value("status", "") : std::string();
    };
    ASSERT_TRUE(eventually([&] { return status_of("oven") == "ok" && status_of("kiln") == "ok"; })) << "never read both";

    // The kiln stops answering: its line waits out 4 s for each request; four writes wait for
    // it, more than any pool of workers shared by the lines would have.
    kiln.silence();
    std::vector<std::unique_ptr<Socket>> kiln_writes;
    for (int i = 0; i < 4; ++i) {
        kiln_writes.push_back(std::make_unique<Socket>(port));
        const std::string body = fmt::format(R"({{"set_point": "{}"}})", 100 + i);
        kiln_writes.back()->send(fmt::format("POST /api/devices/kiln/write HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n"
                                             "Authorization: Bearer {}\r\nContent-Type: application/json\r\n"
                                             "Content-Length: {}\r\n\r\n{}", token, body.size(), body));
    }
    ASSERT_TRUE(eventually([&] { return kiln.lost() > 0; })) << "nothing of the kiln's reached its line";

    // A write to the oven's line goes through all the same, while the kiln's wait.
    const Reply oven = post_write(port, "oven", R"({"set_point": "190"})");
    EXPECT_EQ(oven.status, 200u) << oven.body;
    for (auto& write : kiln_writes) EXPECT_EQ(write->receive(0ms), std::string()) << "a kiln write was answered while its line waited";

    // Answering again, every kiln write is answered (written, or given up for the time it waited).
    kiln.answer_again();
    for (auto& write : kiln_writes) {
        const std::string answer = write->receive_all();
        EXPECT_EQ(answer.rfind("HTTP/1.1 ", 0), 0u) << answer;
    }
}

TEST(HttpApiWithoutHttp, AGatewayWithoutAnHttpTableListensOnNoPort) {
    auto gateway = open_gateway("");
    EXPECT_EQ(gateway->http_port(), 0);
}

// --- history, against a source that records the question ------------------------------------

class RecordingHistory final : public HistorySource {
public:
    ~RecordingHistory() override {
        release();
        for (auto& worker : workers_) worker.join();
    }

    // As the store does: the query on a thread of the history's, not the caller's.
    void run_blocking(std::function<void()> work) const override {
        std::lock_guard lock(mutex_);
        workers_.emplace_back(std::move(work));
    }

    Result<std::vector<HistorySeries>> query(const HistoryQuery& query) const override {
        std::unique_lock lock(mutex_);
        asked_.push_back(query);
        changed_.notify_all();
        // A query the database takes its time over (a month of rows, a slow historian).
        changed_.wait(lock, [this] { return !holding_; });
        if (!query.parameters.empty() && query.parameters.front() == "nonsense") {
            return make_error(ErrorKind::usage, "device \"oven\" has no parameter \"nonsense\"");
        }
        if (query.gateway == "down") return make_error(ErrorKind::link, "postgresql postgres@db:5432/plant: cannot connect");
        if (query.gateway == "slow") return make_error(ErrorKind::timeout, "postgresql postgres@db:5432/plant: no answer within");
        const auto start = query.from;
        HistorySeries series{"measured_value", "°C", {}, {}};
        series.buckets.push_back({start, 20.5, 22.0, 21.25, 4});
        series.buckets.push_back({start + std::chrono::seconds(60), 22.0, 25.5, 23.0, 3});
        series.gaps.push_back({start + std::chrono::seconds(90), start + std::chrono::seconds(150)});
        series.gaps.push_back({start + std::chrono::seconds(170), std::nullopt});
        // The value in force at `from`, recorded 40 s before it; none known of another gateway's.
        if (query.gateway.empty()) series.before = HistoryBefore{start - std::chrono::seconds(40), 19.5};
        return std::vector<HistorySeries>{series};
    }
    std::uint64_t rows_written() const override { return 1234; }
    // No historian unless the test sets its gateways; "down" stands for one that is unreachable.
    Result<std::vector<std::string>> historian_gateways() const override {
        std::lock_guard lock(mutex_);
        if (!gateways_) return HistorySource::historian_gateways();
        if (*gateways_ == std::vector<std::string>{"down"}) return make_error(ErrorKind::link, "postgresql: cannot connect");
        return *gateways_;
    }
    void set_gateways(std::vector<std::string> names) {
        std::lock_guard lock(mutex_);
        gateways_ = std::move(names);
    }

    std::vector<HistoryQuery> asked() const {
        std::lock_guard lock(mutex_);
        return asked_;
    }

    void hold() {
        std::lock_guard lock(mutex_);
        holding_ = true;
    }
    void release() {
        std::lock_guard lock(mutex_);
        holding_ = false;
        changed_.notify_all();
    }
    // Fails loudly when no query was asked within 30 s.
    bool wait_until_asked(std::size_t count) const {
        std::unique_lock lock(mutex_);
        return changed_.wait_for(lock, 30s, [&] { return asked_.size() >= count; });
    }

private:
    mutable std::mutex mutex_;
    mutable std::condition_variable changed_;
    mutable std::vector<std::thread> workers_;
    bool holding_ = false;
    mutable std::vector<HistoryQuery> asked_;
    std::optional<std::vector<std::string>> gateways_;
};

class HttpHistoryTest : public ::testing::Test {
protected:
    HttpHistoryTest() {
        auto config = parse_gateway_config(R"toml(
[gateway]
name = "north"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"
)toml", "plant.toml", profiles());
        if (!config) throw std::runtime_error(config.error().message);
        HttpApiSources sources;
        sources.cache = &cache_;
        sources.writer = &writer_;
        sources.lines = [] { return std::vector<LineReport>{}; };
        sources.history = &history_;
        api_ = std::make_unique<HttpApi>(*config, std::move(sources));
        // As in the gateway: on the engine's loop, the polls' (gateway.cpp).
        auto server = HttpServer::open(HttpServerSettings{}, *api_, &engine_.loop());
        if (!server) throw std::runtime_error(server.error().message);
        server_ = std::move(*server);
    }

    ValueCache cache_;
    RecordingHistory history_;  // before the engine: its queries' answers are posted to the loop
    Engine engine_;
    DeviceWriter writer_{engine_, {}, 1s};
    std::unique_ptr<HttpApi> api_;
    std::unique_ptr<HttpServer> server_;
};

TEST_F(HttpHistoryTest, TheQueryIsPassedOnAndTheSeriesComeBackAsJson) {
    const Reply reply = get(server_->port(), "/api/history?device=oven&parameters=measured_value,set_point"
                                             "&from=2026-12-02T08:00:00Z&to=2026-12-02T09:30:00%2B01:00&points=60");
    ASSERT_EQ(reply.status, 200u) << reply.body;
    const auto asked = history_.asked();
    ASSERT_EQ(asked.size(), 1u);
    EXPECT_EQ(asked[0].device, "oven");
    EXPECT_EQ(asked[0].parameters, (std::vector<std::string>{"measured_value", "set_point"}));
    EXPECT_EQ(asked[0].points, 60u);
    EXPECT_EQ(asked[0].to - asked[0].from, std::chrono::minutes(30));  // 09:30+01:00 is 08:30Z
    const Json json = reply.json();
    EXPECT_EQ(json.at("from"), "2026-12-02T08:00:00.000Z");
    EXPECT_EQ(json.at("to"), "2026-12-02T08:30:00.000Z");
    ASSERT_EQ(json.at("series").size(), 1u);
    const Json& series = json.at("series")[0];
    EXPECT_EQ(series.at("parameter"), "measured_value");
    EXPECT_EQ(series.at("unit"), "°C");
    ASSERT_EQ(series.at("buckets").size(), 2u);
    EXPECT_EQ(series.at("buckets")[1], Json::parse(R"({"time": "2026-12-02T08:01:00.000Z", "min": 22.0, "max": 25.5,
                                                       "mean": 23.0, "count": 3})"));
    // The times without a value, for a chart to break its line there; one that lasts has no end.
    EXPECT_EQ(series.at("gaps"), Json::parse(R"([{"from": "2026-12-02T08:01:30.000Z", "to": "2026-12-02T08:02:30.000Z"},
                                                 {"from": "2026-12-02T08:02:50.000Z", "to": null}])"));
    // The value in force at `from`, where a chart's line starts: no bucket, so no statistics.
    EXPECT_EQ(series.at("before"), Json::parse(R"({"time": "2026-12-02T07:59:20.000Z", "value": 19.5})"));
}

// The server runs on the engine's loop, with the polls: a query is answered from the history's
// thread (HistorySource::run_blocking), so one the database takes its time over holds up neither
// the loop nor the other clients. Asked on the loop, the query held both until it was done.
TEST_F(HttpHistoryTest, AQueryTakingItsTimeHoldsUpNeitherTheLoopNorOtherClients) {
    history_.hold();
    auto slow = std::async(std::launch::async, [this] { return get(server_->port(), "/api/history?device=oven"); });
    ASSERT_TRUE(history_.wait_until_asked(1)) << "the history was never asked";
    std::promise<void> ran;
    engine_.post([&ran] { ran.set_value(); });
    EXPECT_EQ(ran.get_future().wait_for(30s), std::future_status::ready) << "the engine's loop is held by the query";
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
    EXPECT_EQ(slow.wait_for(0s), std::future_status::timeout) << "answered before the query was done";
    history_.release();
    const Reply reply = slow.get();
    EXPECT_EQ(reply.status, 200u) << reply.body;
    EXPECT_EQ(reply.json().at("series").size(), 1u);
}

// No value known to hold at `from` (none recorded shortly before it, or a row of nothing read):
// `before` is null, and the line starts at the first bucket.
TEST_F(HttpHistoryTest, NoValueInForceAtFromIsNull) {
    const Reply reply = get(server_->port(), "/api/history?device=kiln&gateway=south&from=2026-12-02T08:00:00Z&to=2026-12-02T09:00:00Z");
    ASSERT_EQ(reply.status, 200u) << reply.body;
    const Json json = reply.json();
    const Json& series = json.at("series")[0];
    ASSERT_TRUE(series.contains("before"));
    EXPECT_TRUE(series.at("before").is_null());
    EXPECT_EQ(series.at("buckets").size(), 2u);
}

// The CSV says what the JSON says, in rows in time order: the value in force at `from` (no
// bucket: no count), the buckets, and the gaps with their ends (none while one lasts).
TEST_F(HttpHistoryTest, CsvHasAHeaderAndARowABucketGapAndTheValueInForceAtFrom) {
    const Reply reply = get(server_->port(), "/api/history?device=oven&from=2026-12-02T08:00:00.5Z&to=2026-12-02T09:00:00Z&format=csv");
    ASSERT_EQ(reply.status, 200u) << reply.body;
    EXPECT_EQ(reply.header("content-type"), "text/csv; charset=utf-8");
    EXPECT_EQ(reply.body,
              "parameter,unit,time,min,max,mean,count,kind,until\r\n"
              "measured_value,°C,2026-12-02T07:59:20.500Z,19.5,19.5,19.5,,before,\r\n"
              "measured_value,°C,2026-12-02T08:00:00.500Z,20.5,22,21.25,4,bucket,\r\n"
              "measured_value,°C,2026-12-02T08:01:00.500Z,22,25.5,23,3,bucket,\r\n"
              "measured_value,°C,2026-12-02T08:01:30.500Z,,,,,gap,2026-12-02T08:02:30.500Z\r\n"
              "measured_value,°C,2026-12-02T08:02:50.500Z,,,,,gap,\r\n");
}

TEST_F(HttpHistoryTest, DefaultsAreTheLastHourAndFiveHundredPoints) {
    ASSERT_EQ(get(server_->port(), "/api/history?device=oven").status, 200u);
    const auto asked = history_.asked();
    ASSERT_EQ(asked.size(), 1u);
    EXPECT_EQ(asked[0].to - asked[0].from, std::chrono::hours(1));
    EXPECT_EQ(asked[0].points, 500u);
    EXPECT_TRUE(asked[0].parameters.empty());
}

// As Grafana and the dashboard say them: times before now, and the parameters' aliases.
TEST_F(HttpHistoryTest, TimesMayBeRelativeToNowAndParametersNamedByAlias) {
    const auto before = std::chrono::system_clock::now();
    ASSERT_EQ(get(server_->port(), "/api/history?device=oven&parameters=PV,SP&from=-7d&to=-30m").status, 200u);
    ASSERT_EQ(get(server_->port(), "/api/history?device=oven&from=-1.5h&to=now").status, 200u);
    const auto after = std::chrono::system_clock::now();
    const auto asked = history_.asked();
    ASSERT_EQ(asked.size(), 2u);
    EXPECT_EQ(asked[0].parameters, (std::vector<std::string>{"measured_value", "set_point"}));
    EXPECT_EQ(asked[0].to - asked[0].from, std::chrono::hours(7 * 24) - std::chrono::minutes(30));
    EXPECT_GE(asked[0].to, before - std::chrono::minutes(30));
    EXPECT_LE(asked[0].to, after - std::chrono::minutes(30));
    EXPECT_EQ(asked[1].to - asked[1].from, std::chrono::minutes(90));
    EXPECT_GE(asked[1].to, before);
    EXPECT_LE(asked[1].to, after);
}

// Another gateway's history: its device is not configured here, so its names go to the store
// (the historian, which knows the device's parameters and so what its aliases mean) as
// written. This gateway named with gateway=: its own device, its aliases resolved here.
TEST_F(HttpHistoryTest, AnotherGatewaysDeviceIsAskedOfTheStoreAsNamedAndThisOnesWithItsAliases) {
    ASSERT_EQ(get(server_->port(), "/api/history?device=kiln&gateway=south&parameters=PV").status, 200u);
    ASSERT_EQ(get(server_->port(), "/api/history?device=oven&gateway=north&parameters=PV,SP").status, 200u);
    const auto asked = history_.asked();
    ASSERT_EQ(asked.size(), 2u);
    EXPECT_EQ(asked[0].gateway, "south");
    EXPECT_EQ(asked[0].device, "kiln");
    EXPECT_EQ(asked[0].parameters, (std::vector<std::string>{"PV"}));
    EXPECT_EQ(asked[1].gateway, "north");
    EXPECT_EQ(asked[1].parameters, (std::vector<std::string>{"measured_value", "set_point"}));
}

// A gateway or device name no gateway can have (bytes that are no UTF-8, spaces, quotes) is
// the asker's mistake, said in the API's words, never passed to the historian.
TEST_F(HttpHistoryTest, AGatewayOrDeviceThatIsNoNameIs400) {
    for (const char* gateway : {"%FF%FE", "a%20b", "x%27y", "%00"}) {
        const Reply reply = get(server_->port(), std::string("/api/history?device=kiln&gateway=") + gateway);
        EXPECT_EQ(reply.status, 400u) << gateway << ": " << reply.body;
        EXPECT_THAT(reply.json().at("error").get<std::string>(), HasSubstr("is not a gateway's name")) << gateway;
    }
    const Reply device = get(server_->port(), "/api/history?device=%C3%28&gateway=south");
    EXPECT_EQ(device.status, 400u) << device.body;
    EXPECT_THAT(device.json().at("error").get<std::string>(), HasSubstr("device=\"\\xc3(\" is not a device's name"));
    EXPECT_TRUE(history_.asked().empty());
}

// A historian that cannot be reached or does not answer in time is the server's trouble, not
// the asker's: 503, with what went wrong, so the dashboard can say so and ask again later.
TEST_F(HttpHistoryTest, AHistorianDownOrTooSlowIs503WithTheReason) {
    for (const auto& [gateway, reason] : {std::pair{"down", "cannot connect"}, std::pair{"slow", "no answer within"}}) {
        const Reply reply = get(server_->port(), std::string("/api/history?device=kiln&gateway=") + gateway);
        EXPECT_EQ(reply.status, 503u) << reply.body;
        EXPECT_THAT(reply.json().at("error").get<std::string>(), HasSubstr(reason));
    }
}

// The dashboard's choice of whose history the trend shows: the historian's gateways and this
// one's name; 404 without a historian, 503 when it cannot be reached.
TEST_F(HttpHistoryTest, TheHistoriansGatewaysAreListedWithThisOnesName) {
    const Reply none = get(server_->port(), "/api/history/gateways");
    EXPECT_EQ(none.status, 404u) << none.body;
    EXPECT_THAT(none.json().at("error").get<std::string>(), HasSubstr("forward_to"));
    history_.set_gateways({"north", "south"});
    const Reply listed = get(server_->port(), "/api/history/gateways");
    ASSERT_EQ(listed.status, 200u) << listed.body;
    EXPECT_EQ(listed.json(), nlohmann::json::parse(R"({"this": "north", "gateways": ["north", "south"]})"));
    history_.set_gateways({"down"});
    EXPECT_EQ(get(server_->port(), "/api/history/gateways").status, 503u);
}

TEST_F(HttpHistoryTest, BadQueriesAreRefusedSayingWhatIsWrong) {
    const auto port = server_->port();
    const auto error_of = [&](const std::string& query, unsigned status) {
        const Reply reply = get(port, "/api/history?" + query);
        EXPECT_EQ(reply.status, status) << query << ": " << reply.body;
        return reply.json().value("error", std::string());
    };
    EXPECT_THAT(error_of("from=2026-12-02T08:00:00Z", 400), HasSubstr("missing device"));
    EXPECT_THAT(error_of("device=oven&from=yesterday", 400), HasSubstr("ISO 8601"));
    EXPECT_THAT(error_of("device=oven&from=-1fortnight", 400), HasSubstr("a time before now (-1h, -30m, -7d; at most a century)"));
    EXPECT_THAT(error_of("device=oven&from=+1h", 400), HasSubstr("is not a time"));
    EXPECT_THAT(error_of("device=oven&from=2026-12-02T08:00:00", 400), HasSubstr("with its zone"));
    EXPECT_THAT(error_of("device=oven&from=2026-02-30T08:00:00Z", 400), HasSubstr("ISO 8601"));
    // The clock's nanoseconds span 1677-2262: times outside the years taken wrapped round to
    // others (year 1 answered for 1754).
    EXPECT_THAT(error_of("device=oven&from=0001-01-01T00:00:00Z", 400), HasSubstr("between the years 1700 and 2200"));
    EXPECT_THAT(error_of("device=oven&to=9999-12-31T23:59:59Z", 400), HasSubstr("between the years 1700 and 2200"));
    EXPECT_THAT(error_of("device=oven&from=-100000000d", 400), HasSubstr("at most a century"));
    EXPECT_THAT(error_of("device=oven&from=2026-12-02T09:00:00Z&to=2026-12-02T08:00:00Z", 400), HasSubstr("must be before"));
    EXPECT_THAT(error_of("device=oven&points=0", 400), HasSubstr("1..10000"));
    EXPECT_THAT(error_of("device=oven&points=many", 400), HasSubstr("1..10000"));
    EXPECT_THAT(error_of("device=oven&format=xml", 400), HasSubstr("csv"));
    EXPECT_THAT(error_of("device=oven&colour=red", 400), HasSubstr("unknown query parameter"));
    EXPECT_THAT(error_of("device=kiln", 404), HasSubstr("no device \"kiln\""));
    EXPECT_THAT(error_of("device=oven&parameters=nonsense", 400), HasSubstr("no parameter \"nonsense\""));
}

// loopwire_value is what the latest poll read: a value the poll did not read, or a device gone
// stale, has no sample, never the old number.
TEST(PrometheusText, AValueIsExportedOnlyWhileTheLatestPollReadIt) {
    const auto profile = device::testing::builtin("tc10");
    const device::Parameter& pv = device::testing::parameter(*profile, "measured_value");
    const device::Parameter& sp = device::testing::parameter(*profile, "set_point");
    device::WatchedDevice state = device::watch("tc10@3", {&pv, &sp});
    state.status = device::DeviceStatus::partial;
    state.values[0].last = device::EngineeringValue{181.5, "ok", 1815, "°C"};
    state.values[0].fresh = true;
    state.values[0].read_at = device::MonitorClock::now() - 2s;
    state.values[1].last = device::EngineeringValue{150.0, "ok", 1500, "°C"};  // read before, not by this poll
    state.values[1].fresh = false;
    CachedDevice oven{"oven", state, std::chrono::system_clock::now(), 1s, std::chrono::milliseconds(2000)};
    oven.seen_at = device::MonitorClock::now();  // the view taken now: ages are measured to it

    const std::string text = prometheus_text("", {}, {{"oven", "sim"}}, {oven}, nullptr);
    EXPECT_THAT(text, HasSubstr("# TYPE loopwire_value gauge\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_value{device=\"oven\",parameter=\"measured_value\",unit=\"°C\"} 181.5\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_value_age_seconds{device=\"oven\",parameter=\"measured_value\",unit=\"°C\"} 2."));
    EXPECT_THAT(text, Not(HasSubstr("parameter=\"set_point\""))) << "a value the latest poll did not read";

    oven.state.status = device::DeviceStatus::stale;
    for (auto& value : oven.state.values) value.fresh = false;
    const std::string stale = prometheus_text("", {}, {{"oven", "sim"}}, {oven}, nullptr);
    EXPECT_THAT(stale, Not(HasSubstr("loopwire_value{"))) << stale;
}

// Many gateways into one Prometheus: every sample says whose it is; and the bits of a bit field
// (the TC10's alarms) are gauges an alerting rule can select on.
TEST(PrometheusText, EverySampleNamesItsGatewayAndEachAlarmBitIsAGauge) {
    const auto profile = device::testing::builtin("tc10");
    const device::Parameter& alarms = device::testing::parameter(*profile, "alarm_status");
    device::WatchedDevice state = device::watch("tc10@3", {&alarms});
    state.status = device::DeviceStatus::ok;
    state.values[0].last = device::EngineeringValue{std::map<std::string, bool>{{"alarm_1", true}, {"alarm_2", false}}, "ok", 1, ""};
    state.values[0].fresh = true;
    CachedDevice oven{"oven", state, std::chrono::system_clock::now(), 1s, std::chrono::milliseconds(2000)};
    const RecordingHistory history;

    const std::string text = prometheus_text("north", {}, {{"oven", "sim"}}, {oven}, &history);
    EXPECT_THAT(text, HasSubstr("loopwire_bit{gateway=\"north\",device=\"oven\",parameter=\"alarm_status\",bit=\"alarm_1\"} 1\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_bit{gateway=\"north\",device=\"oven\",parameter=\"alarm_status\",bit=\"alarm_2\"} 0\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_history_rows_written_total{gateway=\"north\"} 1234\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_device_status{gateway=\"north\",device=\"oven\",status=\"ok\"} 1\n"));
    // Every sample line, labelled or not before, has the gateway first.
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
        if (line.empty() || line.front() == '#') continue;
        EXPECT_THAT(line, ::testing::MatchesRegex("loopwire_[a-z_]+\\{gateway=\"north\"[,}].*")) << line;
    }
}

TEST_F(HttpHistoryTest, MetricsCountTheHistoryRows) {
    const Reply reply = get(server_->port(), "/metrics");
    EXPECT_THAT(reply.body, HasSubstr("loopwire_history_rows_written_total{gateway=\"north\"} 1234\n"));
}

// A history forwarded to PostgreSQL: its outbox and the forwarder's counts, as the store says.
class ForwardingHistory final : public HistorySource {
public:
    Result<std::vector<HistorySeries>> query(const HistoryQuery&) const override { return std::vector<HistorySeries>{}; }
    std::uint64_t rows_written() const override { return 10; }
    std::optional<ForwardStats> forward_stats() const override { return ForwardStats{42, 7000, 12.5, 3}; }
};

TEST(Metrics, AForwardedHistoryShowsWhatWaitsAndWhatWent) {
    const ForwardingHistory forwarding;
    const std::string text = prometheus_text("", {}, {}, {}, &forwarding);
    EXPECT_THAT(text, HasSubstr("# TYPE loopwire_history_forward_waiting_rows gauge\nloopwire_history_forward_waiting_rows 42\n"));
    EXPECT_THAT(text, HasSubstr("# TYPE loopwire_history_forwarded_rows_total counter\nloopwire_history_forwarded_rows_total 7000\n"));
    EXPECT_THAT(text, HasSubstr("loopwire_history_forward_oldest_waiting_seconds 12.5\n"));
    EXPECT_THAT(text, HasSubstr("# TYPE loopwire_history_forward_errors_total counter\nloopwire_history_forward_errors_total 3\n"));
    // A history kept only locally has none of them.
    const RecordingHistory local;
    EXPECT_THAT(prometheus_text("", {}, {}, {}, &local), Not(HasSubstr("history_forward")));
}

// --- limits, on a server whose values the test feeds itself --------------------------------------

class HttpLimitsTest : public ::testing::Test {
protected:
    void start(HttpServerSettings settings) {
        auto config = parse_gateway_config(R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"
)toml", "plant.toml", profiles());
        if (!config) throw std::runtime_error(config.error().message);
        HttpApiSources sources;
        sources.cache = &cache_;
        sources.writer = &writer_;
        sources.lines = [] { return std::vector<LineReport>{}; };
        api_ = std::make_unique<HttpApi>(*config, std::move(sources));
        auto server = HttpServer::open(settings, *api_);
        if (!server) throw std::runtime_error(server.error().message);
        server_ = std::move(*server);
    }

    // One sample of the oven whose measured value is `value`: a change for every subscriber.
    void sample(double value) {
        auto profile = profiles().find("tc10");
        ASSERT_TRUE(profile);
        const device::Parameter* measured = (*profile)->find("measured_value");
        ASSERT_NE(measured, nullptr);
        device::WatchedDevice state = device::watch("tc10@3", {measured});
        state.status = device::DeviceStatus::ok;
        state.values[0].last = device::EngineeringValue{value, "ok", 0, ""};
        state.values[0].fresh = true;
        state.values[0].read_at = device::MonitorClock::now();
        cache_.update("oven", state, std::chrono::system_clock::now());
    }

    ValueCache cache_;
    Engine engine_;
    DeviceWriter writer_{engine_, {}, 1s};
    std::unique_ptr<HttpApi> api_;
    std::unique_ptr<HttpServer> server_;
};

TEST_F(HttpLimitsTest, AnEventClientThatDoesNotReadIsDroppedWithoutSlowingThePolls) {
    HttpServerSettings settings;
    settings.event_queue_limit = 4096;
    start(settings);
    Socket slow(server_->port(), 4096);
    slow.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");  // and never reads
    Socket fine(server_->port());
    fine.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    // Both subscribed once their streams have begun (the slow one reads its headers, no more).
    EXPECT_THAT(slow.receive_until("\r\n\r\n"), HasSubstr("text/event-stream"));
    EXPECT_THAT(fine.receive_until("\r\n\r\n"), HasSubstr("text/event-stream"));
    // Far more than the socket buffers and the queue hold: each sample only queues.
    const auto before = std::chrono::steady_clock::now();
    for (int i = 0; i < 100000; ++i) {
        sample(i);
        if (i % 1000 == 0) {
            // The reading client keeps up, and so stays.
            while (auto some = fine.receive(0ms)) {
                if (some->empty()) break;
            }
        }
    }
    EXPECT_LT(std::chrono::steady_clock::now() - before, 20s) << "the samples waited for a client";
    // The slow one was dropped: once what reached its socket is read, the connection ends.
    std::optional<std::string> received = std::string();
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    while (received && std::chrono::steady_clock::now() < give_up) received = slow.receive(100ms);
    EXPECT_FALSE(received) << "the client that did not read was not dropped";
    // Others are still served.
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
}

TEST_F(HttpLimitsTest, ConnectionsBeyondTheLimitAreAnswered503) {
    HttpServerSettings settings;
    settings.max_connections = 2;
    start(settings);
    // Both taken by event streams, which no newcomer displaces.
    Socket first(server_->port());
    Socket second(server_->port());
    for (Socket* open : {&first, &second}) {
        ASSERT_TRUE(open->send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
        EXPECT_THAT(open->receive_until("\r\n\r\n"), HasSubstr("200 OK"));
    }
    const Reply refused = get(server_->port(), "/api/devices");
    EXPECT_EQ(refused.status, 503u);
    EXPECT_THAT(refused.json().at("error").get<std::string>(), HasSubstr("too many connections"));
}

TEST_F(HttpLimitsTest, ANewcomerAtTheLimitTakesThePlaceOfTheConnectionIdleLongest) {
    HttpServerSettings settings;
    settings.max_connections = 2;
    start(settings);
    // Both taken once each has been answered; keep-alive, they stay open, waiting for a request.
    Socket first(server_->port());
    Socket second(server_->port());
    for (Socket* open : {&first, &second}) {
        ASSERT_TRUE(open->send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
        EXPECT_THAT(open->receive_until("\r\n\r\n"), HasSubstr("200 OK"));
    }
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
    // The first, idle longest, made room (closed with nothing said); the second is still served.
    EXPECT_FALSE(first.receive(deadline)) << "the connection idle longest was not closed";
    ASSERT_TRUE(second.send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
    EXPECT_THAT(second.receive_until("\r\n\r\n"), HasSubstr("200 OK"));
}

TEST_F(HttpLimitsTest, AtTheLimitTheAddressHoldingTheMostConnectionsGivesOneUp) {
    HttpServerSettings settings;
    settings.max_connections = 4;
    start(settings);
    // One keep-alive connection from 127.0.0.2, idle longest; then three from 127.0.0.3.
    std::vector<std::unique_ptr<Socket>> open;
    for (const char* from : {"127.0.0.2", "127.0.0.3", "127.0.0.3", "127.0.0.3"}) {
        open.push_back(std::make_unique<Socket>(server_->port(), 0, from));
        ASSERT_TRUE(open.back()->send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
        EXPECT_THAT(open.back()->receive_until("\r\n\r\n"), HasSubstr("200 OK"));
    }
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
    // The oldest of 127.0.0.3's made room; 127.0.0.2's one, older still, is served on.
    EXPECT_FALSE(open[1]->receive(deadline)) << "the busiest address's oldest connection was not closed";
    for (std::size_t kept : {0u, 2u, 3u}) {
        ASSERT_TRUE(open[kept]->send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")) << kept;
        EXPECT_THAT(open[kept]->receive_until("\r\n\r\n"), HasSubstr("200 OK")) << kept;
    }
}

TEST_F(HttpLimitsTest, EventStreamsBeyondTheirShareAreRefusedAndLeaveRoomForRequests) {
    HttpServerSettings settings;
    settings.max_connections = 8;
    settings.max_event_streams = 3;
    settings.max_event_streams_per_client = 2;
    start(settings);
    const std::string events = "GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    std::vector<std::unique_ptr<Socket>> streams;
    auto open_stream = [&](const char* from) {
        streams.push_back(std::make_unique<Socket>(server_->port(), 0, from));
        EXPECT_TRUE(streams.back()->send(events));
        return streams.back()->receive_until("\r\n\r\n");
    };
    EXPECT_THAT(open_stream("127.0.0.2"), HasSubstr("200 OK"));
    EXPECT_THAT(open_stream("127.0.0.2"), HasSubstr("200 OK"));
    const std::string third = open_stream("127.0.0.2");
    EXPECT_THAT(third, HasSubstr("429 Too Many Requests"));
    EXPECT_THAT(third, HasSubstr("too many event streams from 127.0.0.2 (at most 2"));
    EXPECT_THAT(third, HasSubstr("Retry-After: 5"));
    EXPECT_THAT(open_stream("127.0.0.3"), HasSubstr("200 OK"));
    const std::string fourth = open_stream("127.0.0.4");
    EXPECT_THAT(fourth, HasSubstr("503 Service Unavailable"));
    EXPECT_THAT(fourth, HasSubstr("too many event streams (at most 3"));
    // A stream that ends gives its place to the next.
    streams.front().reset();
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    std::string again;
    while (again.find("200 OK") == std::string::npos && std::chrono::steady_clock::now() < give_up) {
        again = open_stream("127.0.0.4");
    }
    EXPECT_THAT(again, HasSubstr("200 OK"));
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
}

// A few dozen dashboards and clients that open connections and trickle a header, from several
// addresses, reconnecting as soon as they are closed: a request is answered 200 within a second,
// every time it is asked, while they go on.
TEST_F(HttpLimitsTest, StreamsAndReconnectingSlowlorisFromManyAddressesDoNotLockOutARequest) {
    HttpServerSettings settings;
    settings.header_timeout = 2s;  // the slowloris clients are cut, and reconnect, during the test
    start(settings);
    const std::uint16_t port = server_->port();
    // 64 event streams, 8 from each of 8 addresses: those within the streams' share stream, the
    // others are refused, and close (as a browser's EventSource does).
    std::vector<std::unique_ptr<Socket>> streams;
    for (int i = 0; i < 64; ++i) {
        const std::string from = fmt::format("127.0.0.{}", 10 + i % 8);
        streams.push_back(std::make_unique<Socket>(port, 0, from.c_str()));
        ASSERT_TRUE(streams.back()->send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
    }
    std::size_t streaming = 0;
    for (auto& stream : streams) {
        const std::string head = stream->receive_until("\r\n\r\n");
        if (head.find("200 OK") != std::string::npos) {
            ++streaming;
        } else {
            EXPECT_THAT(head, HasSubstr("too many")) << head;
            stream.reset();
        }
    }
    EXPECT_EQ(streaming, settings.max_event_streams);

    // 64 slowloris clients, 8 from each of 8 more addresses, each sending a byte of a header
    // that never ends every 50 ms, and connecting again at once when closed or refused.
    std::atomic<bool> attacking{true};
    std::atomic<std::size_t> connects{0}, closed{0};
    std::thread slowloris([&] {
        const std::string header = "GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + std::string(100000, 'z');
        std::vector<std::unique_ptr<Socket>> clients(64);
        std::vector<std::size_t> sent(clients.size(), 0);
        while (attacking) {
            for (std::size_t i = 0; i < clients.size(); ++i) {
                if (clients[i]) {
                    const auto some = clients[i]->receive(0ms);
                    if (!some || !some->empty()) {
                        clients[i].reset();  // closed, or refused
                        ++closed;
                    }
                }
                if (!clients[i]) {
                    const std::string from = fmt::format("127.0.0.{}", 20 + i % 8);
                    try {
                        clients[i] = std::make_unique<Socket>(port, 0, from.c_str());
                    } catch (const std::runtime_error&) {
                        continue;  // the backlog is full: next round
                    }
                    ++connects;
                    sent[i] = 0;
                }
                if (!clients[i]->send(header.substr(sent[i]++, 1))) clients[i].reset();
            }
            std::this_thread::sleep_for(50ms);  // the attack's pace, not a wait for the server
        }
    });
    // Probes through two rounds of header_timeout, with the server kept full.
    const auto probing_until = std::chrono::steady_clock::now() + 2 * settings.header_timeout + 1s;
    std::size_t probes = 0;
    while (std::chrono::steady_clock::now() < probing_until) {
        const auto asked = std::chrono::steady_clock::now();
        const Reply reply = get(port, "/api/devices");
        const auto took = std::chrono::steady_clock::now() - asked;
        EXPECT_EQ(reply.status, 200u) << reply.body;
        EXPECT_LT(took, 1s) << "probe " << probes;
        ++probes;
        std::this_thread::sleep_for(200ms);  // the probes' pace
    }
    attacking = false;
    slowloris.join();
    EXPECT_GE(probes, 10u);
    // The attack was one: it kept the server full, its clients were closed and came back.
    EXPECT_GT(connects.load(), 64u);
    EXPECT_GT(closed.load(), 0u);
    // The streams within their share were never disturbed.
    for (auto& stream : streams) {
        if (stream) {
            EXPECT_TRUE(stream->receive(0ms)) << "a stream was closed";
        }
    }
}

// What each of `clients` got before the server closed it, while each sends the next byte of
// `request` whenever the server has said nothing for a moment (a slowloris client): closed ones
// are done; the rest go on until the deadline.
std::vector<std::optional<std::string>> trickle_until_closed(std::vector<std::unique_ptr<Socket>>& clients,
                                                             const std::string& request) {
    std::vector<std::optional<std::string>> received(clients.size(), std::string());
    std::vector<bool> open(clients.size(), true);
    std::vector<std::size_t> sent(clients.size(), 1);  // each sent the first byte already
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    while (std::chrono::steady_clock::now() < give_up && std::count(open.begin(), open.end(), true) > 0) {
        for (std::size_t i = 0; i < clients.size(); ++i) {
            if (!open[i]) continue;
            auto some = clients[i]->receive(5ms);
            if (!some) {
                open[i] = false;
            } else if (!some->empty()) {
                *received[i] += *some;
            } else if (sent[i] < request.size() && !clients[i]->send(request.substr(sent[i]++, 1))) {
                open[i] = false;
            }
        }
    }
    for (std::size_t i = 0; i < clients.size(); ++i) {
        if (open[i]) received[i] = std::nullopt;  // still open at the deadline
    }
    return received;
}

TEST_F(HttpLimitsTest, SlowlorisAndStreamsNobodyReadsLeaveRoomForOthers) {
    HttpServerSettings settings;
    settings.read_timeout = 1s;
    start(settings);
    // A header trickled a byte at a time never ends (the X-Slow value is longer than anyone waits).
    const std::string slow_request = "GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + std::string(5000, 'z');
    std::vector<std::unique_ptr<Socket>> slowloris;
    for (int i = 0; i < 64; ++i) {
        slowloris.push_back(std::make_unique<Socket>(server_->port(), 0, "127.0.0.2"));
        ASSERT_TRUE(slowloris.back()->send(slow_request.substr(0, 1)));
    }
    const auto began = std::chrono::steady_clock::now();
    // Streams nobody reads, each asked once the one before has been answered (one whose request
    // the server has not read yet could be taken for an idle connection and make room for the next).
    std::vector<std::unique_ptr<Socket>> listeners;
    std::vector<std::string> heads;
    for (int i = 0; i < 64; ++i) {
        listeners.push_back(std::make_unique<Socket>(server_->port(), 4096, "127.0.0.3"));
        ASSERT_TRUE(listeners.back()->send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));  // and never read
        const auto first = listeners.back()->receive(deadline);
        ASSERT_TRUE(first && !first->empty()) << "no answer to an event stream";
        heads.push_back(*first);
    }
    // 128 connections, twice max_connections: an honest client from another address is
    // answered all the same.
    const Reply honest = get(server_->port(), "/api/devices");
    EXPECT_EQ(honest.status, 200u) << honest.body;

    // The slowloris clients: beyond max_connections_per_client each newcomer took the place of
    // the one from that address that had waited longest (closed with nothing said, or answered
    // 429 if every other was being answered); the last ones closed read_timeout after they
    // began, however steadily they trickle.
    const auto slow = trickle_until_closed(slowloris, slow_request);
    for (const auto& got : slow) {
        ASSERT_TRUE(got) << "a slowloris client was still connected after " << deadline.count() << " s";
        if (!got->empty()) {
            EXPECT_THAT(*got, HasSubstr("too many connections from 127.0.0.2 (at most 8"));
        }
    }
    EXPECT_GE(std::chrono::steady_clock::now() - began, 900ms) << "closed before read_timeout";

    // The streams nobody reads: their share of the address's connections streaming, the rest
    // refused 429 (beyond the streams' share, or beyond the address's connections).
    std::size_t streaming = 0;
    for (const auto& head : heads) {
        if (head.find("429 Too Many Requests") != std::string::npos) continue;
        EXPECT_THAT(head, HasSubstr("200 OK"));
        ++streaming;
    }
    EXPECT_EQ(streaming, settings.max_event_streams_per_client);
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
}

TEST_F(HttpLimitsTest, AnEventClientThatTakesNothingForTheSendTimeoutIsDropped) {
    HttpServerSettings settings;
    settings.send_timeout = 1s;
    settings.event_queue_limit = 16 * 1024 * 1024;  // never reached here: the drop is the timeout's
    settings.max_connections_per_client = 1;         // the idle stream's slot shows when it is let go
    start(settings);
    Socket idle(server_->port(), 4096);
    idle.send("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");  // and never reads again
    const auto first = idle.receive(deadline);
    ASSERT_TRUE(first && first->find("200 OK") != std::string::npos) << "the stream did not start";
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 429u) << "the stream holds this address's one slot";
    // A few hundred kilobytes of events: more than the two socket buffers hold, far less than
    // the queue may. The write that waits for the client is given up after send_timeout, and
    // the slot is free again.
    for (int i = 0; i < 3000; ++i) sample(i);
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    unsigned status = 0;
    while (status != 200 && std::chrono::steady_clock::now() < give_up) {
        Socket asking(server_->port());
        asking.send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
        const std::string answer = asking.receive_all();
        if (answer.rfind("HTTP/1.1 200", 0) == 0) status = 200;
    }
    EXPECT_EQ(status, 200u) << "the client that took nothing was not dropped";
    // What reached its socket before the drop is there to read, then the end.
    std::optional<std::string> received = std::string();
    while (received && std::chrono::steady_clock::now() < give_up) received = idle.receive(100ms);
    EXPECT_FALSE(received) << "the dropped stream's connection did not end";
}

TEST_F(HttpLimitsTest, OversizedHeadersAreAnswered431) {
    start(HttpServerSettings{});
    const Reply reply = request(server_->port(), "GET", "/api/devices", {}, {"X-Padding: " + std::string(20000, 'x')});
    EXPECT_EQ(reply.status, 431u);
}

// A chunked request whose chunk-size line (here its extension) never ends counts against neither
// the header nor the body limit in the parser: the connection's buffer bounds it, and the client
// is answered 413 at once (or cut off with what it still sends unread), never held until
// read_timeout while the gateway's memory grows.
TEST_F(HttpLimitsTest, AChunkLineThatNeverEndsIsRefusedAtTheBufferBound) {
    HttpServerSettings settings;
    settings.read_timeout = 120s;  // far beyond the test's deadline: only the bound can end it
    start(settings);
    Socket client(server_->port());
    const auto began = std::chrono::steady_clock::now();
    client.send("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n11;" +
                std::string(200 * 1024, 'x'));
    std::string answer;
    std::optional<std::string> some = std::string();
    while (some && std::chrono::steady_clock::now() - began < deadline) {
        some = client.receive(100ms);
        if (some) answer += *some;
    }
    EXPECT_FALSE(some) << "the connection was still open after " << deadline.count() << " s";
    if (!answer.empty()) {
        EXPECT_THAT(answer, HasSubstr("413"));
        EXPECT_THAT(answer, HasSubstr("with its headers and chunked framing"));
    }
    EXPECT_EQ(get(server_->port(), "/api/devices").status, 200u);
}

// RFC 9112, 6.1: a Transfer-Encoding the server does not understand is refused, 501, and the
// connection closed: read as a request without a body, its body would be answered as the next
// request (here a GET of another device smuggled in a POST).
TEST_F(HttpLimitsTest, ATransferEncodingOtherThanChunkedIsRefusedAndTheConnectionClosed) {
    start(HttpServerSettings{});
    Socket client(server_->port());
    const std::string smuggled = "GET /api/devices/oven HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
    client.send("POST /api/devices/oven/write HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: gzip\r\n\r\n" + smuggled);
    const std::string answer = client.receive_all();
    EXPECT_EQ(parse_reply(answer).status, 501u) << answer;
    EXPECT_THAT(answer, HasSubstr("Transfer-Encoding is not supported"));
    EXPECT_EQ(answer.find("HTTP/1.1 200"), std::string::npos) << "the smuggled request was answered: " << answer;
}

// RFC 9110, 9.3.2: HEAD is GET without the body, its length still said (it was 405); RFC 9112,
// 3.2.2: the absolute form of the target is taken, its authority standing for Host.
TEST_F(HttpLimitsTest, HeadIsGetWithoutItsBodyAndTheAbsoluteFormIsTaken) {
    start(HttpServerSettings{});
    const Reply got = get(server_->port(), "/api/devices");
    ASSERT_EQ(got.status, 200u);
    Socket client(server_->port());
    client.send("HEAD /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
    const Reply head = parse_reply(client.receive_all());
    EXPECT_EQ(head.status, 200u);
    EXPECT_EQ(head.header("content-length"), std::to_string(got.body.size()));
    EXPECT_EQ(head.body, "");
    EXPECT_EQ(request(server_->port(), "GET", "http://127.0.0.1/api/devices").status, 200u);
    EXPECT_EQ(request(server_->port(), "GET", "HTTP://127.0.0.1/api/devices?x=1").status, 200u);
    EXPECT_EQ(request(server_->port(), "GET", "http://evil.example/api/devices").status, 421u)
        << "the authority of the absolute form was not checked as the Host";
}

// RFC 9110, 7.2: a request with two Host headers is a 400, whichever comes first: only the first
// would have been checked against the names the front answers to.
TEST_F(HttpLimitsTest, TwoHostHeadersAreRefused400) {
    start(HttpServerSettings{});
    for (const auto& [first, second] : {std::pair{"127.0.0.1", "evil.example"}, std::pair{"evil.example", "127.0.0.1"}}) {
        Socket client(server_->port());
        client.send(fmt::format("GET /api/devices HTTP/1.1\r\nHost: {}\r\nHost: {}\r\nConnection: close\r\n\r\n", first, second));
        const Reply reply = parse_reply(client.receive_all());
        EXPECT_EQ(reply.status, 400u) << first << ", then " << second << ": " << reply.body;
        EXPECT_THAT(reply.body, HasSubstr("more than one Host header"));
    }
}

}  // namespace
}  // namespace loopwire::gateway
