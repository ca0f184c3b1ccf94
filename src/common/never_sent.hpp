#pragma once
// The mark of a request that never went on the wire: a timeout whose deadline passed while the
// line was busy with other requests (gateway/line_scheduler.hpp). It says nothing about the
// device asked, so a poll that ends with it is not a device that does not answer
// (client/monitor_state.hpp).
#include "common/result.hpp"

namespace loopwire {

inline constexpr int not_sent_code = 1;  // Error::code of such a timeout

inline bool never_sent(const Error& error) { return error.kind == ErrorKind::timeout && error.code == not_sent_code; }

}  // namespace loopwire
