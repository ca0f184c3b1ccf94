// The alarm engine's cost at a plant's scale: 256 devices x 40 parameters, a limit alarm on each
// (10,240, of every kind, with deadbands and delays), every value read again every second as the
// polls would, and the engine ticked each second. Run on virtual time as fast as it goes; the
// figures are the engine's CPU time per evaluation, the share of one core that evaluating every
// value once a second takes (goal: under 1 %), and the resident memory the alarms take.
//
//   alarm_engine [SECONDS]      simulated seconds, 120 by default
#include <time.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "gateway/alarms/alarm_engine.hpp"

namespace {

using namespace loopwire::gateway::alarms;
using namespace std::chrono_literals;

constexpr int devices = 256;
constexpr int parameters = 40;

long resident_kib() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line)) {
        if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    }
    return 0;
}

double cpu_seconds() {
    timespec now{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) / 1e9;
}

std::string device_name(int d) { return fmt::format("device{:03}", d); }
std::string parameter_name(int p) { return fmt::format("parameter_{:02}", p); }

// A value that wanders across its limit every few minutes, differently for each parameter.
double value_at(int d, int p, int second) {
    return 100.0 + 12.0 * std::sin((second + d * 7 + p * 13) / (20.0 + p));
}

}  // namespace

int main(int argc, char** argv) {
    const int seconds = argc > 1 ? std::atoi(argv[1]) : 120;
    if (seconds < 1) {
        std::fprintf(stderr, "usage: alarm_engine [SECONDS]\n");
        return 2;
    }
    const long before_kib = resident_kib();
    std::vector<LimitAlarm> limits;
    std::vector<std::string> names;
    for (int d = 0; d < devices; ++d) {
        names.push_back(device_name(d));
        for (int p = 0; p < parameters; ++p) {
            LimitAlarm alarm;
            alarm.device = names.back();
            alarm.parameter = parameter_name(p);
            alarm.kind = p % 4 == 0 ? LimitKind::high : p % 4 == 1 ? LimitKind::high_high : p % 4 == 2 ? LimitKind::low : LimitKind::low_low;
            alarm.limit = p % 4 < 2 ? 108.0 : 92.0;
            alarm.deadband = 1.0;
            alarm.on_delay = p % 3 == 0 ? 5s : 0s;
            alarm.off_delay = p % 5 == 0 ? 3s : 0s;
            alarm.name = fmt::format("{}_{}", alarm.parameter, name_of(alarm.kind));
            limits.push_back(std::move(alarm));
        }
    }
    AlarmEngine engine(std::move(limits), names);
    const long built_kib = resident_kib();
    // The names as the cache's changes carry them: made once, as the polls' are.
    std::vector<std::string> parameter_names;
    for (int p = 0; p < parameters; ++p) parameter_names.push_back(parameter_name(p));
    const Time start = Time(std::chrono::seconds(1767225600));
    std::size_t transitions = 0;
    std::size_t evaluations = 0;
    const double cpu_start = cpu_seconds();
    for (int second = 0; second < seconds; ++second) {
        const Time now = start + std::chrono::seconds(second);
        for (int d = 0; d < devices; ++d) {
            for (int p = 0; p < parameters; ++p) {
                transitions += engine.feed(names[static_cast<std::size_t>(d)], parameter_names[static_cast<std::size_t>(p)],
                                           value_at(d, p, second), "ok", "°C", now).size();
                ++evaluations;
            }
        }
        transitions += engine.tick(now).size();
    }
    const double cpu = cpu_seconds() - cpu_start;
    const double per_evaluation_ns = cpu / static_cast<double>(evaluations) * 1e9;
    const double core_share = cpu / seconds * 100.0;
    fmt::print("alarms: {} limit alarms + {} communication alarms on {} devices\n", devices * parameters, engine.size() -
               static_cast<std::size_t>(devices * parameters), devices);
    fmt::print("evaluated: {} values over {} simulated seconds, {} transitions\n", evaluations, seconds, transitions);
    fmt::print("cost per evaluation: {:.0f} ns\n", per_evaluation_ns);
    fmt::print("share of one core at every value once a second: {:.3f} % (goal under 1 %)\n", core_share);
    fmt::print("resident memory of the engine: {} KiB ({:.0f} bytes an alarm)\n", built_kib - before_kib,
               static_cast<double>(built_kib - before_kib) * 1024.0 / static_cast<double>(engine.size()));
    return core_share < 1.0 ? 0 : 1;
}
