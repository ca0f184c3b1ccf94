// The restore runner (client/restore_runner.hpp) on a faulty bus (client/faulty_bus_rig.hpp). The faults
// hit each frame of the restore in turn: a dropped request, a dropped reply, a corrupted reply.
// Whatever happens, the outcome is honest, checked through the clean bus afterwards: success
// only when every value is back; otherwise each change is named exactly once as written (and
// is back), not written (and still the changed value) or uncertain (its reply was lost).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <memory>

#include "client/restore_runner.hpp"
#include "client/faulty_bus_rig.hpp"
#include "devices/registry.hpp"

namespace loopwire::app {
namespace {

using namespace std::chrono_literals;
using testing::FaultyBusRig;
using Assignments = std::vector<std::pair<std::string, std::string>>;

device::RawValues read_raw(device::DeviceClient& client, const std::vector<std::string>& names) {
    std::vector<const device::Parameter*> parameters;
    for (const auto& name : names) parameters.push_back(client.device().profile->find(name));
    const auto report = client.read(parameters);
    EXPECT_FALSE(report.first_error) << report.first_error->message;
    return report.raw;
}

// One call per assignment: the client checks the AC20's mode before each (Notes 5-7), so a
// mode step must have happened before the write that needs it is checked.
void write_all(device::DeviceClient& client, const Assignments& assignments) {
    for (const auto& [name, text] : assignments) {
        auto written = client.write({{client.device().profile->find(name), text}});
        ASSERT_TRUE(written.ok()) << name << ": " << written.error().message;
    }
}

enum class Fault { drop_request, drop_reply, corrupt_reply };

struct Counted {
    Fault fault;
    unsigned frame;  // which request of the restore (0-based) is hit
    unsigned requests = 0;
};

// The n-th request dropped, or the reply to it dropped or corrupted.
testing::FaultPolicy hit(Fault fault, unsigned frame) {
    auto state = std::make_shared<Counted>(Counted{fault, frame});
    return [state](const std::string& from, ByteView bytes, unsigned) {
        transport::BusFault result;
        if (from == "master") {
            const unsigned index = state->requests++;
            result.drop = index == state->frame && state->fault == Fault::drop_request;
        } else if (state->requests == state->frame + 1) {
            result.drop = state->fault == Fault::drop_reply;
            if (state->fault == Fault::corrupt_reply) result.corrupt_bytes = {bytes.size() - 3};
        }
        return result;
    };
}

// Each fault met costs a whole restore (the AC20's test runs 45 of them), and the virtual bus
// takes its wire time in real time: at 38400 baud a quarter of 9600's. The speed plays no part in what is
// tested here, the order of the writes and the honesty of the outcome.
constexpr std::uint32_t restore_baud = 38400;

struct Tally {
    unsigned completed = 0;
    unsigned stopped = 0;
};

// Restores `saved` over `changed` with one fault at each request in turn, until a run completes:
// with no retries every fault met stops the restore, so a completed run sent fewer requests
// than the one hit, and so will every later one.
template <typename Check>
Tally restore_under_each_fault(FaultyBusRig& rig, const device::RawValues& saved, const Assignments& changed,
                               const std::vector<std::string>& names, Check check_after) {
    Tally tally;
    for (Fault fault : {Fault::drop_request, Fault::drop_reply, Fault::corrupt_reply}) {
        for (unsigned frame = 0; frame < 40; ++frame) {
            auto client = rig.client(0);
            auto clean = rig.clean_client(0);
            rig.heal();
            write_all(clean, changed);
            const auto current = read_raw(clean, names);
            auto plan = device::plan_restore(*client.device().profile, saved, current, {},
                                             device::models::restore_procedure_for(*client.device().profile));
            if (!plan) {
                ADD_FAILURE() << plan.error().message;
                return tally;
            }
            rig.inject(hit(fault, frame));
            std::unique_ptr<std::FILE, int (*)(std::FILE*)> progress(std::tmpfile(), &std::fclose);
            const device::RestoreOutcome outcome = device::execute_restore(client, *plan, progress.get());
            rig.heal();
            const auto after = read_raw(clean, names);
            SCOPED_TRACE(::testing::Message() << "fault " << static_cast<int>(fault) << " at request " << frame << "; "
                                              << (outcome.error ? outcome.error->message : "completed") << "; "
                                              << outcome.return_to_control.value_or("no return to control mode"));
            check_after(clean);
            if (!outcome.error) {
                ++tally.completed;
                for (const auto& change : plan->changes) EXPECT_EQ(after.at(change.parameter->name), change.to) << change.parameter->name;
                break;  // no fault met (with no retries every fault stops it): later frames see none either
            }
            ++tally.stopped;
            EXPECT_FALSE(outcome.error->message.empty());
            for (const auto& change : plan->changes) {
                const std::string& name = change.parameter->name;
                const auto count = [&](const std::vector<std::string>& list) { return std::count(list.begin(), list.end(), name); };
                EXPECT_EQ(count(outcome.written) + count(outcome.uncertain) + count(outcome.not_written), 1) << name;
                if (count(outcome.written)) {
                    EXPECT_EQ(after.at(name), change.to) << name << " reported written";
                }
                if (count(outcome.not_written)) {
                    EXPECT_EQ(after.at(name), change.from) << name << " reported not written";
                }
            }
        }
    }
    return tally;
}

// TC10 (§5.3.8): SP within SP.LL..SP.HL; the changed SP.HL is below the saved SP, so the plan
// raises SP.HL before SP goes back, and a stop between the two must leave both as reported.
TEST(RestoreOnFaultyBus, Tc10StopsHonestlyOrCompletesWithEveryValueBack) {
    FaultyBusRig rig({"tc10@3"}, 100ms, restore_baud);
    auto client = rig.client(0);
    // With the words that bound them (SP.LL, AL1L/AL1H) and dP, so the plan can order the writes.
    const std::vector<std::string> names{"set_point", "set_point_high_limit", "alarm_1_threshold", "proportional_band", "integral_time",
                                         "set_point_low_limit", "alarm_1_low_limit", "alarm_1_high_limit", "decimal_point"};
    const auto saved = read_raw(client, names);
    const Assignments changed{{"set_point", "100"}, {"set_point_high_limit", "150"}, {"alarm_1_threshold", "40"},
                              {"proportional_band", "33"}, {"integral_time", "99"}};
    const auto tally = restore_under_each_fault(rig, saved, changed, names, [](device::DeviceClient&) {});
    EXPECT_GT(tally.completed, 0u);
    EXPECT_GT(tally.stopped, 3u);
}

// AC20 Notes 5-7: a restore that stops anywhere, even between entering configuration mode
// (word 347) and leaving it (word 3051), leaves the device in control mode (word 135 = 0).
TEST(RestoreOnFaultyBus, Ac20StopsInControlModeOrCompletes) {
    FaultyBusRig rig({"ac20@1"}, 100ms, restore_baud);
    auto client = rig.clean_client(0);
    const std::vector<std::string> names{"probe_input_filter", "bar_graph_high", "auxiliary_set_point_2", "proportional_band",
                                         "set_point_low_limit", "set_point_high_limit", "primary_variable_decimals"};
    const auto saved = read_raw(client, names);
    const Assignments changed{{"local_remote", "remote"}, {"configuration_mode_code", "0"}, {"probe_input_filter", "7"},
                              {"end_configuration_menu_1", "1"}, {"bar_graph_high", "1.50"}, {"end_configuration_menu_6", "1"},
                              {"enable_control_mode", "1"}, {"local_remote", "remote"}, {"auxiliary_set_point_2", "1.25"},
                              {"proportional_band", "55"}};
    const auto in_control_mode = [](device::DeviceClient& c) {
        const auto status = read_raw(c, {"device_status"});
        EXPECT_EQ(status.at("device_status"), 0) << "word 135: not in control mode";
    };
    const auto tally = restore_under_each_fault(rig, saved, changed, names, in_control_mode);
    EXPECT_GT(tally.completed, 0u);
    EXPECT_GT(tally.stopped, 3u);
}

}  // namespace
}  // namespace loopwire::app
