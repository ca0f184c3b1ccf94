#pragma once
// Helpers shared by the transport tests.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

#include "common/bytes.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::transport::testing {

// A fresh directory under the system's temporary directory, removed with everything in it.
class TempDir {
public:
    TempDir() {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-transport-XXXXXX").string();
        if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
        path_ = pattern;
    }
    ~TempDir() {
        std::error_code ignored;
        std::filesystem::remove_all(path_, ignored);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    std::string file(const std::string& name) const { return (path_ / name).string(); }

private:
    std::filesystem::path path_;
};

// Reads until `count` bytes arrived, the stream fails or `timeout` passes; returns what came.
inline Bytes read_exactly(ByteStream& stream, std::size_t count,
                          std::chrono::milliseconds timeout = std::chrono::milliseconds{2000}) {
    Bytes out;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::uint8_t buffer[256];
    while (out.size() < count) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) break;
        const std::size_t want = std::min(sizeof buffer, count - out.size());
        auto got = stream.read_some(std::span(buffer, want), left);
        if (!got) break;
        out.insert(out.end(), buffer, buffer + *got);
    }
    return out;
}

inline Bytes bytes_of(std::string_view text) { return Bytes(text.begin(), text.end()); }

}  // namespace loopwire::transport::testing
