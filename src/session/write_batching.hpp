#pragma once
// Writes put off to the end of an event loop's round. A gateway's Modbus TCP front hands each
// client's request to a line the moment it reads it; with twenty clients ready at once, a TCP
// device behind a pipelined line would get twenty writes of one frame each, and on a busy host
// each wakes the device's server for one request. A sender on a loop's thread may instead note
// its frame and ask for one write of everything noted once the handlers already ready have run:
// the device then reads the twenty requests at once and answers them in one write.
//
// Only where the loop says so: a thread that runs no WriteBatching::Scope writes at once, so
// CLI masters and the lines' own threads behave as before.
#include <functional>
#include <vector>

namespace loopwire::session {

class WriteBatching {
public:
    // Queues `work` to run on this loop's thread after the handlers already ready.
    using Post = std::function<void(std::function<void()>)>;

    // Held by the loop's thread while it runs the loop (around io_context::run).
    class Scope {
    public:
        explicit Scope(Post post);
        ~Scope();
        Scope(const Scope&) = delete;
        Scope& operator=(const Scope&) = delete;

    private:
        friend class WriteBatching;
        void run_flushes();

        Post post_;
        std::vector<std::function<void()>> flushes_;
        bool posted_ = false;
        Scope* outer_;
    };

    // On a thread inside a Scope: `flush` runs once, on this thread, at the end of the round,
    // and true is returned. Elsewhere false: the caller writes now. A flush that must not outlive
    // its sender holds a weak reference: a loop that stops drops the flushes not yet run.
    static bool defer(std::function<void()> flush);
};

}  // namespace loopwire::session
