#pragma once
// The master side: sends requests, waits for the matching reply, retries, and keeps the line
// discipline of its framing (docs/DESIGN.md, session layer).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "codec/pdu.hpp"
#include "common/clock.hpp"
#include "common/result.hpp"
#include "session/trace.hpp"
#include "transport/byte_stream.hpp"
#include "transport/link_url.hpp"

namespace loopwire::session {

using std::chrono::milliseconds;

class LineLoop;

struct MasterOptions {
    milliseconds timeout{1000};   // per try
    // Extra tries after a timeout, or after a reply refused as a probable copy of another
    // request's (serial lines); never after an exception reply.
    unsigned retries = 0;
    // Silence after a broadcast before the next request, so slaves can execute it
    // (Modbus over serial line V1.02, 2.4.1: "turnaround delay", typically 100 to 200 ms).
    milliseconds turnaround{100};
    // Serial lines: after a try that got no reply it could take (none, a wrong one, an ambiguous
    // one), a reply to it may still arrive late, and RTU has no transaction id to tell it from the
    // next request's. So the next request waits until the line has been quiet this long,
    // discarding whatever arrives. nullopt: as long as `timeout`. Costs nothing while replies
    // come in time.
    std::optional<milliseconds> late_reply_window;
    bool linking_ram_only = false;  // Linking: single writes as M (RAM only) instead of W
    TraceSink trace;                // -v: every frame sent, received or discarded
    // Counts every run of bytes the master discards (bad CRC or LRC, broken frames, noise,
    // replies that answer nothing), traced or not: the gateway's garbled-frames counter, kept
    // without a trace, which would copy every frame sent and received.
    std::shared_ptr<std::atomic<std::uint64_t>> discarded;
    // What the serial master's silences, timeouts and turnarounds run on (common/clock.hpp). A
    // virtual clock only makes sense with a stream that reads the same clock. The TCP master
    // keeps its deadlines on its loop's clock.
    std::shared_ptr<Clock> clock = steady_clock();
    // Serial masters: carry the exchanges on this loop (session/line_loop.hpp), shared with
    // other lines, instead of a thread of the master's own; *_async calls then only queue, and
    // completions run on the loop's thread. The loop's clock is then the master's, and `clock`
    // is not used. Null: the blocking calls run on the caller's thread.
    // The TCP master: its connection is read, replies matched and requests expired on this loop
    // (requests are written from the caller's thread), and a lost connection is not made again
    // by the master (the gateway's ReopeningMaster reopens the line). Null: a loop of its own,
    // and it connects again on the next request after the connection was lost.
    std::shared_ptr<LineLoop> loop;
};

class Master {
public:
    using Completion = std::function<void(Result<codec::Reply>)>;

    virtual ~Master() = default;
    Master() = default;
    Master(const Master&) = delete;
    Master& operator=(const Master&) = delete;

    // Sends `request` to `unit` and returns the reply that answers it. Unit 0 broadcasts: no
    // reply is awaited, the turnaround delay is kept, and an empty normal reply is returned.
    // An exception reply is ErrorKind::exception with the code. Safe to call from several
    // threads: a serial line carries one request at a time, TCP pipelines them.
    virtual Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) = 0;

    // The same without blocking, for event loops: `done` runs on a thread of the master's.
    virtual void execute_async(std::uint8_t unit, codec::Request request, Completion done) = 0;

    using ForwardCompletion = std::function<void(Result<Bytes>)>;

    // A PDU of any function code passed through as it is, for a gateway that serves Modbus TCP
    // clients from this link (docs/DESIGN.md, gateway). The result is the PDU the unit answered,
    // an exception reply (function + 80h, code) included, for the caller to pass back
    // unchanged; errors are only what a device cannot say itself: no reply, a reply that does
    // not answer, a link that failed, a PDU that is not Modbus (check_forwardable), or a
    // framing that cannot carry it (Linking). Unit 0 broadcasts and returns an empty PDU.
    virtual Result<Bytes> forward(std::uint8_t unit, ByteView pdu) = 0;
    virtual void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) = 0;

    virtual std::string describe() const = 0;

    // Ends what is under way now and refuses what comes after, each with a link error saying
    // the line is being closed (marked abandoned, common/never_sent.hpp: it tells nothing of
    // the device): for a master about to go with a gateway that stops or reloads, so that
    // nothing waits out a reply timeout. From any thread. The default does nothing: the
    // master's calls end by themselves.
    virtual void close() {}
};

// RTU, ASCII and Linking on a serial line, pseudo-terminal or virtual bus port, and RTU frames
// through a serial device server (rtu+tcp). One outstanding request; at least 3.5 character
// times of silence kept before every frame.
std::unique_ptr<Master> make_serial_master(std::unique_ptr<transport::ByteStream> stream,
                                           const transport::LinkUrl& link, MasterOptions options);

// Modbus TCP: transaction ids, several requests in flight, reconnects after a lost connection.
std::unique_ptr<Master> make_tcp_master(std::unique_ptr<transport::ByteStream> stream,
                                        const transport::LinkUrl& link, MasterOptions options);

// Opens the link a URL names (serial port or TCP connection) and the matching master.
// `rtu:virtual` links exist only inside one process: the caller wires those itself.
Result<std::unique_ptr<Master>> open_master(const transport::LinkUrl& link, MasterOptions options);

}  // namespace loopwire::session
