// MeshParsing: the helpers both mesh readers share (see MeshParsing.h).
#include "vdbrad/mesh/MeshParsing.h"

#include <openvdb/Exceptions.h>

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
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

// ---- polygons ----------------------------------------------------------------------------------

namespace {

using Vec2d = openvdb::math::Vec2<double>;

/// Twice the signed area of the triangle (a, b, c): positive counter-clockwise.
double
orient(const Vec2d& a, const Vec2d& b, const Vec2d& c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/// Ear clipping of the counter-clockwise polygon @a p into @a out (indices into p). False if
/// the outline runs out of ears (it crosses itself) or the work exceeds a bound quadratic in
/// its size (the file is untrusted; a simple polygon stays far below it).
bool
earClip(const std::vector<Vec2d>& p, std::vector<std::array<uint32_t, 3>>& out)
{
    std::vector<uint32_t> ring(p.size());
    std::iota(ring.begin(), ring.end(), 0u);
    out.clear();
    size_t budget = 16 * p.size() * p.size();
    size_t i = 0, tried = 0;
    bool flat = false;   // no proper ear left: take a flat one (collinear or repeated corners)
    while (ring.size() > 3) {
        const size_t m = ring.size();
        if (tried >= m) {
            if (flat) return false;
            flat = true;
            tried = 0;
        }
        i %= m;
        const uint32_t a = ring[(i + m - 1) % m], b = ring[i], c = ring[(i + 1) % m];
        const double o = orient(p[a], p[b], p[c]);
        // A proper ear: convex, and no other corner in or on it.
        bool ear = flat ? o == 0.0 : o > 0.0;
        for (size_t j = 0; !flat && ear && j < m; ++j) {
            const uint32_t q = ring[j];
            if (q == a || q == b || q == c) continue;
            if (p[q] == p[a] || p[q] == p[b] || p[q] == p[c]) continue;   // a repeated corner
            if (budget-- == 0) return false;
            ear = !(orient(p[a], p[b], p[q]) >= 0.0 && orient(p[b], p[c], p[q]) >= 0.0
                && orient(p[c], p[a], p[q]) >= 0.0);
        }
        if (!ear) {
            ++i;
            ++tried;
            continue;
        }
        out.push_back({a, b, c});
        ring.erase(ring.begin() + std::ptrdiff_t(i));
        i = i == 0 ? m - 2 : i - 1;   // the corner before changed: try it next
        tried = 0;
        flat = false;
    }
    out.push_back({ring[0], ring[1], ring[2]});
    return true;
}

} // namespace

void
triangulatePolygons(const std::vector<openvdb::Vec3f>& points,
    std::vector<openvdb::Vec3I>& triangles, const std::vector<PolygonFan>& fans)
{
    using openvdb::Vec3d;
    std::vector<uint32_t> polygon;
    std::vector<Vec3d> corners;
    std::vector<Vec2d> flat;
    std::vector<std::array<uint32_t, 3>> ears;
    for (const PolygonFan& fan : fans) {
        // Ear clipping is quadratic in the corners: a larger polygon keeps its fan.
        if (fan.count < 2 || fan.count > 254) continue;
        polygon.assign({triangles[fan.first][0], triangles[fan.first][1]});
        for (uint32_t j = 0; j < fan.count; ++j) polygon.push_back(triangles[fan.first + j][2]);
        const size_t n = polygon.size();
        corners.resize(n);
        for (size_t i = 0; i < n; ++i) corners[i] = Vec3d(points[polygon[i]]);
        // Newell's normal: the polygon's vector area, robust to collinear and repeated corners.
        Vec3d normal(0.0);
        for (size_t i = 0; i < n; ++i) normal += corners[i].cross(corners[(i + 1) % n]);
        if (!(normal.lengthSqr() > 0.0)) continue;
        // Convex (no corner turning against the normal, within rounding): the fan is exact.
        bool convex = true;
        for (size_t i = 0; i < n && convex; ++i) {
            const Vec3d in = corners[i] - corners[(i + n - 1) % n];
            const Vec3d out = corners[(i + 1) % n] - corners[i];
            const double turn = in.cross(out).dot(normal);
            convex = turn >= -1e-9 * in.length() * out.length() * normal.length();
        }
        if (convex) continue;
        // In the plane of the two axes other than the normal's dominant one, ordered so that the
        // polygon runs counter-clockwise.
        const int k = int(std::abs(normal[0]) >= std::abs(normal[1])
            ? (std::abs(normal[0]) >= std::abs(normal[2]) ? 0 : 2)
            : (std::abs(normal[1]) >= std::abs(normal[2]) ? 1 : 2));
        int u = (k + 1) % 3, v = (k + 2) % 3;
        if (normal[k] < 0.0) std::swap(u, v);
        flat.resize(n);
        for (size_t i = 0; i < n; ++i) flat[i] = Vec2d(corners[i][u], corners[i][v]);
        if (!earClip(flat, ears)) continue;
        for (uint32_t j = 0; j < fan.count; ++j) {
            triangles[fan.first + j] = openvdb::Vec3I(polygon[ears[j][0]], polygon[ears[j][1]],
                polygon[ears[j][2]]);
        }
    }
}

} // namespace parsing
} // namespace vdbrad
