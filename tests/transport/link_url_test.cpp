#include "transport/link_url.hpp"

#include <gtest/gtest.h>

#include <string>

namespace loopwire::transport {
namespace {

LinkUrl parse_ok(std::string_view text) {
    auto url = parse_link_url(text);
    if (!url) {
        ADD_FAILURE() << text << ": " << url.error().message;
        return {};
    }
    return *url;
}

bool same(const LinkUrl& a, const LinkUrl& b) {
    return a.framing == b.framing && a.path == b.path && a.host == b.host && a.port == b.port &&
           a.serial.baud == b.serial.baud && a.serial.data_bits == b.serial.data_bits &&
           a.serial.parity == b.serial.parity && a.serial.stop_bits == b.serial.stop_bits &&
           a.serial.rs485 == b.serial.rs485 && a.serial.rs485_delay_before == b.serial.rs485_delay_before &&
           a.serial.rs485_delay_after == b.serial.rs485_delay_after && a.serial.guard == b.serial.guard;
}

TEST(LinkUrl, FramingNames) {
    EXPECT_EQ(framing_name(Framing::rtu), "rtu");
    EXPECT_EQ(framing_name(Framing::ascii), "ascii");
    EXPECT_EQ(framing_name(Framing::linking), "linking");
    EXPECT_EQ(framing_name(Framing::tcp), "tcp");
    EXPECT_EQ(framing_name(Framing::rtu_over_tcp), "rtu+tcp");
}

TEST(LinkUrl, RtuWithEveryOption) {
    const LinkUrl url = parse_ok("rtu:/dev/ttyUSB0?baud=9600&parity=odd&stop=2&data=7&rs485=1");
    EXPECT_EQ(url.framing, Framing::rtu);
    EXPECT_TRUE(url.is_serial());
    EXPECT_EQ(url.path, "/dev/ttyUSB0");
    EXPECT_EQ(url.serial.baud, 9600u);
    EXPECT_EQ(url.serial.parity, Parity::odd);
    EXPECT_EQ(url.serial.stop_bits, 2u);
    EXPECT_EQ(url.serial.data_bits, 7u);
    EXPECT_EQ(url.serial.rs485, Rs485::on);
}

TEST(LinkUrl, SerialDefaultsAreTheModbusSerialLineDefault) {
    for (const char* text : {"rtu:/dev/ttyUSB0", "ascii:/dev/ttyS1"}) {
        const LinkUrl url = parse_ok(text);
        EXPECT_EQ(url.serial.baud, 19200u) << text;
        EXPECT_EQ(url.serial.data_bits, 8u) << text;
        EXPECT_EQ(url.serial.parity, Parity::even) << text;
        EXPECT_EQ(url.serial.stop_bits, 1u) << text;
        EXPECT_EQ(url.serial.rs485, Rs485::off) << text;
        EXPECT_EQ(url.serial.guard, LineGuard{}) << text;
    }
}

TEST(LinkUrl, AsciiKeepsEightDataBitsUnlessTold) {
    const LinkUrl eight = parse_ok("ascii:/dev/ttyS1?baud=9600&parity=even");
    EXPECT_EQ(eight.framing, Framing::ascii);
    EXPECT_EQ(eight.serial.data_bits, 8u);
    const LinkUrl seven = parse_ok("ascii:/dev/ttyS1?baud=9600&parity=even&data=7");
    EXPECT_EQ(seven.serial.data_bits, 7u);
    EXPECT_EQ(seven.serial.baud, 9600u);
}

// The spec asks for 2 stop bits with 7N: accepted as given, the user may know their device.
TEST(LinkUrl, AsciiSevenNoParityOneStopIsAccepted) {
    const LinkUrl url = parse_ok("ascii:/dev/ttyS1?data=7&parity=none&stop=1");
    EXPECT_EQ(url.serial.data_bits, 7u);
    EXPECT_EQ(url.serial.parity, Parity::none);
    EXPECT_EQ(url.serial.stop_bits, 1u);
}

// Only the ramp/soak controller speaks Linking: its factory line (manual chapter 1) is the default.
TEST(LinkUrl, LinkingDefaultsToTheRampSoakControllersLine) {
    const LinkUrl url = parse_ok("linking:/dev/ttyS1");
    EXPECT_EQ(url.serial.baud, 38400u);
    EXPECT_EQ(url.serial.parity, Parity::odd);
    EXPECT_EQ(url.serial.data_bits, 8u);
    EXPECT_EQ(url.serial.stop_bits, 1u);
}

TEST(LinkUrl, Linking) {
    const LinkUrl url = parse_ok("linking:/dev/ttyS1?baud=9600");
    EXPECT_EQ(url.framing, Framing::linking);
    EXPECT_EQ(url.path, "/dev/ttyS1");
    EXPECT_EQ(url.serial.baud, 9600u);
}

TEST(LinkUrl, ParityNamesAndLetters) {
    struct Case {
        const char* value;
        Parity parity;
    };
    for (const Case& c : {Case{"none", Parity::none}, Case{"n", Parity::none}, Case{"N", Parity::none},
                          Case{"even", Parity::even}, Case{"e", Parity::even}, Case{"E", Parity::even},
                          Case{"odd", Parity::odd}, Case{"o", Parity::odd}, Case{"ODD", Parity::odd}}) {
        EXPECT_EQ(parse_ok(std::string("rtu:/dev/ttyS0?parity=") + c.value).serial.parity, c.parity) << c.value;
    }
}

TEST(LinkUrl, EverySupportedBaud) {
    for (std::uint32_t baud : {600u, 1200u, 2400u, 4800u, 9600u, 19200u, 38400u, 57600u, 115200u}) {
        EXPECT_EQ(parse_ok("rtu:/dev/ttyS0?baud=" + std::to_string(baud)).serial.baud, baud);
    }
}

TEST(LinkUrl, Rs485Zero) { EXPECT_EQ(parse_ok("rtu:/dev/ttyS0?rs485=0").serial.rs485, Rs485::off); }

TEST(LinkUrl, Rs485TakesWordsAutoAndDelays) {
    EXPECT_EQ(parse_ok("rtu:/dev/ttyS0?rs485=true").serial.rs485, Rs485::on);
    EXPECT_EQ(parse_ok("rtu:/dev/ttyS0?rs485=false").serial.rs485, Rs485::off);
    const LinkUrl url = parse_ok("rtu:/dev/ttyS0?rs485=auto&rs485_delay_before=2ms&rs485_delay_after=0");
    EXPECT_EQ(url.serial.rs485, Rs485::if_supported);
    EXPECT_EQ(url.serial.rs485_delay_before, std::chrono::milliseconds(2));
    EXPECT_EQ(url.serial.rs485_delay_after, std::chrono::milliseconds(0));
}

// 3.5 characters of 11 bits at 9600 baud are 4010 us; a guard in time is taken as written.
TEST(LinkUrl, GuardInCharactersOrTime) {
    const LinkUrl characters = parse_ok("rtu:/dev/ttyS0?baud=9600&guard=3.5c");
    EXPECT_EQ(characters.serial.guard.characters, 3.5);
    EXPECT_EQ(characters.serial.guard_time(), std::chrono::microseconds(4010));
    const LinkUrl time = parse_ok("rtu:/dev/ttyS0?guard=5ms");
    EXPECT_EQ(time.serial.guard_time(), std::chrono::milliseconds(5));
    EXPECT_EQ(parse_ok("rtu:/dev/ttyS0?guard=250us").serial.guard_time(), std::chrono::microseconds(250));
}

TEST(LinkUrl, VirtualBus) {
    const LinkUrl url = parse_ok("rtu:virtual");
    EXPECT_EQ(url.framing, Framing::rtu);
    EXPECT_EQ(url.path, "virtual");
    EXPECT_EQ(parse_ok("ascii:virtual?baud=9600").path, "virtual");
}

TEST(LinkUrl, RelativePathsAndPtyLinks) {
    EXPECT_EQ(parse_ok("rtu:ttyA").path, "ttyA");
    EXPECT_EQ(parse_ok("rtu:/tmp/loopwire-x/ttyB?baud=38400").path, "/tmp/loopwire-x/ttyB");
}

TEST(LinkUrl, Tcp) {
    const LinkUrl url = parse_ok("tcp://127.0.0.1:502");
    EXPECT_EQ(url.framing, Framing::tcp);
    EXPECT_FALSE(url.is_serial());
    EXPECT_EQ(url.host, "127.0.0.1");
    EXPECT_EQ(url.port, 502);
    EXPECT_TRUE(url.path.empty());
}

TEST(LinkUrl, TcpDefaultPortIs502) {
    const LinkUrl url = parse_ok("tcp://plc.example");
    EXPECT_EQ(url.host, "plc.example");
    EXPECT_EQ(url.port, 502);
}

TEST(LinkUrl, TcpIpv6InBrackets) {
    const LinkUrl url = parse_ok("tcp://[::1]:1502");
    EXPECT_EQ(url.host, "::1");
    EXPECT_EQ(url.port, 1502);
    EXPECT_EQ(parse_ok("tcp://[fe80::1]").port, 502);
}

TEST(LinkUrl, RtuOverTcp) {
    const LinkUrl url = parse_ok("rtu+tcp://serial-server.local:4001");
    EXPECT_EQ(url.framing, Framing::rtu_over_tcp);
    EXPECT_FALSE(url.is_serial());
    EXPECT_EQ(url.host, "serial-server.local");
    EXPECT_EQ(url.port, 4001);
}

TEST(LinkUrl, PortLimits) {
    EXPECT_EQ(parse_ok("tcp://h:65535").port, 65535);
    EXPECT_EQ(parse_ok("tcp://h:1").port, 1);
    EXPECT_EQ(parse_ok("tcp://h:0").port, 0);  // servers: any free port
}

class LinkUrlRoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(LinkUrlRoundTrip, CanonicalTextParsesBackToTheSameLink) {
    const LinkUrl url = parse_ok(GetParam());
    const std::string canonical = url.to_string();
    const LinkUrl again = parse_ok(canonical);
    EXPECT_TRUE(same(url, again)) << GetParam() << " -> " << canonical;
    EXPECT_EQ(again.to_string(), canonical);
}

INSTANTIATE_TEST_SUITE_P(AcceptedForms, LinkUrlRoundTrip,
                         ::testing::Values("rtu:/dev/ttyUSB0?baud=19200&parity=even&stop=1&data=8&rs485=1",
                                           "rtu:/dev/ttyUSB0?rs485=auto&rs485_delay_before=1ms&rs485_delay_after=3ms",
                                           "rtu:/dev/ttyUSB0?guard=4.5c", "rtu:/dev/ttyUSB0?guard=750us",
                                           "rtu:/dev/ttyUSB0", "ascii:/dev/ttyS1?baud=9600&parity=even&data=7",
                                           "ascii:/dev/ttyS1?parity=n&stop=2&data=7", "linking:/dev/ttyS1?baud=9600",
                                           "linking:/dev/ttyS1?baud=38400&parity=o", "rtu:virtual",
                                           "rtu:virtual?baud=600", "tcp://127.0.0.1:502", "tcp://[::1]:1502",
                                           "tcp://localhost", "rtu+tcp://serial-server.local:4001",
                                           "rtu+tcp://[2001:db8::7]"));

TEST(LinkUrl, CanonicalForms) {
    EXPECT_EQ(parse_ok("rtu:/dev/ttyUSB0").to_string(), "rtu:/dev/ttyUSB0?baud=19200&parity=even&data=8&stop=1");
    EXPECT_EQ(parse_ok("ascii:/dev/ttyS1?data=7&parity=N&stop=2&rs485=1").to_string(),
              "ascii:/dev/ttyS1?baud=19200&parity=none&data=7&stop=2&rs485=1");
    EXPECT_EQ(parse_ok("tcp://[::1]").to_string(), "tcp://[::1]:502");
    EXPECT_EQ(parse_ok("rtu+tcp://gw:4001").to_string(), "rtu+tcp://gw:4001");
}

// ----- errors -----

struct BadUrl {
    const char* text;
    std::vector<const char*> message_parts;  // each must appear in the message
};

void PrintTo(const BadUrl& bad, std::ostream* out) { *out << bad.text; }

class LinkUrlErrors : public ::testing::TestWithParam<BadUrl> {};

TEST_P(LinkUrlErrors, AreUsageErrorsNamingTheBadPartAndTheChoices) {
    const BadUrl& bad = GetParam();
    auto url = parse_link_url(bad.text);
    ASSERT_FALSE(url) << bad.text << " was accepted";
    EXPECT_EQ(url.error().kind, ErrorKind::usage);
    const std::string& message = url.error().message;
    EXPECT_NE(message.find("link URL '" + std::string(bad.text) + "'"), std::string::npos) << message;
    for (const char* part : bad.message_parts) {
        EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' missing from: " << message;
    }
}

INSTANTIATE_TEST_SUITE_P(
    Every, LinkUrlErrors,
    ::testing::Values(
        BadUrl{"", {"empty", "rtu:/dev/ttyUSB0", "tcp://127.0.0.1:502"}},
        BadUrl{"/dev/ttyUSB0", {"missing scheme", "rtu, ascii, linking, tcp, rtu+tcp"}},
        BadUrl{"modbus:/dev/ttyUSB0", {"unknown scheme 'modbus'", "rtu, ascii, linking, tcp, rtu+tcp"}},
        BadUrl{"RTU:/dev/ttyUSB0", {"unknown scheme 'RTU'"}},
        BadUrl{"udp://127.0.0.1:502", {"unknown scheme 'udp'", "rtu+tcp"}},
        BadUrl{"rtu:", {"missing serial port path", "rtu:/dev/ttyUSB0", "rtu:virtual"}},
        BadUrl{"ascii:?baud=9600", {"missing serial port path", "ascii:/dev/ttyUSB0"}},
        BadUrl{"rtu:///dev/ttyUSB0", {"without '//'", "rtu:/dev/ttyUSB0"}},
        BadUrl{"rtu:/dev/ttyUSB0?speed=9600", {"unknown option 'speed'", "baud, parity, data, stop, rs485"}},
        BadUrl{"rtu:/dev/ttyUSB0?baud", {"option 'baud' has no value", "name=value"}},
        BadUrl{"rtu:/dev/ttyUSB0?", {"empty option", "baud, parity, data, stop, rs485"}},
        BadUrl{"rtu:/dev/ttyUSB0?baud=9600&", {"empty option"}},
        BadUrl{"rtu:/dev/ttyUSB0?baud=9600&&parity=none", {"empty option"}},
        BadUrl{"rtu:/dev/x?baud=12345",
               {"baud '12345' is not a supported rate", "600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200"}},
        BadUrl{"rtu:/dev/x?baud=", {"baud '' is not a supported rate", "115200"}},
        BadUrl{"rtu:/dev/x?baud=fast", {"baud 'fast'"}},
        BadUrl{"rtu:/dev/x?baud=-9600", {"baud '-9600'"}},
        BadUrl{"rtu:/dev/x?baud=99999999999", {"baud '99999999999'"}},
        BadUrl{"rtu:/dev/x?parity=mark", {"parity 'mark' is not valid", "none, even, odd", "n, e, o"}},
        BadUrl{"rtu:/dev/x?data=9", {"data bits '9' is not valid", "7 or 8"}},
        BadUrl{"rtu:/dev/x?data=", {"data bits '' is not valid", "7 or 8"}},
        BadUrl{"rtu:/dev/x?stop=3", {"stop bits '3' is not valid", "1 or 2"}},
        BadUrl{"rtu:/dev/x?stop=1.5", {"stop bits '1.5' is not valid", "1 or 2"}},
        BadUrl{"rtu:/dev/x?rs485=yes", {"rs485 'yes' is not valid", "1 or true to enable", "auto"}},
        BadUrl{"rtu:/dev/x?rs485_delay_before=1.5ms", {"rs485_delay_before '1.5ms' is not valid", "whole milliseconds"}},
        BadUrl{"rtu:/dev/x?rs485_delay_after=2s", {"rs485_delay_after '2s' is not valid", "0ms to 1000ms"}},
        BadUrl{"rtu:/dev/x?guard=fast", {"guard 'fast' is not valid", "3.5c", "5ms"}},
        BadUrl{"rtu:/dev/x?guard=c", {"guard 'c' is not valid"}},
        BadUrl{"rtu:/dev/x?guard=2000c", {"guard '2000c' is not valid"}},
        BadUrl{"rtu:/dev/x?guard=2s", {"guard '2s' is not valid"}},
        BadUrl{"rtu:/dev/x?baud=9600&baud=19200", {"option 'baud' is given twice"}},
        BadUrl{"rtu:/dev/x?parity=n&parity=e", {"option 'parity' is given twice"}},
        BadUrl{"tcp:127.0.0.1:502", {"tcp links are written tcp://host[:port]"}},
        BadUrl{"rtu+tcp:gw:4001", {"rtu+tcp links are written rtu+tcp://host[:port]"}},
        BadUrl{"tcp://", {"empty host"}},
        BadUrl{"tcp://:502", {"empty host"}},
        BadUrl{"tcp://[]:502", {"empty host"}},
        BadUrl{"tcp://127.0.0.1:", {"bad port number ''", "0..65535"}},
        BadUrl{"tcp://127.0.0.1:65536", {"bad port number '65536'", "0..65535"}},
        BadUrl{"tcp://127.0.0.1:http", {"bad port number 'http'"}},
        BadUrl{"tcp://127.0.0.1:-1", {"bad port number '-1'"}},
        BadUrl{"tcp://plc one:502", {"host 'plc one' contains ' '", "IPv6 address in brackets"}},
        BadUrl{"tcp://[[x]:502", {"host '[x' contains '['"}},
        BadUrl{"tcp://::1:502", {"IPv6 addresses go in brackets", "[::1]"}},
        BadUrl{"tcp://[::1:502", {"missing ']'"}},
        BadUrl{"tcp://[::1]502", {"unexpected '502' after the IPv6 address"}},
        BadUrl{"tcp://127.0.0.1:502?timeout=5", {"take no path or options"}},
        BadUrl{"tcp://127.0.0.1:502/unit/1", {"take no path or options"}}));

}  // namespace
}  // namespace loopwire::transport
