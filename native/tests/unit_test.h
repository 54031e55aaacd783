/// @file unit_test.h
/// @brief A minimal test harness for the core's C++ unit tests: TEST(name) { CHECK(...); } and a main
/// that runs them all and reports each failed check with its file and line.
#pragma once

#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

namespace pcvr::unit {

struct Registry {
    std::vector<std::pair<std::string, std::function<void()>>> tests;
    int failures = 0;
    static Registry& get() {
        static Registry r;
        return r;
    }
};

struct Register {
    Register(const char* name, std::function<void()> fn) { Registry::get().tests.emplace_back(name, std::move(fn)); }
};

inline void fail(const char* file, int line, const std::string& what) {
    ++Registry::get().failures;
    std::fprintf(stderr, "%s:%d: check failed: %s\n", file, line, what.c_str());
}

}  // namespace pcvr::unit

#define TEST(name)                                                         \
    static void test_##name();                                            \
    static ::pcvr::unit::Register register_##name(#name, test_##name);   \
    static void test_##name()

#define CHECK(condition) \
    ((condition) ? (void)0 : ::pcvr::unit::fail(__FILE__, __LINE__, #condition))

/// |a - b| <= tolerance, with both values in the message when it fails.
#define CHECK_NEAR(a, b, tolerance)                                                                        \
    do {                                                                                                   \
        const double a_ = (a), b_ = (b);                                                                   \
        if (!(std::abs(a_ - b_) <= (tolerance)))                                                           \
            ::pcvr::unit::fail(__FILE__, __LINE__,                                                         \
                               std::string(#a " ~ " #b ": ") + std::to_string(a_) + " vs " + std::to_string(b_)); \
    } while (0)
