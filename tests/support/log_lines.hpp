#pragma once
// The lines a gateway part logs (a GatewayLog sink), kept for a test to look through; the part
// may log from its own threads.
#include <algorithm>
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "support/eventually.hpp"

namespace loopwire::testing {

class LogLines {
public:
    std::function<void(const std::string&)> sink() {
        return [this](const std::string& line) {
            std::lock_guard lock(mutex_);
            lines_.push_back(line);
        };
    }
    // Whether a line holds `part`, and how many do.
    bool has(const std::string& part) { return count(part) > 0; }
    int count(const std::string& part) {
        std::lock_guard lock(mutex_);
        return static_cast<int>(std::count_if(lines_.begin(), lines_.end(),
                                              [&](const std::string& line) { return line.find(part) != std::string::npos; }));
    }
    std::vector<std::string> all() {
        std::lock_guard lock(mutex_);
        return lines_;
    }
    // Waits until a line holds `part`; false at the deadline.
    bool wait_for(const std::string& part, std::chrono::milliseconds deadline = default_patience) {
        return eventually([&] { return has(part); }, deadline);
    }

private:
    std::mutex mutex_;
    std::vector<std::string> lines_;
};

}  // namespace loopwire::testing
