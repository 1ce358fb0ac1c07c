// Compiles the test programs' precompiled header (test_pch.h) for objscan_test_pch, which the test
// programs reuse (tests/CMakeLists.txt).
