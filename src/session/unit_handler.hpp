#pragma once
// What a slave session dispatches to: one handler per unit id. The handler decides what the
// device answers, and when it stays silent.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "codec/pdu.hpp"
#include "common/bytes.hpp"

namespace loopwire::session {

class UnitHandler {
public:
    virtual ~UnitHandler() = default;
    // The reply PDU for a request PDU, or nullopt for no reply at all (some devices stay silent
    // on requests they cannot serve, e.g. the AC20 on an unimplemented function code).
    // `broadcast`: the request came to unit 0; it is executed and any reply is dropped.
    virtual std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) = 0;

    // Receives the reply PDU of one request, or nullopt for no reply. Call it exactly once.
    using ReplyCallback = std::function<void(std::optional<Bytes>)>;

    // Who asked: 0 for a serial line, one number per TCP connection, so a gateway can share a
    // line fairly between the clients (docs/DESIGN.md, gateway).
    using Origin = std::uint64_t;

    // The asker of one request: its origin and, for a handler that queues requests (a gateway's
    // line), whether the answer is still wanted. A TCP connection that has closed, or whose
    // client has ended its side of it, no longer wants what has not been sent yet: a queued
    // request of it is dropped instead of taking the line. The flag is the connection's, read
    // from any thread with the reader's locks held; copying it costs no allocation, which matters
    // as every request carries it. Null: always wanted.
    using WantedFlag = std::shared_ptr<const std::atomic<bool>>;
    static bool wanted(const WantedFlag& flag) { return !flag || flag->load(std::memory_order_relaxed); }
    struct Asker {
        Asker(Origin from = 0, WantedFlag wanted = {}, bool writes = true,  // NOLINT: an Origin is an Asker
              std::shared_ptr<const std::string> address = {})
            : origin(from), still_wanted(std::move(wanted)), may_write(writes), peer(std::move(address)) {}
        Origin origin;
        WantedFlag still_wanted;
        // False for a TCP client whose address is outside the slave's write_allow
        // (SlaveOptions::access): a handler passes on only its reads.
        bool may_write;
        // The client's address ("127.0.0.1:50312"), shared by the requests of its connection (no
        // copy a request); none for a serial master.
        std::shared_ptr<const std::string> peer;
        bool wanted() const { return UnitHandler::wanted(still_wanted); }
    };

    // The same decision, for handlers that answer later: a gateway forwards the request to a
    // serial line and replies when the device has answered. `reply` may be called from any
    // thread, after handle_async() has returned; a TCP slave sends the reply with the request's
    // transaction id whenever it comes, so replies on one connection may overtake each other
    // (Modbus Messaging on TCP/IP V1.0b, 4.2: the transaction id pairs them). The default
    // answers at once through handle().
    virtual void handle_async(Bytes request_pdu, bool broadcast, const Asker& /*asker*/, ReplyCallback reply) {
        reply(handle(request_pdu, broadcast));
    }

    // The unit id the handler answers at now when a request changed it (a simulated AC20 whose
    // word 527 was written answers at the new address after its reply); 0 when it hears nothing
    // on this line any more (set to another baud rate, byte format or protocol, or its serial
    // interface switched off); nullopt: the id it is served under. May be called from any thread.
    virtual std::optional<std::uint8_t> answers_as() const { return std::nullopt; }

    // Something went past on the handler's line: a frame for any unit (this one, another, or
    // none served here; broadcast too), or bytes the framer discarded (a bad check, noise).
    // The slave session calls it on every handler of the line that hears it (answers_as() is
    // not 0), before the frame is handled, at the time the slave received it; a device whose
    // state lives on line activity (AC20 Note 5: "it is sufficient to detect line activity")
    // reads its own clock. May be called from any thread.
    virtual void line_activity() {}
};

// A handler that works on decoded requests. Requests that do not decode are answered the way
// the Modbus application protocol (V1.1b3, 7) says: exception 1 for a function code the
// handler does not serve, 3 for a malformed quantity or byte count, 2 for a range past FFFFh.
class RequestHandler : public UnitHandler {
public:
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override;

protected:
    // A normal or exception reply to a request that decoded cleanly.
    virtual codec::Reply serve(const codec::Request& request) = 0;
};

}  // namespace loopwire::session
