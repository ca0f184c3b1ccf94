#pragma once
// The marks of requests whose end says nothing about the device asked, so that a poll that ends
// with one is not a device that does not answer (client/monitor_state.hpp):
//   never sent: a timeout whose deadline passed while the line was busy with other requests
//     (gateway/line_scheduler.hpp);
//   abandoned: the line was closed under it, as the gateway stopped or reloaded
//     (session::Master::close).
#include "common/result.hpp"

namespace loopwire {

inline constexpr int not_sent_code = 1;   // Error::code of a timeout never sent
inline constexpr int abandoned_code = 2;  // Error::code of a link error of a line being closed

inline bool never_sent(const Error& error) { return error.kind == ErrorKind::timeout && error.code == not_sent_code; }
inline bool abandoned(const Error& error) { return error.kind == ErrorKind::link && error.code == abandoned_code; }
inline bool says_nothing_of_the_device(const Error& error) { return never_sent(error) || abandoned(error); }

}  // namespace loopwire
