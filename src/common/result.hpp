#pragma once
// Expected failures (timeouts, exception replies, bad check bytes, bad user input) travel as
// values. std::expected is C++23; this is the small subset loopwire needs under C++20.
#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace loopwire {

// What went wrong, in the categories the CLI maps to exit codes.
enum class ErrorKind {
    usage,      // the caller asked for something malformed (bad URL, bad argument)
    link,       // the byte pipe failed (cannot open, disconnected, I/O error)
    timeout,    // no (valid) reply within the time allowed
    exception,  // the peer answered with a Modbus exception
    malformed,  // bytes that do not form a valid frame or PDU
    mismatch,   // a well-formed reply that does not answer the request sent
};

struct Error {
    ErrorKind kind;
    std::string message;   // says what was wrong and, where it can, what to do
    int code = 0;          // ErrorKind::exception: the exception code; otherwise 0
};

inline Error make_error(ErrorKind kind, std::string message, int code = 0) {
    return Error{kind, std::move(message), code};
}

template <typename T>
class [[nodiscard]] Result {
public:
    Result(T value) : state_(std::in_place_index<0>, std::move(value)) {}  // NOLINT: implicit by design
    Result(Error error) : state_(std::in_place_index<1>, std::move(error)) {}  // NOLINT

    bool ok() const { return state_.index() == 0; }
    explicit operator bool() const { return ok(); }

    T& value() & { assert(ok()); return std::get<0>(state_); }
    const T& value() const& { assert(ok()); return std::get<0>(state_); }
    T&& value() && { assert(ok()); return std::get<0>(std::move(state_)); }
    T* operator->() { return &value(); }
    const T* operator->() const { return &value(); }
    T& operator*() & { return value(); }
    const T& operator*() const& { return value(); }

    const Error& error() const { assert(!ok()); return std::get<1>(state_); }

private:
    std::variant<T, Error> state_;
};

template <>
class [[nodiscard]] Result<void> {
public:
    Result() = default;
    Result(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT
    bool ok() const { return ok_; }
    explicit operator bool() const { return ok_; }
    const Error& error() const { assert(!ok_); return error_; }

private:
    Error error_{ErrorKind::usage, {}};
    bool ok_ = true;
};

}  // namespace loopwire
