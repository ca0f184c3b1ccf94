#include "app/json_errors.hpp"

#include <atomic>

#include "codec/pdu.hpp"

namespace loopwire::app {
namespace {

std::atomic<bool> json_errors{false};

const char* kind_name(ErrorKind kind) {
    switch (kind) {
        case ErrorKind::usage: return "usage";
        case ErrorKind::link: return "link";
        case ErrorKind::timeout: return "timeout";
        case ErrorKind::exception: return "exception";
        case ErrorKind::malformed: return "malformed";
        case ErrorKind::mismatch: return "mismatch";
    }
    return "link";
}

}  // namespace

nlohmann::ordered_json error_json(const Error& error) {
    nlohmann::ordered_json out{{"error", error.message}, {"kind", kind_name(error.kind)}};
    if (error.kind == ErrorKind::exception) {
        out["code"] = error.code;
        const auto name = codec::exception_name(static_cast<std::uint8_t>(error.code));
        out["exception"] = name ? nlohmann::ordered_json(*name) : nlohmann::ordered_json(nullptr);
    }
    return out;
}

JsonErrors::JsonErrors(bool on) : previous_(json_errors.exchange(on)) {}
JsonErrors::~JsonErrors() { json_errors = previous_; }

bool json_errors_on() { return json_errors; }

}  // namespace loopwire::app
