#include "vdbrad/core/ProcessInfo.h"

#include <unistd.h>

#include <cstdio>

namespace vdbrad {

namespace {

double
pageBytes()
{
    const long size = ::sysconf(_SC_PAGESIZE);
    return size > 0 ? double(size) : 0.0;
}

// The first two fields of /proc/self/statm: total and resident pages.
bool
statm(unsigned long& total, unsigned long& resident)
{
    FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return false;
    const bool ok = std::fscanf(f, "%lu %lu", &total, &resident) == 2;
    std::fclose(f);
    return ok;
}

} // namespace

double
residentBytes()
{
    unsigned long total = 0, resident = 0;
    return statm(total, resident) ? double(resident) * pageBytes() : 0.0;
}

double
virtualBytes()
{
    unsigned long total = 0, resident = 0;
    return statm(total, resident) ? double(total) * pageBytes() : 0.0;
}

double
physicalMemory()
{
    const long pages = ::sysconf(_SC_PHYS_PAGES);
    return pages > 0 ? double(pages) * pageBytes() : 0.0;
}

} // namespace vdbrad
