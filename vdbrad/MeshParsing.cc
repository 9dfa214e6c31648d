// MeshParsing: the helpers both mesh readers share (see MeshParsing.h).
#include "vdbrad/MeshParsing.h"

#include <openvdb/Exceptions.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <sys/stat.h>

namespace vdbrad {
namespace parsing {

namespace {

bool
isBlank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

} // namespace

std::string
at(const std::string& name, size_t line)
{
    return name + ":" + std::to_string(line);
}

std::string
quote(std::string_view s)
{
    std::string out = "'";
    for (size_t i = 0; i < s.size() && i < 40; ++i) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        out += (c >= 32 && c < 127) ? char(c) : '?';
    }
    if (s.size() > 40) out += "...";
    return out + "'";
}

std::string_view
trim(std::string_view s)
{
    while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
    while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
    return s;
}

void
split(std::string_view s, std::vector<std::string_view>& tokens)
{
    tokens.clear();
    size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && isBlank(s[i])) ++i;
        const size_t start = i;
        while (i < s.size() && !isBlank(s[i])) ++i;
        if (i > start) tokens.push_back(s.substr(start, i - start));
    }
}

bool
parseDouble(std::string_view s, double& v)
{
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    if (s.empty()) return false;
    const char* end = s.data() + s.size();
    const auto [ptr, ec] = std::from_chars(s.data(), end, v);
    if (ptr != end) return false;
    if (ec == std::errc::result_out_of_range) {
        // Well-formed but beyond double: overflow must read as infinite (and be refused as
        // such), underflow as zero. A negative exponent, or none on a mantissa below 1, is
        // underflow.
        const bool negative = s[0] == '-';
        const size_t e = s.find_first_of("eE");
        const std::string_view mantissa = s.substr(negative ? 1 : 0, e - (negative ? 1 : 0));
        const bool tiny = e != std::string_view::npos
            ? (e + 1 < s.size() && s[e + 1] == '-')
            : (mantissa[0] == '.' || (mantissa.size() > 1 && mantissa.substr(0, 2) == "0."));
        v = tiny ? 0.0 : std::numeric_limits<double>::infinity();
        if (negative) v = -v;
        return true;
    }
    return ec == std::errc();
}

bool
fitsFloat(double v)
{
    return std::isfinite(v) && std::abs(v) <= double(std::numeric_limits<float>::max());
}

std::string
formatNumber(double v)
{
    std::ostringstream os;
    os << v;
    return os.str();
}

void
openFile(std::ifstream& f, const std::string& path, const std::string& label)
{
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
        OPENVDB_THROW(openvdb::IoError, label << ": cannot open: is a directory");
    }
    f.open(path, std::ios::binary);
    if (!f) OPENVDB_THROW(openvdb::IoError, label << ": cannot open: " << std::strerror(errno));
}

} // namespace parsing
} // namespace vdbrad
