// The source of the object library that owns the test executables' shared precompiled header
// (tests/CMakeLists.txt); CMake needs one source to build the header for.
#include <gtest/gtest.h>
