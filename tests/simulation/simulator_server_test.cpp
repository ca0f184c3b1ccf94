// Where `loopwire simulate` serves (simulation/simulator_server.hpp): the choice between --link
// and --pty with its mistakes, and a register bank served on TCP to a real master.
#include <gtest/gtest.h>

#include <thread>

#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulator_server.hpp"

namespace loopwire::device {
namespace {

TEST(SimulatorLink, OneOfLinkOrPtyAndAPtyIsSerial) {
    auto neither = simulator_link("", "");
    ASSERT_FALSE(neither);
    EXPECT_EQ(neither.error().kind, ErrorKind::usage);
    EXPECT_EQ(neither.error().message, "say where to serve: --link URL (serial port or tcp://host:port) or --pty PATH");

    auto network_pty = simulator_link("tcp://127.0.0.1:1502", "/tmp/ttyV0");
    ASSERT_FALSE(network_pty);
    EXPECT_NE(network_pty.error().message.find("carries serial framings (rtu, ascii, linking), not tcp"), std::string::npos);

    auto pty = simulator_link("", "/tmp/ttyV0");
    ASSERT_TRUE(pty) << pty.error().message;
    EXPECT_EQ(pty->pty, "/tmp/ttyV0");
    EXPECT_EQ(pty->url.framing, transport::Framing::rtu);
    EXPECT_EQ(pty->url.path, "/tmp/ttyV0");
}

TEST(SimulatorServer, AVirtualBusCannotBeServedToOtherPrograms) {
    auto link = simulator_link("rtu:virtual", "");
    ASSERT_TRUE(link);
    auto server = SimulatorServer::open(*link, {}, {});
    ASSERT_FALSE(server);
    EXPECT_EQ(server.error().kind, ErrorKind::usage);
}

TEST(SimulatorServer, ServesItsUnitsOnTcpUntilStopped) {
    auto link = simulator_link("tcp://127.0.0.1:0", "");
    ASSERT_TRUE(link) << link.error().message;
    auto bank = std::make_shared<session::RegisterBank>();
    bank->set(codec::Table::holding_registers, 7, 1234);
    auto server = SimulatorServer::open(*link, {{5, bank}}, {});
    ASSERT_TRUE(server) << server.error().message;
    const std::string opened = (*server)->opened();
    ASSERT_EQ(opened.rfind("listening on port ", 0), 0u) << opened;
    const std::string port = opened.substr(std::string("listening on port ").size());

    std::stop_source stop;
    Result<void> served;
    std::thread serving([&] { served = (*server)->serve(stop.get_token()); });
    {
        auto url = transport::parse_link_url("tcp://127.0.0.1:" + port);
        ASSERT_TRUE(url) << url.error().message;
        auto master = session::open_master(*url, {});
        ASSERT_TRUE(master) << master.error().message;
        auto reply = (*master)->execute(5, codec::read_request(codec::FunctionCode::read_holding_registers, 7, 1));
        ASSERT_TRUE(reply) << reply.error().message;
        EXPECT_EQ(reply->values, std::vector<std::uint16_t>{1234});
    }
    stop.request_stop();
    serving.join();
    EXPECT_TRUE(served) << served.error().message;
    EXPECT_EQ((*server)->requests_served(), 1u);
}

}  // namespace
}  // namespace loopwire::device
