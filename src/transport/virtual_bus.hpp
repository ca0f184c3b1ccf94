#pragma once
// An in-memory multi-drop serial line. Every byte written by one port reaches every other port
// after the time it takes on the wire at the bus's baud rate and character size, so timing
// behaviour (3.5-character gaps, turnaround delays) can be tested without hardware. Tests can
// inject faults on the bytes in flight.
//
// Choices made where real lines differ (details in virtual_bus.cpp):
// - The wire is shared and half-duplex; a write that starts while another is on the wire waits
//   for it (serialised) rather than colliding. write() returns once its last byte has left.
// - A port never hears its own writes.
// - write() returns once its last byte has left, unless the port was attached with
//   Writes::return_at_once.
// - A dropped write still occupies the wire; noise_before takes wire time before the write;
//   extra_delay and duplicate_after are latency only (the sender and the wire do not wait for
//   them); a truncated write takes the wire time of what is sent.
// - poll_handle() is a timerfd that is readable exactly while read_some() has bytes to return.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "transport/byte_stream.hpp"

namespace loopwire::transport {

// What happens to one write on its way across the bus. Faults apply to a whole write (a frame,
// as sessions write them) and are decided by the test's own function, so runs are deterministic.
struct BusFault {
    bool drop = false;                        // the write never arrives
    std::vector<std::size_t> corrupt_bytes;   // indexes whose bits are inverted
    std::chrono::microseconds extra_delay{0}; // arrives this much later
    Bytes noise_before;                       // bytes that appear on the line before the write
    // Only the first this many bytes go out (a sender that stops mid-frame: reset, lost power),
    // and only they take wire time.
    std::optional<std::size_t> truncate_to;
    // The same bytes (after corruption and truncation) arrive a second time, this long after the
    // first copy started: a repeater or relay that sends a frame twice. Latency only, like
    // extra_delay: the wire and the sender do not wait for it, and its bytes land among whatever
    // else arrives then.
    std::optional<std::chrono::microseconds> duplicate_after;
};

// Decides the fault for a write: (sending port name, bytes written) -> fault.
using FaultInjector = std::function<BusFault(const std::string& from, ByteView bytes)>;

class VirtualBus : public std::enable_shared_from_this<VirtualBus> {
public:
    static std::shared_ptr<VirtualBus> create(std::uint32_t baud, unsigned bits_per_character);

    // Whether a port's write() waits until its last byte has left, as a real port's does
    // (tcdrain), or returns at once, its bytes still taking their wire time: for a loop that
    // serves several buses on one thread and must not wait on one of them
    // (simulation/simulated_lines.hpp).
    enum class Writes { wait_for_wire, return_at_once };

    // A new station on the bus. The port keeps the bus alive.
    std::unique_ptr<ByteStream> attach(const std::string& name, Writes writes = Writes::wait_for_wire);
    void set_fault_injector(FaultInjector injector);
    std::chrono::microseconds character_time() const;

    struct Impl;
    explicit VirtualBus(std::unique_ptr<Impl> impl);
    ~VirtualBus();

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace loopwire::transport
