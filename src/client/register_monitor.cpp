#include "client/register_monitor.hpp"

#include <algorithm>

namespace loopwire::device {

Result<std::vector<std::uint16_t>> read_registers(Master& master, const RegisterRange& range) {
    std::vector<std::uint16_t> values;
    while (values.size() < range.count) {
        const auto chunk = static_cast<std::uint16_t>(std::min<std::size_t>(range.per_request, range.count - values.size()));
        const auto at = static_cast<std::uint16_t>(range.wire_address + values.size());
        auto reply = master.execute(range.unit, codec::read_request(range.function, at, chunk));
        if (!reply) return reply.error();
        values.insert(values.end(), reply->values.begin(), reply->values.end());
    }
    return values;
}

void run_register_monitor(Master& master, const RegisterRange& range, const MonitorSettings& settings,
                          const std::function<void(const RegisterSample&)>& sink, const std::stop_token& stop) {
    RegisterSample sample;
    SampleSteps steps;
    steps.poll = [&](unsigned) {
        sample.words.clear();
        sample.error.reset();
        auto words = read_registers(master, range);
        if (words) {
            sample.words = std::move(*words);
        } else {
            sample.error = words.error();
            ++sample.errors;
        }
    };
    steps.write = [&](unsigned index, std::chrono::system_clock::time_point time, unsigned) {
        sample.index = index;
        sample.time = time;
        sink(sample);
    };
    run_sample_schedule(settings, steps, stop);
}

}  // namespace loopwire::device
