// The simulators against loopwire's own master side on the virtual bus: DeviceClient reads
// every readable parameter of each simulated device and writes by name (docs/DESIGN.md: device-side
// tests go through the wire).
#include <gtest/gtest.h>

#include <algorithm>
#include <thread>

#include "client/device_client.hpp"
#include "simulation/simulated_device.hpp"
#include "session/slave.hpp"
#include "support/profile_test_support.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

struct BusCase {
    std::string id;
    std::string link;              // settings the device offers (profile serial_defaults), at 9600 baud
    std::string parameter;         // a writable parameter and a value in its range
    std::string value;
};

// A simulated device on a virtual bus and a DeviceClient talking to it through a master.
struct BusRig {
    explicit BusRig(const BusCase& bus_case) {
        link = *transport::parse_link_url(bus_case.link);
        auto profile = testing::builtin(bus_case.id);
        EXPECT_TRUE(profile);
        bus = transport::VirtualBus::create(link.serial.baud, 10);
        slave_port = bus->attach("slave");
        slave = std::make_unique<session::Slave>(link, session::UnitMap{{5, std::make_shared<SimulatedDevice>(profile)}});
        server = std::jthread([this](std::stop_token stop) { (void)slave->serve_stream(*slave_port, stop); });
        session::MasterOptions options;
        options.timeout = 2s;
        options.retries = 2;  // a loaded, sanitised test machine can stretch a frame past its gaps
        master = session::make_serial_master(bus->attach("master"), link, options);
        client = std::make_unique<DeviceClient>(*master, *parse_device_address(bus_case.id + "@5"));
    }
    ~BusRig() {
        server.request_stop();
        server.join();
    }

    transport::LinkUrl link;
    std::shared_ptr<transport::VirtualBus> bus;
    std::unique_ptr<transport::ByteStream> slave_port;
    std::unique_ptr<session::Slave> slave;
    std::jthread server;
    std::unique_ptr<session::Master> master;
    std::unique_ptr<DeviceClient> client;
};

class SimulatedDeviceOnBus : public ::testing::TestWithParam<BusCase> {
protected:
    void SetUp() override {
        rig = std::make_unique<BusRig>(GetParam());
        client = rig->client.get();
    }
    void TearDown() override { rig.reset(); }

    std::unique_ptr<BusRig> rig;
    DeviceClient* client = nullptr;
};

// Every value decodes: status ok, or a special state the profile names (never an unlisted enum
// code or a failed request).
TEST_P(SimulatedDeviceOnBus, ReadsAllAndEveryValueDecodes) {
    const Profile& profile = *client->device().profile;
    auto all = resolve_parameters(profile, {"all"});
    ASSERT_TRUE(all.ok());
    const ReadReport report = client->read(*all);
    EXPECT_FALSE(report.first_error) << report.first_error->message;
    for (const ParameterReading& reading : report.readings) {
        ASSERT_TRUE(reading.value) << reading.parameter->name << ": " << reading.error;
        const std::string& status = reading.value->status;
        const bool special = std::any_of(reading.parameter->special.begin(), reading.parameter->special.end(),
                                         [&](const SpecialValue& s) { return s.state == status; });
        EXPECT_TRUE(status == "ok" || special) << reading.parameter->name << ": " << status;
    }
}

TEST_P(SimulatedDeviceOnBus, NamedWriteReadsBack) {
    const Parameter* parameter = client->device().profile->find(GetParam().parameter);
    ASSERT_NE(parameter, nullptr);
    // AC20 Note 5: a master writes only in remote; the client checks bit 218 first.
    if (const Parameter* remote = client->device().profile->find("local_remote")) {
        ASSERT_TRUE(client->write({{remote, "remote"}}).ok());
    }
    auto written = client->write({{parameter, GetParam().value}});
    ASSERT_TRUE(written.ok()) << written.error().message;
    const ReadReport back = client->read({parameter});
    ASSERT_TRUE(back.readings.at(0).value) << back.readings.at(0).error;
    auto text = format_value(*parameter, *back.readings[0].value, back.raw);
    ASSERT_TRUE(text.ok());
    EXPECT_EQ(*text, GetParam().value);
}

// AC20 Note 5: in local the master can only read (bit 218 aside). The client reads bit 218 and
// refuses the write before sending it, saying what to do.
TEST(SimulatedAc20, WriteInLocalIsRefusedBeforeSendingWithTheRemedy) {
    const BusCase ac20{"ac20", "rtu:virtual?baud=9600&parity=even", "auxiliary_set_point_2", "250"};
    BusRig rig(ac20);
    const Profile& profile = *rig.client->device().profile;
    auto refused = rig.client->write({{profile.find("auxiliary_set_point_2"), "250"}});
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().kind, ErrorKind::usage);
    EXPECT_NE(refused.error().message.find("control needs local_remote=remote"), std::string::npos) << refused.error().message;
    const ReadReport after = rig.client->read({profile.find("auxiliary_set_point_2")});
    ASSERT_TRUE(after.readings.at(0).value);
    EXPECT_NE(after.readings[0].value->raw, 250);
}

// The mode check follows the assignments in order: remote set by the first lets the second in;
// the other way round, the set point would reach a device still in local, so it is refused.
TEST(SimulatedAc20, RemoteSetEarlierInTheSameWriteLetsLaterAssignmentsThrough_Note5) {
    const BusCase ac20{"ac20", "rtu:virtual?baud=9600&parity=even", "auxiliary_set_point_2", "250"};
    BusRig rig(ac20);
    const Profile& profile = *rig.client->device().profile;
    const Parameter* remote = profile.find("local_remote");
    const Parameter* set_point = profile.find("auxiliary_set_point_2");
    EXPECT_FALSE(rig.client->write({{set_point, "250"}, {remote, "remote"}}).ok());
    auto written = rig.client->write({{remote, "remote"}, {set_point, "250"}});
    ASSERT_TRUE(written.ok()) << written.error().message;
    const ReadReport after = rig.client->read({set_point});
    ASSERT_TRUE(after.readings.at(0).value);
    EXPECT_EQ(after.readings[0].value->raw, 250);
}

INSTANTIATE_TEST_SUITE_P(
    Profiles, SimulatedDeviceOnBus,
    ::testing::Values(BusCase{"ac20", "rtu:virtual?baud=9600&parity=even", "auxiliary_set_point_2", "250"},
                      BusCase{"tc10", "rtu:virtual?baud=9600&parity=none", "set_point", "125"},
                      BusCase{"rampsoak", "rtu:virtual?baud=9600&parity=odd", "output_limit", "87.5"}),
    [](const ::testing::TestParamInfo<BusCase>& test) { return test.param.id; });

}  // namespace
}  // namespace loopwire::device
