// Runs every TEST of the core's C++ unit tests; exit status 1 when a check failed.
#include "unit_test.h"

int main() {
    auto& registry = pcvr::unit::Registry::get();
    for (const auto& [name, fn] : registry.tests) {
        const int before = registry.failures;
        fn();
        std::printf("%s %s\n", registry.failures == before ? "ok  " : "FAIL", name.c_str());
    }
    std::printf("%zu tests, %d failed checks\n", registry.tests.size(), registry.failures);
    return registry.failures == 0 ? 0 : 1;
}
