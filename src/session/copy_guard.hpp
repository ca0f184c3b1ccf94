#pragma once
// What a serial line's master heard and wrote lately: enough to tell whether a frame that answers
// a request in shape could be a copy of an earlier frame (a repeater or relay sending a reply
// twice, hundreds of milliseconds apart). RTU has no transaction id, so bytes and time are all
// there is. Sans-I/O: it is told what happened and when, and reads no clock.
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <utility>

#include "codec/table.hpp"
#include "common/bytes.hpp"
#include "common/clock.hpp"

namespace loopwire::session {

class CopyGuard {
public:
    using Duration = Instant::duration;

    // `window`: how long after a frame a copy of it may still arrive (the master's reply timeout
    // plus its late-reply window). Everything heard within it is kept, however many frames that
    // is: a copy 350 ms late on a busy line comes dozens of frames after its original.
    explicit CopyGuard(Duration window) : window_(window) {}

    // A frame heard at `at`, for `request` (empty: it answered no request of ours, e.g. a stray
    // frame between exchanges or a second frame for one request).
    void heard(ByteView raw, ByteView request, Instant at);

    // Bytes heard at `at` that made no frame (damaged: a frame cut by a pause, noise), while
    // `request` was awaited (empty: between exchanges). A frame heard damaged may come again
    // whole, as a repeater's copy: its bytes are found in these, in the order they came.
    void heard_damaged(ByteView bytes, ByteView request, Instant at);

    // A request sent to `unit` (0: broadcast) at `at` that may change what a read answers:
    // anything but functions 1-4. The answers it may change are forgotten.
    void sent(std::uint8_t unit, ByteView pdu, Instant at);

    // The reply `raw` to a read `request` was handed out: the device's answer until a write
    // over what it reads. Kept beyond the window (a poll every few seconds finds its answer
    // again), for a bounded number of requests.
    void answered(std::uint8_t unit, ByteView request, ByteView raw);

    struct Earlier {
        Instant at;     // when the frame with the same bytes was heard
        bool replaced;  // it answered this same read, before a write over what it reads
    };

    // The earlier frame `raw` may be a copy of, for `request` to `unit` at `now`: a frame with the
    // same bytes heard within the window for another request (or for none), whole or among
    // damaged bytes heard while another request was awaited (or none), or for this same read
    // before a write over what it reads (its value is the one the write replaced). None when the
    // device's last answer to this same read was these bytes and nothing was written over it
    // since, or when they are a write's echo heard for this same write (the echo is the same
    // whatever the device held): then the bytes are the device's answer, whichever frame
    // brought them. With `doubt_own_answers` (the unit has just left a try unanswered) that is
    // no proof: a copy of its own answer from a moment ago would make a silent device look alive,
    // so the same bytes heard for this same request within the window count as a possible copy.
    std::optional<Earlier> copy_of(ByteView raw, ByteView request, std::uint8_t unit, Instant now,
                                   bool doubt_own_answers = false) const;

    // The device answered `request` with `raw` (a later try heard the same bytes again): frames
    // with those bytes heard since `since` for no request were its answers, not copies.
    void confirm(ByteView raw, ByteView request, Instant since);

    static bool reads_only(std::uint8_t function) { return function >= 1 && function <= 4; }

private:
    struct HeardFrame {
        Bytes raw;
        Bytes request;
        Instant at;
    };
    struct SentWrite {
        Instant at;
        std::optional<codec::DataSpan> span;  // none: it may change anything
    };

    bool written_over(std::uint8_t unit, const codec::DataSpan& read, Instant at) const;
    std::optional<Earlier> among_damaged(ByteView raw, ByteView request, Instant recent) const;
    void forget_answers(std::uint8_t unit, const std::optional<codec::DataSpan>& written);
    void forget_before(Instant at);

    // A bound on memory only: far more frames than a line carries within any sane window.
    static constexpr std::size_t most_frames = 4096;
    static constexpr std::size_t most_writes_per_unit = 256;
    static constexpr std::size_t most_answers = 4096;
    static constexpr std::size_t most_damaged_runs = 4096;

    Duration window_;
    std::deque<HeardFrame> frames_;                        // oldest first
    std::deque<HeardFrame> damaged_;                       // runs of damaged bytes, oldest first
    std::map<std::uint8_t, std::deque<SentWrite>> writes_;  // by unit, oldest first
    std::map<std::pair<std::uint8_t, Bytes>, Bytes> answers_;  // (unit, read request) -> the reply frame
};

}  // namespace loopwire::session
