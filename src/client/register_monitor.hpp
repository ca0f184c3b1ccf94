#pragma once
// Raw registers of a device without a profile, read once or polled on the monitors' one loop
// (client/monitor_loop.hpp): what `loopwire read` and `loopwire monitor` do with TABLE ADDRESS
// [COUNT], apart from parsing it and showing the numbers the registers hold.
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <stop_token>
#include <vector>

#include "client/link.hpp"
#include "client/monitor_loop.hpp"
#include "codec/pdu.hpp"
#include "common/result.hpp"

namespace loopwire::device {

struct RegisterRange {
    std::uint8_t unit = 1;
    codec::FunctionCode function = codec::FunctionCode::read_holding_registers;  // one of the four reads
    std::uint16_t wire_address = 0;
    unsigned count = 1;        // registers (or bits)
    unsigned per_request = 1;  // the most one request may ask for (1 on a Linking link)
};

// Reads the range in as few requests as `per_request` allows, in address order; the first
// failure ends it.
Result<std::vector<std::uint16_t>> read_registers(Master& master, const RegisterRange& range);

// One poll of the range: the words, or the error that left them unread.
struct RegisterSample {
    unsigned index = 0;  // 1-based
    std::chrono::system_clock::time_point time;
    std::vector<std::uint16_t> words;  // empty when `error` is set
    std::optional<Error> error;
    unsigned errors = 0;  // failed polls so far, this one included
};

// Polls the range once per settings.interval on the monitors' fixed schedule, handing each
// sample to `sink`, until settings.count samples or `stop`. A unit that does not answer costs
// one timeout per sample and the polling goes on.
void run_register_monitor(Master& master, const RegisterRange& range, const MonitorSettings& settings,
                          const std::function<void(const RegisterSample&)>& sink, const std::stop_token& stop);

}  // namespace loopwire::device
