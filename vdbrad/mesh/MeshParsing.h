// MeshParsing: what the OBJ and PLY readers (ObjReader.cc, PlyReader.cc) share, inside the
// library only.
//
// Both readers treat the file as untrusted: every count read from it is checked against the bytes
// that are actually there before anything is reserved, every index against the vertices that
// exist, every number for syntax and finiteness. Errors name the file (and the line, for text).
#pragma once

#include <openvdb/Types.h>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace vdbrad {
namespace parsing {

/// "name:line", where an error message points.
std::string at(const std::string& name, size_t line);

/// A token for an error message: quoted, short and printable, since it may be binary garbage.
std::string quote(std::string_view s);

/// @a s without leading and trailing blanks (space, tab, CR, vertical tab, form feed).
std::string_view trim(std::string_view s);

/// The blank-separated tokens of @a s, as views into it, replacing the contents of @a tokens.
void split(std::string_view s, std::vector<std::string_view>& tokens);

/// Locale-independent (unlike strtod, which a host application may have localised to "1,5").
/// Accepts a leading '+', which from_chars does not; nan and inf parse, the callers refuse them.
bool parseDouble(std::string_view s, double& v);

/// Finite and within float's range (converting a larger double to float is undefined behaviour).
bool fitsFloat(double v);

/// @a v as a stream writes it, for messages.
std::string formatNumber(double v);

/// Opens @a path or throws "<label>: cannot open: <reason>". Refuses directories up front: on
/// Linux they open as streams and then read as empty files.
void openFile(std::ifstream& f, const std::string& path, const std::string& label);

// ---- polygons ----------------------------------------------------------------------------------

/// A polygon of more than three vertices as a reader first stored it: the fan (v0 v1 v2),
/// (v0 v2 v3), ... at triangles [first, first + count). The fan alone holds its vertices, so a
/// reader can fan every polygon as it reads (vertices may still be to come) and fix the few
/// that need it at the end.
struct PolygonFan
{
    size_t first;
    uint32_t count;   // triangles: the polygon's vertices less two
};

/// @brief Re-triangulates each polygon of @a fans in place whose fan is wrong: a fan covers a
/// convex polygon exactly, but over a concave one (an L-shaped floor) it lays triangles outside
/// the outline, wound backwards. Those are ear-clipped in the plane of their Newell normal
/// instead, into as many triangles (so per-triangle materials stay put), wound as the polygon.
/// A fan that cannot be improved on (self-intersecting or degenerate outline, more than 256
/// vertices) is kept as it is.
void triangulatePolygons(const std::vector<openvdb::Vec3f>& points,
    std::vector<openvdb::Vec3I>& triangles, const std::vector<PolygonFan>& fans);

} // namespace parsing
} // namespace vdbrad
