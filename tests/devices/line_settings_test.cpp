// The line describes itself, through the wire: a simulated device served as unit N on a line at
// some settings reports exactly those in its own words, and changing them over the line takes
// effect when its manual says. Also: units follow the configuration words, read along with the
// value (values.hpp unit_of), and change when the unit word is written over the wire.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <thread>

#include "client/device_client.hpp"
#include "devices/registry.hpp"
#include "session/slave.hpp"
#include "support/profile_test_support.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

// One simulated device served as `unit` on a virtual bus with `link`'s settings, the way
// `loopwire simulate` and the gateway's virtual lines build it (SimulationEnvironment::on_line),
// and a master on the same bus.
struct LineRig {
    LineRig(const std::string& id, std::uint8_t unit, const std::string& link_text) {
        link = *transport::parse_link_url(link_text);
        profile = testing::builtin(id);
        bus = transport::VirtualBus::create(link.serial.baud, 10);
        slave_port = bus->attach("slave");
        slave = std::make_unique<session::Slave>(
            link, session::UnitMap{{unit, models::make_simulated_device(profile, SimulationEnvironment{}.on_line(unit, link))}});
        server = std::jthread([this](std::stop_token stop) { (void)slave->serve_stream(*slave_port, stop); });
        session::MasterOptions options;
        options.timeout = 400ms;  // silence is an expected answer here: keep it short, no retries
        options.retries = 0;
        master = session::make_serial_master(bus->attach("master"), link, options);
    }
    ~LineRig() {
        server.request_stop();
        server.join();
    }

    DeviceClient client(std::uint8_t unit) { return DeviceClient(*master, DeviceAddress{profile, unit, 0}); }

    // The raw words of `names`, read from `unit`; fails the test when any read fails.
    RawValues words(std::uint8_t unit, const std::vector<std::string>& names) {
        std::vector<const Parameter*> parameters;
        for (const auto& name : names) parameters.push_back(profile->find(name));
        auto report = client(unit).read(parameters);
        EXPECT_FALSE(report.first_error) << report.first_error->message;
        RawValues result;
        for (const auto& name : names) {
            if (auto raw = report.raw.find(name); raw != report.raw.end()) result[name] = raw->second;
        }
        return result;
    }

    // Whether `unit` answers a read of `name` at all (a timeout is no answer).
    bool answers(std::uint8_t unit, const std::string& name) {
        auto report = client(unit).read({profile->find(name)});
        return !report.first_error || report.first_error->kind != ErrorKind::timeout;
    }

    // The unit a read of `name` comes back with.
    std::string unit_of_reading(std::uint8_t unit, const std::string& name) {
        auto report = client(unit).read({profile->find(name)});
        EXPECT_TRUE(report.readings.at(0).value) << name << ": " << report.readings.at(0).error;
        return report.readings.at(0).value ? report.readings.at(0).value->unit : std::string("(not read)");
    }

    Result<WriteReport> write(std::uint8_t unit, const std::vector<std::pair<std::string, std::string>>& assignments) {
        std::vector<std::pair<const Parameter*, std::string>> resolved;
        for (const auto& [name, value] : assignments) resolved.emplace_back(profile->find(name), value);
        return client(unit).write(resolved);
    }

    transport::LinkUrl link;
    std::shared_ptr<const Profile> profile;
    std::shared_ptr<transport::VirtualBus> bus;
    std::unique_ptr<transport::ByteStream> slave_port;
    std::unique_ptr<session::Slave> slave;
    std::jthread server;
    std::unique_ptr<session::Master> master;
};

// An exception reply, however the master hands it over (an exception error or reply).
bool refused(const Result<codec::Reply>& reply) {
    if (!reply) return reply.error().kind == ErrorKind::exception;
    return reply->kind == codec::ReplyKind::exception;
}

// --- AC20: words 526-529, menu group 7 "Sr.Ln" ---------------------------------------------

// Introduction: "Each slave has a unique address ranging from 1 to 255"; word 528 "4 = 9600
// Baud"; word 529 "1 = 8 bits + odd parity"; word 526 "1 = Modbus".
TEST(Ac20Line, ServedAsUnit255At9600OddItsWordsSaySo) {
    LineRig rig("ac20", 255, "rtu:virtual?baud=9600&parity=odd");
    const auto words = rig.words(255, {"serial_interface_protocol", "serial_link_address", "serial_baud_rate", "serial_byte_format"});
    EXPECT_EQ(words.at("serial_link_address"), 255);
    EXPECT_EQ(words.at("serial_baud_rate"), 4);
    EXPECT_EQ(words.at("serial_byte_format"), 1);
    EXPECT_EQ(words.at("serial_interface_protocol"), 1);
}

// Word 527: "Serial link device address. Note: The new data will be activated after the device
// answer": the write is answered at the old address, then only the new one answers.
TEST(Ac20Line, NewAddressIsActivatedAfterTheDeviceAnswer) {
    LineRig rig("ac20", 7, "rtu:virtual?baud=19200&parity=even");
    auto written = rig.write(7, {{"local_remote", "remote"}, {"serial_link_address", "200"}});
    ASSERT_TRUE(written) << written.error().message;  // answered, by unit 7
    EXPECT_FALSE(rig.answers(7, "serial_link_address"));
    EXPECT_EQ(rig.words(200, {"serial_link_address"}).at("serial_link_address"), 200);
}

// Word 528: "Baud rate for serial link ... Note: The new data will be activated after the device
// answer": at 600 baud the device no longer hears a 19200-baud line; word 529 likewise.
TEST(Ac20Line, NewBaudRateOrByteFormatIsActivatedAfterTheDeviceAnswer) {
    LineRig rig("ac20", 3, "rtu:virtual?baud=19200&parity=even");
    ASSERT_TRUE(rig.write(3, {{"local_remote", "remote"}, {"serial_baud_rate", "600"}}));
    EXPECT_FALSE(rig.answers(3, "serial_baud_rate"));

    LineRig other("ac20", 4, "rtu:virtual?baud=19200&parity=even");
    ASSERT_TRUE(other.write(4, {{"local_remote", "remote"}, {"serial_byte_format", "8_bits_no_parity"}}));
    EXPECT_FALSE(other.answers(4, "serial_byte_format"));
}

// Word 526: "0 = No serial interface": after the answer the device is off the line.
TEST(Ac20Line, NoSerialInterfaceMeansNoFurtherAnswer) {
    LineRig rig("ac20", 9, "rtu:virtual?baud=19200&parity=even");
    ASSERT_TRUE(rig.write(9, {{"local_remote", "remote"}, {"serial_interface_protocol", "none"}}));
    EXPECT_FALSE(rig.answers(9, "serial_interface_protocol"));
}

// A value word 528 does not list ("0 = 600 Baud ... 5 = 19200 Baud") is not a setting the
// device has: refused, nothing changes, the device still answers where it was.
TEST(Ac20Line, AnUnlistedRateIsRefusedAndTheDeviceStays) {
    LineRig rig("ac20", 5, "rtu:virtual?baud=9600&parity=even");
    ASSERT_TRUE(rig.write(5, {{"local_remote", "remote"}}));
    EXPECT_TRUE(refused(rig.master->execute(5, codec::write_single_register(528, 6))));
    EXPECT_EQ(rig.words(5, {"serial_baud_rate"}).at("serial_baud_rate"), 4);
}

// --- TC10: §5.3.11 (Ser) #131 Add, #132 bAud ------------------------------------------------

// §5.3.11 #131 "Адрес прибора 0 (оFF/ВЫКЛ) ... 254"; #132 "3 = 19.2 = 19200 бод".
TEST(Tc10Line, ServedAsUnit254At19200ItsWordsSaySo) {
    LineRig rig("tc10", 254, "rtu:virtual?baud=19200&parity=none");
    const auto words = rig.words(254, {"device_address", "baud_rate"});
    EXPECT_EQ(words.at("device_address"), 254);
    EXPECT_EQ(words.at("baud_rate"), 3);
}

// #131 Add: the manual does not say when a new address takes effect; the simulator follows
// the AC20's rule (after the reply, profiles/NOTES.md). "0 (оFF/ВЫКЛ)": serial communication off.
TEST(Tc10Line, NewAddressAnswersAfterTheReplyAndOffIsSilent) {
    LineRig rig("tc10", 3, "rtu:virtual?baud=9600&parity=none");
    ASSERT_TRUE(rig.write(3, {{"device_address", "12"}}));
    EXPECT_FALSE(rig.answers(3, "device_address"));
    EXPECT_EQ(rig.words(12, {"device_address"}).at("device_address"), 12);
    ASSERT_TRUE(rig.write(12, {{"device_address", "off"}}));
    EXPECT_FALSE(rig.answers(12, "device_address"));
}

// #132 bAud "0 = 1200 ... 4 = 38.4": at another rate the device no longer hears this line.
TEST(Tc10Line, NewBaudRateTakesTheDeviceOffThisLine) {
    LineRig rig("tc10", 3, "rtu:virtual?baud=9600&parity=none");
    ASSERT_TRUE(rig.write(3, {{"baud_rate", "38.4"}}));
    EXPECT_FALSE(rig.answers(3, "baud_rate"));
}

// --- ramp/soak: §1 Level 3 and §7 rows 0060H-0063H (PSL, BITS, IDNO, BAUD) ------------------

// §1 "P A C I: MODBUS ASCII Protocol", "E B 2: Even parity, Data bits = 8, Stop Bit = 2",
// "I d. N D ID Number", "48: 4800 bps"; §4.2 "ID Number ... 1~255".
TEST(RampSoakLine, ServedAsUnit255OnAscii4800E82ItsWordsSaySo) {
    LineRig rig("rampsoak", 255, "ascii:virtual?baud=4800&parity=even&stop=2&data=8");
    const auto words = rig.words(255, {"protocol_selection", "communication_bits", "id_number", "baud_rate"});
    EXPECT_EQ(words.at("protocol_selection"), 1);
    EXPECT_EQ(words.at("communication_bits"), 3);
    EXPECT_EQ(words.at("id_number"), 255);
    EXPECT_EQ(words.at("baud_rate"), 1);
}

// §7: IDNO and BAUD are listed with function code "03H" only (set in Level 3 on the front
// panel): a write over the line is refused and the controller keeps answering where it was.
TEST(RampSoakLine, IdNumberCannotBeWrittenOverTheLine) {
    LineRig rig("rampsoak", 9, "rtu:virtual?baud=38400&parity=odd");
    EXPECT_TRUE(refused(rig.master->execute(9, codec::write_single_register(98, 10))));
    EXPECT_EQ(rig.words(9, {"id_number"}).at("id_number"), 9);
}

// --- Units follow the configuration, read along with the value ------------------------------

// TC10 §5.3.1 #5 unit "0 = C = °C 1 = F = °F": the measured value's unit follows it.
TEST(UnitsOnTheWire, Tc10TemperatureUnitWordGivesTheUnit) {
    LineRig rig("tc10", 3, "rtu:virtual?baud=9600&parity=none");
    EXPECT_EQ(rig.unit_of_reading(3, "measured_value"), "°C");
    ASSERT_TRUE(rig.write(3, {{"temperature_unit", "F"}}));
    EXPECT_EQ(rig.unit_of_reading(3, "measured_value"), "°F");
    EXPECT_EQ(rig.unit_of_reading(3, "set_point"), "°F");
}

// Ramp/soak §7 UNIT (0066H) "0000H=C 0001H=F 0002H=A": PV and SV follow it.
TEST(UnitsOnTheWire, RampSoakUnitRegisterGivesTheUnit) {
    LineRig rig("rampsoak", 1, "rtu:virtual?baud=38400&parity=odd");
    EXPECT_EQ(rig.unit_of_reading(1, "process_value"), "°C");
    ASSERT_TRUE(rig.write(1, {{"unit", "F"}}));
    EXPECT_EQ(rig.unit_of_reading(1, "process_value"), "°F");
    ASSERT_TRUE(rig.write(1, {{"unit", "A"}}));
    EXPECT_EQ(rig.unit_of_reading(1, "set_value"), "EU");
}

// AC20 word 2001 PV.SL "0 = Carbon potential ... 1 = Dew point ... 2 = Sensor output in mV" and
// word 2003 tP.In "1-3 ... °C, 4-6 ... °F": the set point's unit read through the wire is the
// one its configuration words give, and the read includes those words.
TEST(UnitsOnTheWire, Ac20SetPointUnitFollowsPrimaryVariableAndTemperatureInput) {
    LineRig rig("ac20", 1, "rtu:virtual?baud=19200&parity=even");
    auto report = rig.client(1).read({rig.profile->find("main_set_point"), rig.profile->find("probe_temperature")});
    ASSERT_FALSE(report.first_error) << report.first_error->message;
    ASSERT_TRUE(report.raw.contains("primary_variable_selection"));
    ASSERT_TRUE(report.raw.contains("temperature_input_type"));
    const std::uint16_t selection = report.raw.at("primary_variable_selection");
    const bool fahrenheit = report.raw.at("temperature_input_type") >= 4;
    const std::string temperature = fahrenheit ? "°F" : "°C";
    const std::string expected = selection == 0 ? "%C" : selection == 2 ? "mV" : temperature;
    EXPECT_EQ(report.readings.at(0).value->unit, expected);
    EXPECT_EQ(report.readings.at(1).value->unit, temperature);
}

// The rule itself, for every combination the AC20 manual lists (unit_of on raw words).
TEST(UnitsOnTheWire, Ac20UnitRulesCoverEveryPrimaryVariable) {
    const auto profile = testing::builtin("ac20");
    const Parameter& set_point = *profile->find("main_set_point");
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 0}, {"temperature_input_type", 4}}), "%C");
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 1}, {"temperature_input_type", 2}}), "°C");
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 1}, {"temperature_input_type", 5}}), "°F");
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 2}, {"temperature_input_type", 5}}), "mV");
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 1}}), unknown_unit);  // tP.In not read
    EXPECT_EQ(unit_of(set_point, {{"primary_variable_selection", 1}, {"temperature_input_type", 9}}), unknown_unit);
}

}  // namespace
}  // namespace loopwire::device
