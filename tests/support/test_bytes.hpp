#pragma once
// Frames written in tests as the manuals print them ("01 03 00 8A 00 01 A5 E0").
#include <gtest/gtest.h>

#include <initializer_list>
#include <string_view>

#include "common/bytes.hpp"

namespace loopwire::testing {

inline Bytes hex(std::string_view text) {
    auto bytes = parse_hex(text);
    EXPECT_TRUE(bytes.has_value()) << "bad hex in test: " << text;
    return bytes.value_or(Bytes{});
}

inline Bytes concat(std::initializer_list<Bytes> parts) {
    Bytes out;
    for (const Bytes& part : parts) out.insert(out.end(), part.begin(), part.end());
    return out;
}

}  // namespace loopwire::testing
