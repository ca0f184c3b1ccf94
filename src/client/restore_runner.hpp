#pragma once
// Runs a restore plan (device/restore_plan.hpp) on a device: the stages in order, then every
// changed value read back. Apart from `loopwire restore` so it can be driven on a faulty bus.
// A failure stops at once and says which values are known written, which are not, and which
// may or may not be (a write whose reply never came); a device left in configuration or
// security-code mode is sent back to control mode (AC20 word 3051 = 1, Note 7).
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "client/device_client.hpp"
#include "client/restore_plan.hpp"

namespace loopwire::device {

struct RestoreOutcome {
    std::optional<Error> error;              // none: every change written and read back equal
    std::vector<std::string> written;        // acknowledged by the device
    std::vector<std::string> uncertain;      // sent, but no valid reply: may or may not be in
    std::vector<std::string> not_written;    // never sent
    std::optional<std::string> return_to_control;  // what happened when leaving a special mode
};

// Prints "[i/n] stage" lines to `progress` while it runs.
RestoreOutcome execute_restore(device::DeviceClient& client, const device::RestorePlan& plan, std::FILE* progress);

// The lines `loopwire restore` prints on stderr for a failed outcome.
void print_restore_failure(const RestoreOutcome& outcome, std::FILE* out);

}  // namespace loopwire::device
