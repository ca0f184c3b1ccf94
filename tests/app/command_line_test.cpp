#include <gtest/gtest.h>

#include "app/command_line.hpp"
#include "app/exit_codes.hpp"

namespace loopwire::app {
namespace {

TEST(ExitCodes, EachErrorKindHasItsOwnStatus) {
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::usage, "")), 2);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::link, "")), 3);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::timeout, "")), 4);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::exception, "", 2)), 5);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::mismatch, "")), 6);
}

}  // namespace
}  // namespace loopwire::app
