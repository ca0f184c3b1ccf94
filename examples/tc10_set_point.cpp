// Starts a simulated Yokogawa TC10 on a free TCP port, reads its measured value and set point
// by name, writes a new set point, and reads it back.
//   tc10_set_point [SET_POINT]     (default 150; the simulated TC10 shows no decimals)
#include <iostream>
#include <string>

#include <loopwire/loopwire.hpp>

namespace {

// The TC10's temperatures carry no unit in its profile: the device's own temperature_unit
// word says whether they are in °C or °F (manual §5.3.1 #5).
std::string unit_of(const loopwire::Reading& reading, const std::string& temperature_unit) {
    return reading.unit.empty() ? temperature_unit : reading.unit;
}

void print(const loopwire::Reading& reading, const std::string& temperature_unit) {
    std::cout << reading.name << " (" << reading.mnemonic << ") = " << reading.text << ' '
              << unit_of(reading, temperature_unit);
    if (reading.status != "ok") std::cout << " [" << reading.status << ']';
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
        const std::string temperature_unit = "°" + oven.read("temperature_unit").text;

        print(oven.read("measured_value"), temperature_unit);
        print(oven.read("set_point"), temperature_unit);
        oven.write("set_point", set_point);
        std::cout << "wrote set_point = " << set_point << '\n';
        print(oven.read("set_point"), temperature_unit);

        simulator.stop();
    } catch (const loopwire::Failure& failure) {
        std::cerr << "tc10_set_point: " << failure.what() << '\n';
        return 1;
    }
    return 0;
}
