#include "transport/tcp.hpp"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <thread>
#include <vector>

#include "support/eventually.hpp"
#include "test_support.hpp"

namespace loopwire::transport {
namespace {

using namespace std::chrono_literals;
using testing::bytes_of;
using testing::read_exactly;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::unique_ptr<TcpListener> listen_loopback() {
    auto listener = TcpListener::listen("127.0.0.1", 0);
    if (!listener) ADD_FAILURE() << listener.error().message;
    return listener ? std::move(*listener) : nullptr;
}

// A connected client/server pair on loopback.
struct Connection {
    std::unique_ptr<ByteStream> client;
    std::unique_ptr<ByteStream> server;
};

Connection connect_pair(TcpListener& listener) {
    Connection pair;
    auto client = connect_tcp("127.0.0.1", listener.port(), 2s);
    if (!client) {
        ADD_FAILURE() << client.error().message;
        return pair;
    }
    auto server = listener.accept(2s);
    if (!server || !*server) {
        ADD_FAILURE() << "accept failed";
        return pair;
    }
    pair.client = std::move(*client);
    pair.server = std::move(*server);
    return pair;
}

TEST(TcpListener, PortZeroPicksAFreePortAndReportsIt) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    EXPECT_NE(listener->port(), 0);
    EXPECT_GE(listener->poll_handle(), 0);
    auto client = connect_tcp("127.0.0.1", listener->port(), 2s);
    EXPECT_TRUE(client) << client.error().message;
}

TEST(TcpListener, PortInUseSaysSo) {
    auto first = listen_loopback();
    ASSERT_TRUE(first);
    auto second = TcpListener::listen("127.0.0.1", first->port());
    ASSERT_FALSE(second);
    EXPECT_EQ(second.error().kind, ErrorKind::link);
    const std::string& message = second.error().message;
    EXPECT_TRUE(contains(message, "127.0.0.1:" + std::to_string(first->port()))) << message;
    EXPECT_TRUE(contains(message, "already in use")) << message;
}

TEST(TcpListener, AcceptTimesOutWithNoClient) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    const auto start = std::chrono::steady_clock::now();
    auto accepted = listener->accept(50ms);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ASSERT_TRUE(accepted) << accepted.error().message;
    EXPECT_EQ(*accepted, nullptr);
    EXPECT_GE(elapsed, 50ms);
}

TEST(TcpConnect, RefusedSaysNothingIsListening) {
    std::uint16_t port = 0;
    {
        auto listener = listen_loopback();
        ASSERT_TRUE(listener);
        port = listener->port();
    }
    auto client = connect_tcp("127.0.0.1", port, 2s);
    ASSERT_FALSE(client);
    EXPECT_EQ(client.error().kind, ErrorKind::link);
    EXPECT_EQ(client.error().message,
              "nothing listening at 127.0.0.1:" + std::to_string(port) + " — is the server running?");
}

TEST(TcpConnect, UnknownHostSaysSo) {
    auto client = connect_tcp("no-such-host.invalid", 502, 2s);
    ASSERT_FALSE(client);
    EXPECT_EQ(client.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(client.error().message, "unknown host 'no-such-host.invalid'")) << client.error().message;
}

TEST(TcpConnect, EmptyHostIsAUsageError) {
    auto client = connect_tcp("", 502, 1s);
    ASSERT_FALSE(client);
    EXPECT_EQ(client.error().kind, ErrorKind::usage);
}

// A listener whose accept queue is full drops new SYNs, so connecting hangs: the timeout must
// end it, not the kernel's minutes of SYN retries.
TEST(TcpConnect, TimeoutIsBounded) {
    const int server = ::socket(AF_INET, SOCK_STREAM, 0);
    ASSERT_GE(server, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::bind(server, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    ASSERT_EQ(::listen(server, 0), 0);
    socklen_t length = sizeof address;
    ASSERT_EQ(::getsockname(server, reinterpret_cast<sockaddr*>(&address), &length), 0);
    const std::uint16_t port = ntohs(address.sin_port);
    std::vector<std::unique_ptr<ByteStream>> fillers;
    for (int i = 0; i < 4; ++i) {
        auto filler = connect_tcp("127.0.0.1", port, 100ms);
        if (filler) fillers.push_back(std::move(*filler));
    }

    const auto start = std::chrono::steady_clock::now();
    auto client = connect_tcp("127.0.0.1", port, 150ms);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ::close(server);
    ASSERT_FALSE(client) << "the backlog did not fill up";
    EXPECT_EQ(client.error().kind, ErrorKind::timeout);
    EXPECT_TRUE(contains(client.error().message, "no answer from 127.0.0.1:" + std::to_string(port) + " within 150 ms"))
        << client.error().message;
    EXPECT_GE(elapsed, 150ms);
}

TEST(TcpStream, EchoesBothWaysAndDescribesTheEndpoints) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    EXPECT_EQ(client->describe(), "tcp 127.0.0.1:" + std::to_string(listener->port()));
    EXPECT_TRUE(contains(server->describe(), "tcp 127.0.0.1:")) << server->describe();

    const Bytes request = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, 0x01};
    ASSERT_TRUE(client->write(request));
    EXPECT_EQ(read_exactly(*server, request.size()), request);
    const Bytes reply = {0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x01, 0x03, 0x02, 0x12, 0x34};
    ASSERT_TRUE(server->write(reply));
    EXPECT_EQ(read_exactly(*client, reply.size()), reply);
}

TEST(TcpStream, CarriesSeveralMessagesInOrder) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    Bytes expected;
    for (int i = 0; i < 50; ++i) {
        const Bytes message = bytes_of("message " + std::to_string(i) + ";");
        ASSERT_TRUE(client->write(message));
        expected.insert(expected.end(), message.begin(), message.end());
    }
    EXPECT_EQ(read_exactly(*server, expected.size()), expected);
}

TEST(TcpStream, LargeWritesArriveWhole) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    Bytes payload(4 * 1024 * 1024);
    for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<std::uint8_t>(i ^ (i >> 9));
    Bytes received;
    std::thread reader([&, &server = server] { received = read_exactly(*server, payload.size(), 20s); });
    auto written = client->write(payload);
    reader.join();
    ASSERT_TRUE(written) << written.error().message;
    EXPECT_TRUE(received == payload) << received.size() << " bytes arrived";
}

TEST(TcpStream, PeerClosingIsALinkError) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    server.reset();
    std::uint8_t buffer[8];
    auto got = client->read_some(buffer, 2s);
    ASSERT_FALSE(got);
    EXPECT_EQ(got.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(got.error().message, "connection closed by peer")) << got.error().message;
    EXPECT_TRUE(contains(got.error().message, client->describe())) << got.error().message;
}

// Writing into a closed connection must come back as an error value, not SIGPIPE.
TEST(TcpStream, WritingToAClosedPeerIsALinkErrorNotASignal) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    server.reset();
    Result<void> written;
    // The first write after the close usually succeeds (it provokes the reset).
    const auto refused = [&] {
        written = client->write(bytes_of("anyone there?"));
        return !written.ok();
    };
    ASSERT_TRUE(loopwire::testing::eventually(refused)) << "every write to the closed connection succeeded";
    ASSERT_FALSE(written.ok());
    EXPECT_EQ(written.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(written.error().message, "by peer")) << written.error().message;
}

TEST(TcpStream, ReadTimesOutWithZeroBytes) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    std::uint8_t buffer[8];
    const auto start = std::chrono::steady_clock::now();
    auto got = client->read_some(buffer, 30ms);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 0u);
    EXPECT_GE(elapsed, 30ms);
}

TEST(TcpStream, DiscardInputDropsWhatArrived) {
    auto listener = listen_loopback();
    ASSERT_TRUE(listener);
    auto [client, server] = connect_pair(*listener);
    ASSERT_TRUE(client && server);
    ASSERT_TRUE(server->write(bytes_of("stale")));
    pollfd entry{client->poll_handle(), POLLIN, 0};
    ASSERT_EQ(::poll(&entry, 1, 2000), 1);
    client->discard_input();
    std::uint8_t buffer[8];
    auto got = client->read_some(buffer, 30ms);
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 0u);
    ASSERT_TRUE(server->write(bytes_of("fresh")));
    EXPECT_EQ(read_exactly(*client, 5), bytes_of("fresh"));
}

TEST(TcpStream, WorksOverIpv6Loopback) {
    auto listener = TcpListener::listen("::1", 0);
    if (!listener) GTEST_SKIP() << "no IPv6 loopback here: " << listener.error().message;
    auto client = connect_tcp("::1", (*listener)->port(), 2s);
    ASSERT_TRUE(client) << client.error().message;
    EXPECT_EQ((*client)->describe(), "tcp [::1]:" + std::to_string((*listener)->port()));
    auto server = (*listener)->accept(2s);
    ASSERT_TRUE(server && *server);
    ASSERT_TRUE((*client)->write(bytes_of("v6")));
    EXPECT_EQ(read_exactly(**server, 2), bytes_of("v6"));
}

}  // namespace
}  // namespace loopwire::transport
