#pragma once
// What a public loopwire::Link holds: the master on the opened link.
#include <memory>

#include <loopwire/link.hpp>

#include "session/master.hpp"

namespace loopwire {

struct Link::State {
    std::unique_ptr<session::Master> master;
};

}  // namespace loopwire
