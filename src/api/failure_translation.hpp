#pragma once
// Internal errors (common/result.hpp) become the public API's one exception type.
#include <utility>

#include <loopwire/failure.hpp>

#include "common/result.hpp"

namespace loopwire::api {

Failure to_failure(const Error& error);

[[noreturn]] inline void throw_failure(const Error& error) { throw to_failure(error); }

template <typename T>
T value_or_throw(Result<T> result) {
    if (!result) throw_failure(result.error());
    return std::move(result).value();
}

inline void throw_if_failed(const Result<void>& result) {
    if (!result) throw_failure(result.error());
}

}  // namespace loopwire::api
