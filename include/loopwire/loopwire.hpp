#pragma once
// loopwire for C++ programs: open a link by URL, name a device, read and write its parameters
// by name in engineering units, and serve simulated devices.
//
//   #include <loopwire/loopwire.hpp>
//   loopwire::Link link = loopwire::Link::open("tcp://127.0.0.1:1502");
//   loopwire::Device oven(link, "tc10@3");
//   loopwire::Reading pv = oven.read("measured_value");
//   oven.write("set_point", "150");
//
// Every call that can fail throws loopwire::Failure, whose message says what was wrong.
#include <loopwire/device.hpp>
#include <loopwire/failure.hpp>
#include <loopwire/link.hpp>
#include <loopwire/simulator.hpp>
#include <loopwire/version.hpp>
