// Starts a simulated Yokogawa TC10 on a free TCP port, reads its measured value and set point
// by name, writes a new set point, and reads it back.
//   tc10_set_point [SET_POINT]     (default 150; the simulated TC10 shows no decimals)
#include <iostream>
#include <string>

#include <loopwire/loopwire.hpp>

namespace {

// The unit is the device's own: a TC10's temperatures follow its temperature_unit word (°C or
// °F, manual §5.3.1 #5), which the read takes with the value.
void print(const loopwire::Reading& reading) {
    std::cout << reading.name << " (" << reading.mnemonic << ") = " << reading.text << ' ' << reading.unit;
    if (reading.state != loopwire::ValueStatus::ok) std::cout << " [" << reading.status << ']';
    if (reading.min && reading.max) std::cout << " (" << *reading.min << " to " << *reading.max << ')';
    std::cout << '\n';
}

}  // namespace

int main(int argc, char** argv) {
    const std::string set_point = argc > 1 ? argv[1] : "150";
    try {
        std::cout << "loopwire " << loopwire::version() << '\n';
        loopwire::Simulator simulator = loopwire::Simulator::start("tcp://127.0.0.1:0", {"tc10@3"});
        std::cout << "simulating tc10@3 on " << simulator.url() << '\n';

        loopwire::Link link = loopwire::Link::open(simulator.url());
        loopwire::Device oven(link, "tc10@3");

        print(oven.read("measured_value"));
        print(oven.read("set_point"));
        oven.write("set_point", set_point);
        std::cout << "wrote set_point = " << set_point << '\n';
        print(oven.read("set_point"));

        simulator.stop();
    } catch (const loopwire::Failure& failure) {
        std::cerr << "tc10_set_point: " << failure.what() << '\n';
        return 1;
    }
    return 0;
}
