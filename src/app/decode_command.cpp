// loopwire decode --protocol rtu|ascii|tcp|linking [--direction request|reply] HEX... [--json]
// Explains one frame. Exit 0 for a valid frame, 1 for an invalid one (with the reason).
#include <string>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/frame_explanation.hpp"
#include "codec/pdu.hpp"

namespace loopwire::app {
namespace {

struct DecodeOptions {
    std::string protocol = "rtu";
    std::string direction;
    std::vector<std::string> frame;
    bool json = false;
};

// ASCII frames may be given as their text (":0103008A000171") or as the hex of the characters.
Result<Bytes> wire_bytes(const DecodeOptions& options) {
    std::string joined;
    for (const auto& part : options.frame) joined += part;
    if (options.protocol == "ascii" && !joined.empty() && joined.front() == ':') {
        if (joined.size() < 2 || joined.substr(joined.size() - 2) != "\r\n") joined += "\r\n";
        return Bytes(joined.begin(), joined.end());
    }
    std::string spaced;
    for (const auto& part : options.frame) spaced += part + " ";
    auto bytes = parse_hex(spaced);
    if (!bytes || bytes->empty()) {
        const auto why = hex_problem(spaced);
        return make_error(ErrorKind::usage, fmt::format("'{}' is not a frame in hex{} (like 01 03 00 8A 00 01 A5 E0)", spaced,
                                                        why ? ": " + *why : std::string()));
    }
    return std::move(*bytes);
}

void print_text(const FrameExplanation& e) {
    fmt::print("protocol   {}\n", e.protocol);
    if (e.transaction) fmt::print("transaction {}\n", *e.transaction);
    if (e.unit) fmt::print("unit       {}\n", *e.unit);
    if (e.command) fmt::print("command    {}\n", *e.command);
    // The function and exception codes were each read from one byte of the frame.
    if (e.function) fmt::print("function   {} ({})\n", *e.function, codec::function_name(static_cast<std::uint8_t>(*e.function)));
    if (!e.kind.empty()) fmt::print("kind       {}\n", e.kind);
    if (e.address) fmt::print("address    {} (0x{:04X})\n", *e.address, *e.address);
    if (e.count) fmt::print("count      {}\n", *e.count);
    if (!e.values.empty()) fmt::print("values     {}\n", fmt::join(e.values, " "));
    if (e.exception) fmt::print("exception  {}\n", codec::describe_exception(static_cast<std::uint8_t>(*e.exception)));
    fmt::print("check      {}\n", e.check_ok ? "ok" : "BAD");
    if (!e.problem.empty()) fmt::print("invalid    {}\n", e.problem);
}

int run_decode(const DecodeOptions& options) {
    auto bytes = wire_bytes(options);
    if (!bytes) return report_error(bytes.error());
    auto explanation = explain_frame(options.protocol, options.direction, *bytes);
    if (!explanation) return report_error(explanation.error());
    if (options.json) {
        fmt::print("{}\n", to_json(*explanation).dump());
    } else {
        print_text(*explanation);
    }
    if (!explanation->problem.empty()) {
        fmt::print(stderr, "loopwire: invalid frame: {}\n", explanation->problem);
        return exit_invalid_frame;
    }
    return exit_ok;
}

}  // namespace

void add_decode_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<DecodeOptions>();
    auto* command = app.add_subcommand("decode", "Explain one frame given in hex");
    command->add_option("--protocol", options->protocol, "rtu, ascii, tcp or linking")
        ->check(CLI::IsMember({"rtu", "ascii", "tcp", "linking"}))
        ->capture_default_str();
    command->add_option("--direction", options->direction, "request or reply (default: whichever the frame is)")
        ->check(CLI::IsMember({"request", "reply"}));
    command->add_option("frame", options->frame, "The frame's bytes in hex; ASCII frames also as text (:0103...)")->required();
    command->add_flag("--json", options->json, "Print the explanation as JSON");
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_decode(*options); });
}

}  // namespace loopwire::app
