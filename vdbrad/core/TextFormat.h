// TextFormat: numbers as the library's and the tool's messages print them.
#pragma once

#include <cstdint>
#include <iomanip>
#include <sstream>
#include <string>

namespace vdbrad {

/// 1234567 -> "1,234,567".
inline std::string
withCommas(uint64_t n)
{
    std::string s = std::to_string(n);
    for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
    return s;
}

/// Bytes in binary units with one decimal: "512.0 B", "1.5 GiB".
inline std::string
formatBytes(double b)
{
    std::ostringstream os;
    os << std::fixed << std::setprecision(1);
    if (b < 1024) os << b << " B";
    else if (b < 1024 * 1024) os << b / 1024 << " KiB";
    else if (b < 1024.0 * 1024 * 1024) os << b / (1024 * 1024) << " MiB";
    else if (b < 1024.0 * 1024 * 1024 * 1024) os << b / (1024.0 * 1024 * 1024) << " GiB";
    else os << b / (1024.0 * 1024 * 1024 * 1024) << " TiB";
    return os.str();
}

} // namespace vdbrad
