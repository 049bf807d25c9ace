// Compiles the tests' shared precompiled header (tests/CMakeLists.txt, drape_test_pch).
