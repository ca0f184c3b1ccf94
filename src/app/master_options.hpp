#pragma once
// The options every master-side subcommand takes: --link, --unit, --timeout, --retries, -v.
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "client/link.hpp"
#include "common/result.hpp"

namespace loopwire::app {

struct MasterCommandOptions {
    std::string link;
    int unit = 1;
    std::string device;     // DEVICE@UNIT: talk by parameter name through a profile
    std::string numbering;  // a profile's alternative numbering (AC20: jbus)
    std::string timeout = "1s";
    unsigned retries = 0;
    bool verbose = false;
    bool json = false;
    bool no_identify = false;  // with --device: skip the check that the unit is that device

    // `with_device`: also --device DEVICE@UNIT and --numbering (named read/write).
    void add_to(CLI::App& command, bool with_device = false);
    // --no-identify, for the commands that check the unit is the device named (read, write).
    void add_identify_to(CLI::App& command);
    // Parses the link URL and the durations, opens the link and builds the master. With -v,
    // frames are traced to `trace`, or to stderr when it is empty.
    Result<std::unique_ptr<device::Master>> open(device::TraceSink trace = {}) const;
};

}  // namespace loopwire::app
