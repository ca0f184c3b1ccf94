#pragma once
// The names of this process's threads now (/proc/self/task/*/comm), for tests that count
// threads by role (common/thread_name.hpp names loopwire's).
#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

namespace loopwire::testing {

inline std::multiset<std::string> thread_names() {
    std::multiset<std::string> names;
    for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
        std::ifstream comm(task.path() / "comm");
        std::string name;
        if (std::getline(comm, name)) names.insert(name);
    }
    return names;
}

// How many threads have a name beginning with `prefix`.
inline std::size_t threads_named_like(const std::string& prefix) {
    const auto names = thread_names();
    return static_cast<std::size_t>(
        std::count_if(names.begin(), names.end(), [&](const std::string& name) { return name.starts_with(prefix); }));
}

}  // namespace loopwire::testing
