// ProcessInfo: what this process and this machine hold, read once here for every layer and host
// (memory limits, progress lines, the crash guard's address-space cap).
#pragma once

namespace vdbrad {

/// Bytes this process holds in memory now (its resident set; Linux /proc/self/statm). 0 where it
/// cannot be read.
double residentBytes();

/// Bytes of this process's address space now (virtual size; /proc/self/statm). 0 where it cannot
/// be read.
double virtualBytes();

/// Bytes of physical memory of this machine. 0 where it cannot be read.
double physicalMemory();

} // namespace vdbrad
