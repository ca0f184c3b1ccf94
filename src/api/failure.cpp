#include "api/failure_translation.hpp"

namespace loopwire {

Failure::Failure(Kind kind, const std::string& message, int exception_code)
    : std::runtime_error(message), kind_(kind), exception_code_(exception_code) {}

namespace api {
namespace {

Failure::Kind public_kind(ErrorKind kind) {
    switch (kind) {
        case ErrorKind::usage: return Failure::Kind::usage;
        case ErrorKind::link: return Failure::Kind::link;
        case ErrorKind::timeout: return Failure::Kind::timeout;
        case ErrorKind::exception: return Failure::Kind::device_exception;
        case ErrorKind::malformed: return Failure::Kind::malformed;
        case ErrorKind::mismatch: return Failure::Kind::mismatch;
    }
    return Failure::Kind::link;
}

}  // namespace

Failure to_failure(const Error& error) {
    return Failure(public_kind(error.kind), error.message, error.kind == ErrorKind::exception ? error.code : 0);
}

}  // namespace api
}  // namespace loopwire
