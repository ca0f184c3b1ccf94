#pragma once
// Names a thread as `top -H`, `ps -L` and /proc/PID/task/*/comm show it, so an operator can tell
// what each of a process's threads is (and tests can count them by role). Linux keeps at most
// 15 characters: a longer name is cut there.
#include <pthread.h>

#include <string>
#include <string_view>

namespace loopwire {

inline void name_thread(pthread_t thread, std::string_view name) {
    const std::string shown(name.substr(0, 15));
    ::pthread_setname_np(thread, shown.c_str());
}

}  // namespace loopwire
