// The ac20 behaviour model through the wire.
#include <gtest/gtest.h>
