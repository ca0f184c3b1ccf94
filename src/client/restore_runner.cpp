#include "client/restore_runner.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "profile/request_planner.hpp"

namespace loopwire::device {
namespace {

std::string listed(const std::vector<std::string>& names) {
    return names.empty() ? "nothing" : fmt::format("{}", fmt::join(names, ", "));
}

// An exception reply is the device saying no: that write did not happen. Anything else (no
// reply, a corrupted or mismatched reply, a broken link) leaves it open whether it did.
bool outcome_unknown(const Error& error) { return error.kind != ErrorKind::exception; }

struct StageRun {
    RestoreOutcome& outcome;
    bool in_special_mode = false;
};

// One block (one request) at a time, so a failure knows exactly which values went before it.
Result<void> run_stage(device::DeviceClient& client, const device::RestoreStage& stage, StageRun& run) {
    const auto& device = client.device();
    for (const device::WriteBlock& block : device::plan_writes(*device.profile, stage.writes, device.address_offset)) {
        std::vector<device::PlannedWrite> writes;
        for (std::size_t i = 0; i < block.parameters.size(); ++i) writes.push_back({block.parameters[i], block.values[i]});
        auto done = client.write_raw(writes);
        if (!done) {
            if (stage.restores_values && outcome_unknown(done.error())) {
                for (const auto& write : writes) run.outcome.uncertain.push_back(write.parameter->name);
            }
            // A mode entry whose reply was lost may have switched the mode: leave it to be sure.
            if (stage.mode_effect == device::ModeEffect::enters_special_mode && outcome_unknown(done.error())) run.in_special_mode = true;
            return client.explain(done.error());
        }
        if (stage.restores_values) {
            for (const auto& write : writes) run.outcome.written.push_back(write.parameter->name);
        }
    }
    if (stage.mode_effect == device::ModeEffect::enters_special_mode) run.in_special_mode = true;
    if (stage.mode_effect == device::ModeEffect::leaves_special_mode) run.in_special_mode = false;
    return {};
}

Result<void> run_stages(device::DeviceClient& client, const device::RestorePlan& plan, StageRun& run, std::FILE* progress) {
    std::size_t index = 0;
    for (const auto& stage : plan.stages) {
        fmt::print(progress, "[{}/{}] {}\n", ++index, plan.stages.size(), stage.title);
        if (auto done = run_stage(client, stage, run); !done) return done;
    }
    return {};
}

// Every changed value read back; a device that kept another value is a failed restore.
Result<void> verify(device::DeviceClient& client, const device::RestorePlan& plan) {
    std::vector<const device::Parameter*> changed;
    for (const auto& change : plan.changes) changed.push_back(change.parameter);
    const auto report = client.read(changed);
    if (report.first_error) return make_error(report.first_error->kind, "reading back failed: " + report.first_error->message);
    std::vector<std::string> differing;
    for (const auto& change : plan.changes) {
        const auto raw = report.raw.find(change.parameter->name);
        if (raw == report.raw.end() || raw->second != change.to) differing.push_back(change.parameter->name);
    }
    if (!differing.empty()) {
        return make_error(ErrorKind::mismatch, fmt::format("written but read back different: {}", fmt::join(differing, ", ")));
    }
    return {};
}

// AC20 Note 5: after 3 s without line activity the device is back in local and refuses word
// 3051, so the way back claims remote (bit 218) first; Note 7: 3051 = 1 ends configuration mode.
// Tried three times: the same line just failed once, and a device left in configuration mode
// does not control its process.
std::string return_to_control(device::DeviceClient& client, const device::PlannedWrite& back) {
    std::vector<device::PlannedWrite> writes;
    if (const device::Parameter* remote = client.device().profile->find("local_remote")) writes.push_back({remote, 1});
    writes.push_back(back);
    constexpr int attempts = 3;
    Result<device::WriteReport> done = make_error(ErrorKind::link, "not tried");
    for (int attempt = 0; attempt < attempts && !done; ++attempt) done = client.write_raw(writes);
    return done ? "returned the device to control mode (word 3051 = 1)"
                : fmt::format("could not return the device to control mode in {} tries: {}", attempts, done.error().message);
}

void sort_out_not_written(const device::RestorePlan& plan, RestoreOutcome& outcome) {
    const auto among = [](const std::vector<std::string>& names, const std::string& name) {
        return std::find(names.begin(), names.end(), name) != names.end();
    };
    for (const auto& change : plan.changes) {
        const std::string& name = change.parameter->name;
        if (!among(outcome.written, name) && !among(outcome.uncertain, name)) outcome.not_written.push_back(name);
    }
}

}  // namespace

RestoreOutcome execute_restore(device::DeviceClient& client, const device::RestorePlan& plan, std::FILE* progress) {
    RestoreOutcome outcome;
    StageRun run{outcome};
    auto result = run_stages(client, plan, run, progress);
    if (result) result = verify(client, plan);
    if (result) return outcome;
    outcome.error = result.error();
    sort_out_not_written(plan, outcome);
    if (run.in_special_mode && plan.back_to_control) outcome.return_to_control = return_to_control(client, *plan.back_to_control);
    return outcome;
}

void print_restore_failure(const RestoreOutcome& outcome, std::FILE* out) {
    if (!outcome.error) return;
    fmt::print(out, "loopwire: restore stopped: {}\n", outcome.error->message);
    fmt::print(out, "loopwire: written: {}\n", listed(outcome.written));
    if (!outcome.uncertain.empty()) fmt::print(out, "loopwire: sent without a valid reply (may or may not be written): {}\n", listed(outcome.uncertain));
    fmt::print(out, "loopwire: not written: {}\n", listed(outcome.not_written));
    if (outcome.return_to_control) fmt::print(out, "loopwire: {}\n", *outcome.return_to_control);
}

}  // namespace loopwire::device
