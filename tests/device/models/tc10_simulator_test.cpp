// The tc10 behaviour model through the wire.
#include <gtest/gtest.h>
