#pragma once
// For the fuzz targets of the gateway's fronts: a line with nothing behind it, whose every
// request fails at once (as a broken link would), so a front's answer never waits on a device.
#include <string>

#include "session/master.hpp"

namespace loopwire::fuzz {

class DeadLineMaster final : public session::Master {
public:
    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return failed(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(failed()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return failed(); }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override { done(failed()); }
    std::string describe() const override { return "fuzz line"; }

private:
    static Error failed() { return make_error(ErrorKind::link, "fuzz: no line"); }
};

}  // namespace loopwire::fuzz
