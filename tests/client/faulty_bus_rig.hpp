#pragma once
// Simulated devices served by a session::Slave on a transport::VirtualBus, and a master on the
// same bus whose frames (and the replies to them) pass a fault policy the test sets: drops,
// corrupted bytes, a unit that stops answering. heal() turns the faults off. The clean path the
// tests check the devices' memory through is a second bus, served by a second slave over the
// same devices: a serial line has one master, and a master that heard another's replies between
// its own exchanges would rightly take them for copies (session/serial_master.cpp).
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "client/device_client.hpp"
#include "devices/registry.hpp"
#include "session/master.hpp"
#include "session/slave.hpp"
#include "transport/link_url.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::app::testing {

// (sending port "master" or "slave", bytes, index of this write since the policy was set)
using FaultPolicy = std::function<transport::BusFault(const std::string& from, ByteView bytes, unsigned index)>;

class FaultyBusRig {
public:
    // `devices`: "tc10@3", "rampsoak@5", ... all served by one slave, on a line of `baud` (8N1).
    // The wire time is real time: a test that sends hundreds of frames runs faster, and none of
    // the faults it injects depends on the speed.
    FaultyBusRig(const std::vector<std::string>& devices, std::chrono::milliseconds timeout, std::uint32_t baud = 9600) {
        const auto link = transport::parse_link_url("rtu:virtual?baud=" + std::to_string(baud) + "&parity=none");
        if (!link) throw std::runtime_error(link.error().message);
        bus_ = transport::VirtualBus::create(link->serial.baud, 10);
        bus_->set_fault_injector([this](const std::string& from, ByteView bytes) { return fault_for(from, bytes); });
        session::UnitMap units;
        for (const auto& text : devices) {
            auto address = device::parse_device_address(text);
            if (!address) throw std::runtime_error(address.error().message);
            units.emplace(static_cast<std::uint8_t>(address->unit), device::models::make_simulated_device(address->profile));
            addresses_.push_back(*address);
        }
        slave_port_ = bus_->attach("slave");
        slave_ = std::make_unique<session::Slave>(*link, units);
        server_ = std::jthread([this](std::stop_token stop) { (void)slave_->serve_stream(*slave_port_, stop); });
        // The test asks one master at a time, so the two slaves never run a device at once.
        clean_bus_ = transport::VirtualBus::create(link->serial.baud, 10);
        clean_slave_port_ = clean_bus_->attach("slave");
        clean_slave_ = std::make_unique<session::Slave>(*link, std::move(units));
        clean_server_ = std::jthread([this](std::stop_token stop) { (void)clean_slave_->serve_stream(*clean_slave_port_, stop); });
        session::MasterOptions options;
        options.timeout = timeout;
        options.retries = 0;  // every fault reaches the code under test
        master_ = session::make_serial_master(bus_->attach("master"), *link, options);
        // The clean path retries: a loaded test machine can stretch a frame past its gaps.
        options.retries = 3;
        clean_master_ = session::make_serial_master(clean_bus_->attach("checker"), *link, options);
    }
    ~FaultyBusRig() {
        for (auto* server : {&server_, &clean_server_}) {
            server->request_stop();
            server->join();
        }
    }
    FaultyBusRig(const FaultyBusRig&) = delete;
    FaultyBusRig& operator=(const FaultyBusRig&) = delete;

    session::Master& master() { return *master_; }
    const device::DeviceAddress& address(std::size_t index) const { return addresses_.at(index); }
    device::DeviceClient client(std::size_t index) { return device::DeviceClient(*master_, addresses_.at(index)); }
    // Through a second master, on the clean bus, whose frames never meet a fault (use it only
    // while the faulty master is idle: the devices are the same).
    device::DeviceClient clean_client(std::size_t index) { return device::DeviceClient(*clean_master_, addresses_.at(index)); }

    void inject(FaultPolicy policy) {
        std::lock_guard lock(mutex_);
        policy_ = std::move(policy);
        writes_ = 0;
    }
    void heal() { inject({}); }

private:
    transport::BusFault fault_for(const std::string& from, ByteView bytes) {
        std::lock_guard lock(mutex_);
        if (!policy_) return {};
        return policy_(from, bytes, writes_++);
    }

    // First, so they outlive every port that may still consult them.
    std::mutex mutex_;
    FaultPolicy policy_;
    unsigned writes_ = 0;
    std::shared_ptr<transport::VirtualBus> bus_;
    std::vector<device::DeviceAddress> addresses_;
    std::unique_ptr<transport::ByteStream> slave_port_;
    std::unique_ptr<session::Slave> slave_;
    std::jthread server_;
    std::shared_ptr<transport::VirtualBus> clean_bus_;
    std::unique_ptr<transport::ByteStream> clean_slave_port_;
    std::unique_ptr<session::Slave> clean_slave_;
    std::jthread clean_server_;
    std::unique_ptr<session::Master> master_;
    std::unique_ptr<session::Master> clean_master_;
};

}  // namespace loopwire::app::testing
