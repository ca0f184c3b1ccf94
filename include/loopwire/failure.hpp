#pragma once
// The one exception type of the public API.
#include <stdexcept>
#include <string>

namespace loopwire {

class Failure : public std::runtime_error {
public:
    // What went wrong, in the categories of the command line's exit codes.
    enum class Kind {
        usage,             // something malformed was asked for: a bad URL, name, device or value
        link,              // the link cannot be opened, or broke
        timeout,           // the device did not answer in time
        device_exception,  // the device answered with a Modbus exception (see exception_code())
        malformed,         // bytes that do not form a valid frame
        mismatch,          // a reply that does not answer the request sent
    };

    Failure(Kind kind, const std::string& message, int exception_code = 0);

    Kind kind() const noexcept { return kind_; }
    // The Modbus exception code when kind() is device_exception, otherwise 0.
    int exception_code() const noexcept { return exception_code_; }

private:
    Kind kind_;
    int exception_code_;
};

}  // namespace loopwire
