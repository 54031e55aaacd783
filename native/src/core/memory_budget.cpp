#include "pcvr/memory_budget.h"

#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

constexpr uint64_t kUnlimited = std::numeric_limits<uint64_t>::max();

/// "MemAvailable:  123456 kB" from /proc/meminfo, in bytes.
uint64_t meminfo_available() {
    std::ifstream in("/proc/meminfo");
    std::string key, unit;
    uint64_t value = 0;
    while (in >> key >> value >> unit)
        if (key == "MemAvailable:") return value * 1024;
    return kUnlimited;
}

/// A number from a cgroup v2 file of this process's cgroup ("max" means none).
uint64_t cgroup_value(const std::string& file) {
    std::ifstream cgroup("/proc/self/cgroup");
    std::string line, path;
    while (std::getline(cgroup, line))
        if (line.rfind("0::", 0) == 0) path = line.substr(3);
    std::ifstream in("/sys/fs/cgroup" + path + "/" + file);
    std::string text;
    if (!(in >> text) || text == "max") return kUnlimited;
    try {
        return std::stoull(text);
    } catch (const std::exception&) {
        return kUnlimited;
    }
}

uint64_t address_space_left() {
    rlimit limit{};
    if (getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return kUnlimited;
    // What is mapped already counts against it.
    std::ifstream status("/proc/self/status");
    std::string key, unit;
    uint64_t mapped = 0;
    for (std::string line; std::getline(status, line);)
        if (line.rfind("VmSize:", 0) == 0) std::istringstream(line.substr(7)) >> mapped, mapped *= 1024;
    return limit.rlim_cur > mapped ? uint64_t(limit.rlim_cur) - mapped : 0;
}

}  // namespace

uint64_t default_memory_limit() {
    uint64_t limit = meminfo_available();
    const uint64_t cgroup_max = cgroup_value("memory.max");
    if (cgroup_max != kUnlimited) {
        const uint64_t used = cgroup_value("memory.current");
        limit = std::min(limit, cgroup_max > used && used != kUnlimited ? cgroup_max - used : 0);
    }
    return std::min(limit, address_space_left());
}

MemoryBudget::MemoryBudget(uint64_t limit) : limit_(limit ? limit : default_memory_limit()), default_limit_(limit == 0) {}

void MemoryBudget::add(std::string what, uint64_t bytes) {
    total_ += bytes;
    items_.emplace_back(std::move(what), bytes);
}

void MemoryBudget::check(const std::string& task) const {
    if (total_ <= limit_) return;
    std::string items;
    for (const auto& [what, bytes] : items_) items += (items.empty() ? "" : ", ") + what + " " + format_bytes(bytes);
    throw OutOfMemory(task + " needs about " + format_bytes(total_) + " (" + items + ") but may use only " +
                      format_bytes(limit_) +
                      (default_limit_ ? " (the memory this machine has available; memory_limit= sets another)"
                                      : " (memory_limit)") +
                      ": render a smaller image, or with fewer threads");
}

std::string format_bytes(uint64_t bytes) {
    static const char* const units[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    double value = double(bytes);
    int unit = 0;
    while (value >= 1024.0 && unit < 6) value /= 1024.0, ++unit;
    char text[32];
    std::snprintf(text, sizeof text, unit == 0 ? "%.0f %s" : "%.3g %s", value, units[unit]);
    return text;
}

}  // namespace pcvr
