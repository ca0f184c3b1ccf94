// CopyGuard, sans I/O: which frames could be copies of earlier ones, told by bytes and time.
#include <gtest/gtest.h>

#include "session/copy_guard.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;
using testing::hex;

const Instant t0 = Instant{} + 1h;
const Bytes read_10 = hex("03 00 0A 00 01");
const Bytes read_11 = hex("03 00 0B 00 01");
const Bytes write_10 = hex("06 00 0A 00 05");
const Bytes write_20 = hex("06 00 14 00 05");
const Bytes reply_zero = hex("01 03 02 00 00 B8 44");

TEST(CopyGuard, TheSameBytesForAnotherRequestWithinTheWindowCouldBeACopy) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, read_10, t0);
    const auto copy = guard.copy_of(reply_zero, read_11, 1, t0 + 1999ms);
    ASSERT_TRUE(copy.has_value());
    EXPECT_EQ(copy->at, t0);
    EXPECT_FALSE(copy->replaced);
    EXPECT_FALSE(guard.copy_of(reply_zero, read_11, 1, t0 + 2001ms).has_value()) << "past the window no copy comes";
    EXPECT_FALSE(guard.copy_of(hex("01 03 02 00 01 79 84"), read_11, 1, t0 + 1s).has_value()) << "other bytes";
}

TEST(CopyGuard, AFrameHeardForNoRequestCountsAsAnotherRequests) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, {}, t0);
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 1, t0 + 10ms).has_value());
}

TEST(CopyGuard, EveryFrameOfTheWindowIsKeptNotTheLastFew) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, read_10, t0);
    for (int i = 1; i <= 1000; ++i) {
        guard.heard(hex("01 03 02 00 01 79 84"), read_11, t0 + std::chrono::milliseconds(i));
    }
    EXPECT_TRUE(guard.copy_of(reply_zero, read_11, 1, t0 + 1500ms).has_value());
}

TEST(CopyGuard, TheSameReadsAnswerIsNoCopyUntilAWriteOverIt) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, read_10, t0);
    guard.answered(1, read_10, reply_zero);
    EXPECT_FALSE(guard.copy_of(reply_zero, read_10, 1, t0 + 100ms).has_value());
    guard.sent(1, write_20, t0 + 200ms);  // elsewhere in the unit
    EXPECT_FALSE(guard.copy_of(reply_zero, read_10, 1, t0 + 300ms).has_value());
    guard.sent(1, write_10, t0 + 400ms);  // over what it reads
    const auto replaced = guard.copy_of(reply_zero, read_10, 1, t0 + 500ms);
    ASSERT_TRUE(replaced.has_value());
    EXPECT_TRUE(replaced->replaced);
}

TEST(CopyGuard, AReadsLastAnswerIsKeptBeyondTheWindowUntilAWrite) {
    CopyGuard guard(2s);
    guard.answered(1, read_10, reply_zero);
    guard.heard(reply_zero, read_11, t0 + 1h);  // another register with the same value, just now
    EXPECT_FALSE(guard.copy_of(reply_zero, read_10, 1, t0 + 1h + 10ms).has_value()) << "its own answer";
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 2, t0 + 1h + 10ms).has_value()) << "another unit's answer";
    guard.sent(0, write_10, t0 + 1h + 20ms);  // a broadcast over it
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 1, t0 + 1h + 30ms).has_value());
}

TEST(CopyGuard, AWriteOfUnknownReachForgetsEveryAnswerOfTheUnit) {
    CopyGuard guard(2s);
    guard.answered(1, read_10, reply_zero);
    guard.answered(1, read_11, reply_zero);
    guard.heard(reply_zero, {}, t0);
    guard.sent(1, hex("08 00 01 00 00"), t0 + 1ms);  // diagnostics: reach unknown
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 1, t0 + 2ms).has_value());
    EXPECT_TRUE(guard.copy_of(reply_zero, read_11, 1, t0 + 2ms).has_value());
}

TEST(CopyGuard, AWritesEchoHeardAgainIsNoCopy) {
    CopyGuard guard(2s);
    const Bytes echo = hex("01 06 00 0A 00 05 69 CB");
    guard.sent(1, write_10, t0);
    guard.heard(echo, write_10, t0 + 5ms);
    guard.sent(1, write_10, t0 + 10ms);
    EXPECT_FALSE(guard.copy_of(echo, write_10, 1, t0 + 15ms).has_value());
}

TEST(CopyGuard, ConfirmedBytesHeardForNoRequestBecomeTheRequestsAnswer) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, {}, t0 + 10ms);  // refused for read 11: could have been a copy
    EXPECT_TRUE(guard.copy_of(reply_zero, read_11, 1, t0 + 20ms).has_value());
    guard.confirm(reply_zero, read_11, t0 + 5ms);  // the device said them again
    EXPECT_FALSE(guard.copy_of(reply_zero, read_11, 1, t0 + 20ms).has_value());
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 1, t0 + 20ms).has_value()) << "still read 11's for read 10";
}

// A device that has just left a try unanswered proves nothing by its own last answer coming
// again: a repeater's copy of it would keep a silent device looking alive.
TEST(CopyGuard, AUnitJustSilentIsNotBelievedOnItsOwnAnswerRepeated) {
    CopyGuard guard(2s);
    guard.heard(reply_zero, read_10, t0);
    guard.answered(1, read_10, reply_zero);
    EXPECT_FALSE(guard.copy_of(reply_zero, read_10, 1, t0 + 300ms).has_value());
    EXPECT_TRUE(guard.copy_of(reply_zero, read_10, 1, t0 + 300ms, true).has_value());
    EXPECT_FALSE(guard.copy_of(reply_zero, read_10, 1, t0 + 3s, true).has_value()) << "past the window no copy comes";
}

// A reply cut in two by a pause (a relay or host stalling mid-frame) is heard as two damaged
// runs; a repeater's copy of it comes whole later: its bytes are found among the runs, in order.
TEST(CopyGuard, AFrameHeardDamagedInPiecesIsKnownWhenItsCopyComesWhole) {
    CopyGuard guard(2s);
    guard.heard_damaged(hex("01 03 02"), read_10, t0);
    guard.heard_damaged(hex("00 00 B8 44"), {}, t0 + 30ms);
    const auto copy = guard.copy_of(reply_zero, read_11, 1, t0 + 300ms);
    ASSERT_TRUE(copy.has_value());
    EXPECT_EQ(copy->at, t0);
    // Damaged bytes heard only while this same request was awaited are its own answer's.
    CopyGuard own(2s);
    own.heard_damaged(hex("01 03 02 00"), read_11, t0);
    own.heard_damaged(hex("00 B8 44"), read_11, t0 + 30ms);
    EXPECT_FALSE(own.copy_of(reply_zero, read_11, 1, t0 + 300ms).has_value());
    EXPECT_FALSE(guard.copy_of(reply_zero, read_11, 1, t0 + 3s).has_value()) << "past the window";
}

}  // namespace
}  // namespace loopwire::session
