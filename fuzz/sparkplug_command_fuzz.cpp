// The Sparkplug B node's command path (gateway/sparkplug/sparkplug_payloads.hpp) on arbitrary
// bytes, as a peer could publish them to an NCMD or DCMD topic: decoded with protobuf, each
// metric turned into the text `loopwire write` takes for the TC10's set point (a Double metric)
// and control state (an enumeration's String metric). Properties: it never throws or aborts;
// a payload protobuf refuses is an error, never metrics; every refusal's message holds no
// control byte and stays short whatever the payload held.
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"
#include "gateway/sparkplug/sparkplug_payloads.hpp"
#include "profile/profile.hpp"

using namespace loopwire;
using namespace loopwire::gateway::sparkplug;

namespace {

std::vector<MetricDefinition> tc10_metrics() {
    static const auto profile = device::builtin_profile("tc10");
    fuzz::check(profile.ok(), "the TC10 profile loads");
    std::uint64_t alias = 1;
    std::vector<MetricDefinition> metrics;
    for (const char* name : {"set_point", "control_state", "alarm_status"}) {
        const device::Parameter* parameter = (*profile)->find(name);
        fuzz::check(parameter != nullptr, "the TC10 profile has the fuzzed parameters");
        auto each = parameter_metrics(*parameter, alias);
        metrics.insert(metrics.end(), each.begin(), each.end());
    }
    return metrics;
}

bool printable(std::string_view text) {
    for (const char c : text) {
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const auto metrics = tc10_metrics();
    auto decoded = decode_command(std::string_view(reinterpret_cast<const char*>(data), size));
    if (!decoded) {
        fuzz::check(printable(decoded.error().message), "a refused payload's message has no control byte");
        return 0;
    }
    for (const auto& command : *decoded) {
        for (const auto& metric : metrics) {
            auto text = write_text(metric, command.value);
            if (text) continue;
            fuzz::check(printable(text.error().message), "a refused write's message has no control byte");
            fuzz::check(text.error().message.size() < 400, "a refused write's message stays short");
        }
    }
    return 0;
}
