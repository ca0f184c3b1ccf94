#pragma once
// What the history's tests share: a temporary folder for their files, and a virtual wall clock
// for the store's heartbeats, retention and the forwarder's ages.
#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

namespace loopwire::testing {

// A folder of its own, removed with everything in it when the test ends.
struct TempFolder {
    std::filesystem::path path;
    explicit TempFolder(const std::string& prefix = "loopwire-history") {
        std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
        path = pattern;
    }
    ~TempFolder() {
        std::error_code ignored;
        std::filesystem::remove_all(path, ignored);
    }
    TempFolder(const TempFolder&) = delete;
    TempFolder& operator=(const TempFolder&) = delete;
};

// Virtual wall time: moves only when the test moves it.
struct VirtualWall {
    using Time = std::chrono::system_clock::time_point;
    std::shared_ptr<std::atomic<std::int64_t>> ms = std::make_shared<std::atomic<std::int64_t>>(0);
    explicit VirtualWall(Time start) { set(start); }
    void set(Time time) {
        ms->store(std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch()).count());
    }
    std::function<Time()> clock() const {
        return [ms = ms] { return Time(std::chrono::milliseconds(ms->load())); };
    }
};

}  // namespace loopwire::testing
