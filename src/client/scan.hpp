#pragma once
// Finding the units that answer on a link, optionally sweeping serial line settings, and naming
// each by the profiles' identification words: the engine of `loopwire scan`, which only parses
// its options and prints what this reports as it goes.
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <stop_token>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/result.hpp"
#include "session/master.hpp"
#include "transport/link_url.hpp"

namespace loopwire::device {

struct FoundUnit {
    int unit = 0;
    std::string line;    // the first line setting it answered at ("9600 8N1", or the URL of a network link)
    std::string device;  // the profile id its identification words matched; empty: an unknown Modbus device
    nlohmann::ordered_json identification = nlohmann::ordered_json::object();
    std::vector<std::string> lines;  // every line setting it answered at, in the order tried
    // What the unit said of itself through Read Device Identification (43/14): object names
    // and values; null where it does not implement it.
    nlohmann::ordered_json device_identity = nullptr;
};

// What a scan tells while it runs, each on the scanning thread; any may be left empty.
struct ScanEvents {
    // Before unit `unit` (the index-th of `total`) is tried at `line`; `found` so far.
    std::function<void(const std::string& line, int unit, std::size_t index, std::size_t total, std::size_t found)> trying;
    // A unit answered: new, or found before at another setting (then `lines` has more than one).
    std::function<void(const FoundUnit& unit)> found;
    // Every unit was tried at `line`: `answered` of them answered, and `garbled` runs of bytes
    // were thrown away (CRC errors and the like: the usual sign of a wrong baud rate or parity).
    std::function<void(const std::string& line, std::size_t answered, unsigned garbled)> line_done;
};

struct ScanResult {
    std::vector<FoundUnit> found;                   // each device once, in the order found
    std::vector<std::vector<int>> found_per_line;   // the units that answered at each setting tried
    std::size_t gateway_refusals = 0;               // units a gateway said nothing answers behind (0Ah, 0Bh)
    bool interrupted = false;                       // stopped before every unit was tried
};

// Opens a master on one line setting; session::open_master unless a test wires its own.
using MasterOpener = std::function<Result<std::unique_ptr<session::Master>>(const transport::LinkUrl&, session::MasterOptions)>;

class UnitScan {
public:
    // The settings to try: the link's own, or every baud rate and parity of the sweep (each list
    // empty: the link's own). A sweep of a network link, an unsupported baud rate or a parity
    // other than none, even or odd (n, e, o) is a usage error.
    static Result<UnitScan> plan(const std::string& link, const std::vector<std::string>& bauds,
                                 const std::vector<std::string>& parities);

    // The settings as people read them: "9600 8N1", or the URL of a network link.
    std::vector<std::string> settings_text() const;
    // The settings as links, in the same order.
    const std::vector<transport::LinkUrl>& settings() const { return settings_; }

    // Tries every unit at every setting, each with one read of holding register 0 waiting at
    // most `timeout`: any answer, an exception included, proves a unit is there (the TC10
    // refuses address 0 with exception 2); silence, and a gateway's 0Ah or 0Bh, mean nobody.
    // Each unit found is identified (by profile, and by Read Device Identification where it
    // has it), and listed once however many settings it answered at.
    // `trace` sees every frame. A link that cannot be opened ends the scan with its error.
    Result<ScanResult> run(const std::vector<int>& units, std::chrono::milliseconds timeout, const session::TraceSink& trace,
                           const ScanEvents& events, const std::stop_token& stop, const MasterOpener& open = {}) const;

private:
    explicit UnitScan(std::vector<transport::LinkUrl> settings) : settings_(std::move(settings)) {}
    std::vector<transport::LinkUrl> settings_;
};

// The units found at each line setting tried, in order. True when more than one setting was tried
// and every one found the same units, at least one: real devices answer at their own baud and
// parity only, so the same answers at every setting mean the line does not apply them (a
// pseudo-terminal, a TCP converter with fixed settings).
bool ignores_line_settings(const std::vector<std::vector<int>>& found_per_setting);

}  // namespace loopwire::device
