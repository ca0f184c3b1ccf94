#pragma once
// The ramp/soak controller's Linking protocol (its manual, chapter 6) carries no Modbus PDU:
// R reads one register, M writes one to RAM, W writes one to RAM and EEPROM. Sessions speak
// PDUs, so this adapter translates, one register at a time:
//   R  <->  FC3, quantity 1
//   M  <->  FC6
//   W  <->  FC16, quantity 1   (a distinct function, so a slave can tell a persistent write
//                               from a RAM-only one; a master's FC6 becomes W unless it asked
//                               for RAM-only writes)
// Every reply has the one 8-byte shape 07h 4Dh ID Address Data Sum (§6.1); the manual shows a
// reply to R only (§6.7.1) and none to M or W, so loopwire assumes M and W are answered the
// same way, echoing address and data. Linking has no error reply: a request the slave refuses
// goes unanswered.
#include <memory>

#include "session/frame_codec.hpp"

namespace loopwire::session {

std::unique_ptr<FrameCodec> make_linking_frame_codec(codec::Direction direction,
                                                     bool ram_only_writes);

}  // namespace loopwire::session
