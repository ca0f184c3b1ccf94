// loopwire's serial master alone on a line, for serial_line_share.sh: the same master the gateway
// puts on each of its lines (session::open_master, carried on a session::LineLoop, a request's
// PDU passed through with forward() as the gateway passes its clients' on), reading the same
// holding registers of one unit again and again for a fixed time, each request sent as soon as
// the one before it ended.
// It is what the gateway's figure is compared with: the line shared by many clients through the
// gateway against one master that has it to itself. (`loopwire monitor` cannot stand for it: its
// samples keep a fixed schedule of 10 ms or more, so every request would wait for the next slot.)
//
// Usage: serial_master_loop LINK SECONDS UNIT ADDRESS COUNT
// Prints on stdout:
//   requests/s: R                         replies within the window / the window
//   requests: N, failed: F, seconds: S    F = timeouts, refused and exception replies
//   garbled frames: G                     runs of bytes the master discarded in the window
//                                         (MasterOptions::discarded, the gateway's garbled frames)
// Exit 1 if no request was answered, 2 on bad arguments or a link that cannot be opened.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "codec/pdu.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "transport/link_url.hpp"

namespace {

using WallClock = std::chrono::steady_clock;

bool parse_int(const char* text, long low, long high, long& out) {
    char* end = nullptr;
    out = std::strtol(text, &end, 10);
    return end != text && *end == '\0' && out >= low && out <= high;
}

}  // namespace

int main(int argc, char** argv) {
    long unit = 0;
    long address = 0;
    long count = 0;
    char* end = nullptr;
    const double seconds = argc == 6 ? std::strtod(argv[2], &end) : 0.0;
    if (argc != 6 || end == argv[2] || *end != '\0' || seconds <= 0 || !parse_int(argv[3], 1, 247, unit) ||
        !parse_int(argv[4], 0, 65535, address) || !parse_int(argv[5], 1, 125, count)) {
        std::fprintf(stderr, "usage: serial_master_loop LINK SECONDS UNIT ADDRESS COUNT\n"
                             "  (SECONDS > 0, UNIT 1..247, ADDRESS 0..65535, COUNT 1..125)\n");
        return 2;
    }
    using namespace loopwire;
    auto link = transport::parse_link_url(argv[1]);
    if (!link) {
        std::fprintf(stderr, "serial_master_loop: %s\n", link.error().message.c_str());
        return 2;
    }
    session::MasterOptions options;
    options.discarded = std::make_shared<std::atomic<std::uint64_t>>(0);
    options.loop = std::make_shared<session::LineLoop>();  // the master keeps it while it lives
    auto master = session::open_master(*link, options);
    if (!master) {
        std::fprintf(stderr, "serial_master_loop: %s\n", master.error().message.c_str());
        return 2;
    }
    const auto pdu = codec::encode_request(codec::read_request(codec::FunctionCode::read_holding_registers,
                                                                static_cast<std::uint16_t>(address),
                                                                static_cast<std::uint16_t>(count)));
    if (!pdu) {
        std::fprintf(stderr, "serial_master_loop: %s\n", pdu.error().message.c_str());
        return 2;
    }
    const auto target = static_cast<std::uint8_t>(unit);
    // One untimed request: it proves the path and pays for the first-time costs.
    auto first = (*master)->forward(target, *pdu);
    if (!first) std::fprintf(stderr, "serial_master_loop: first request: %s\n", first.error().message.c_str());

    const std::uint64_t garbled_before = options.discarded->load();
    long answered = 0;
    long failed = 0;
    std::map<std::string, long> failures;  // message -> how often
    const auto start = WallClock::now();
    const auto deadline = start + std::chrono::duration_cast<WallClock::duration>(std::chrono::duration<double>(seconds));
    while (WallClock::now() < deadline) {
        auto reply = (*master)->forward(target, *pdu);
        if (WallClock::now() > deadline) break;  // ended after the window: not counted
        if (reply && !reply->empty() && ((*reply)[0] & 0x80) == 0) {
            ++answered;
        } else if (reply) {
            ++failed;
            ++failures[fmt::format("exception {:02X}h", reply->size() > 1 ? (*reply)[1] : 0)];
        } else {
            ++failed;
            ++failures[reply.error().message];
        }
    }
    for (const auto& [message, times] : failures) std::fprintf(stderr, "serial_master_loop: %ld x %s\n", times, message.c_str());
    std::printf("requests: %ld, failed: %ld, seconds: %.3f\n", answered, failed, seconds);
    std::printf("garbled frames: %llu\n", static_cast<unsigned long long>(options.discarded->load() - garbled_before));
    std::printf("requests/s: %.1f\n", static_cast<double>(answered) / seconds);
    return answered > 0 ? 0 : 1;
}
