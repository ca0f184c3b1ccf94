// The rampsoak behaviour model through the wire.
#include <gtest/gtest.h>
