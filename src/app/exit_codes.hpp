#pragma once
// Exit statuses, so scripts can tell what went wrong (listed in `loopwire --help`).
#include "common/result.hpp"

namespace loopwire::app {

enum ExitCode : int {
    exit_ok = 0,
    exit_invalid_frame = 1,   // decode: the frame is not valid
    exit_usage = 2,           // bad arguments, bad link URL
    exit_link = 3,            // the link cannot be opened or failed
    exit_timeout = 4,         // no reply
    exit_exception = 5,       // the device answered with a Modbus exception
    exit_bad_reply = 6,       // a reply that is malformed or does not answer the request
    exit_interrupted = 130,   // scan stopped by Ctrl-C (128 + SIGINT, as shells report it); what it found is printed
};

inline int exit_code_for(const Error& error) {
    switch (error.kind) {
        case ErrorKind::usage: return exit_usage;
        case ErrorKind::link: return exit_link;
        case ErrorKind::timeout: return exit_timeout;
        case ErrorKind::exception: return exit_exception;
        case ErrorKind::malformed:
        case ErrorKind::mismatch: return exit_bad_reply;
    }
    return exit_link;
}

inline constexpr const char* exit_code_help =
    "Exit status:\n"
    "  0  success\n"
    "  1  decode: the frame is not valid (the reason is printed)\n"
    "  2  usage error: bad arguments or link URL\n"
    "  3  link error: the port or connection cannot be opened, or failed\n"
    "  4  timeout: the device did not answer\n"
    "  5  the device answered with a Modbus exception (code and name printed)\n"
    "  6  a reply that is malformed or does not answer the request\n"
    "  130  scan interrupted by Ctrl-C (the units found so far are printed)\n";

}  // namespace loopwire::app
