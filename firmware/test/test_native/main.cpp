// PlatformIO's native googletest run needs a main(); the CMake build links gtest_main instead.
#ifdef PIO_UNIT_TESTING
#include <gtest/gtest.h>

int main(int argc, char** argv) {
    ::testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
#endif
