// PlyReader: PLY files, ascii or binary in either byte order (Mesh.h: readPly), read as untrusted
// data (MeshParsing.h).
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/MeshParsing.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>

namespace vdbrad {

namespace {

using openvdb::Vec3f;
using openvdb::Vec3I;
using namespace parsing;   // MeshParsing.h

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool
plyType(std::string_view s, PlyType& t)
{
    static const std::pair<const char*, PlyType> kNames[] = {
        {"char", PlyType::Int8}, {"int8", PlyType::Int8},
        {"uchar", PlyType::UInt8}, {"uint8", PlyType::UInt8},
        {"short", PlyType::Int16}, {"int16", PlyType::Int16},
        {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},
        {"int", PlyType::Int32}, {"int32", PlyType::Int32},
        {"uint", PlyType::UInt32}, {"uint32", PlyType::UInt32},
        {"float", PlyType::Float32}, {"float32", PlyType::Float32},
        {"double", PlyType::Float64}, {"float64", PlyType::Float64}};
    for (const auto& [n, type] : kNames) {
        if (s == n) {
            t = type;
            return true;
        }
    }
    return false;
}

size_t
typeSize(PlyType t)
{
    switch (t) {
        case PlyType::Int8: case PlyType::UInt8: return 1;
        case PlyType::Int16: case PlyType::UInt16: return 2;
        case PlyType::Int32: case PlyType::UInt32: case PlyType::Float32: return 4;
        case PlyType::Float64: return 8;
    }
    return 0;
}

bool
isInteger(PlyType t)
{
    return t != PlyType::Float32 && t != PlyType::Float64;
}

/// What a colour channel of this type reads as 1: floats are already in [0, 1].
double
colourScale(PlyType t)
{
    if (!isInteger(t)) return 1.0;
    return (t == PlyType::Int16 || t == PlyType::UInt16) ? 65535.0 : 255.0;
}

struct PlyProperty
{
    std::string name;
    PlyType type;        // the item type, for a list
    bool isList = false;
    PlyType countType = PlyType::UInt8;
};

struct PlyElement
{
    std::string name;
    uint64_t count;
    size_t line;         // header line, for messages
    std::vector<PlyProperty> properties;
};

std::string
plural(const std::string& element)
{
    if (element == "vertex") return "vertices";
    if (element == "face") return "faces";
    return "'" + element + "' elements";
}

std::string
singular(const std::string& element)
{
    return (element == "vertex" || element == "face") ? element : "'" + element + "' element";
}

/// Values of a binary body, in either byte order.
class BinaryReader
{
public:
    BinaryReader(const std::string& name, const char* begin, const char* end, bool swap)
        : mName(name), mPtr(begin), mEnd(end), mSwap(swap) {}

    std::string where() const { return mName; }
    bool beginElement() { return true; }
    void endElement() {}

    bool value(PlyType t, double& v)
    {
        const size_t n = typeSize(t);
        if (size_t(mEnd - mPtr) < n) return false;
        unsigned char b[8];
        std::memcpy(b, mPtr, n);
        mPtr += n;
        if (mSwap) std::reverse(b, b + n);
        switch (t) {
            case PlyType::Int8: { int8_t x; std::memcpy(&x, b, 1); v = x; break; }
            case PlyType::UInt8: v = b[0]; break;
            case PlyType::Int16: { int16_t x; std::memcpy(&x, b, 2); v = x; break; }
            case PlyType::UInt16: { uint16_t x; std::memcpy(&x, b, 2); v = x; break; }
            case PlyType::Int32: { int32_t x; std::memcpy(&x, b, 4); v = x; break; }
            case PlyType::UInt32: { uint32_t x; std::memcpy(&x, b, 4); v = x; break; }
            case PlyType::Float32: { float x; std::memcpy(&x, b, 4); v = x; break; }
            case PlyType::Float64: std::memcpy(&v, b, 8); break;
        }
        return true;
    }

    [[noreturn]] void truncated(const PlyElement& e, uint64_t done) const
    {
        OPENVDB_THROW(openvdb::IoError, mName << ": truncated: expected " << e.count << " "
            << plural(e.name) << ", file ends after " << done);
    }
    /// In binary data a value missing mid-element is the end of the file.
    [[noreturn]] void tooFew(const PlyElement& e, uint64_t done) const { truncated(e, done); }

private:
    const std::string& mName;
    const char* mPtr;
    const char* mEnd;
    bool mSwap;
};

/// Values of an ASCII body: one element per line, blank lines skipped.
class AsciiReader
{
public:
    AsciiReader(const std::string& name, std::string_view body, size_t firstLine)
        : mName(name), mBody(body), mLine(firstLine - 1) {}

    std::string where() const { return at(mName, mLine); }

    bool beginElement()
    {
        while (mPos < mBody.size()) {
            size_t nl = mBody.find('\n', mPos);
            if (nl == std::string_view::npos) nl = mBody.size();
            const std::string_view text = mBody.substr(mPos, nl - mPos);
            mPos = nl + 1;
            ++mLine;
            split(text, mTokens);
            mNext = 0;
            if (!mTokens.empty()) return true;
        }
        return false;
    }

    void endElement()
    {
        if (mNext < mTokens.size()) {
            OPENVDB_THROW(openvdb::ValueError, where() << ": " << mTokens.size() - mNext
                << " more values than the header's properties");
        }
    }

    bool value(PlyType t, double& v)
    {
        if (mNext >= mTokens.size()) return false;
        const std::string_view token = mTokens[mNext++];
        if (!parseDouble(token, v)) {
            OPENVDB_THROW(openvdb::ValueError, where() << ": bad number " << quote(token));
        }
        if (isInteger(t) && std::isfinite(v) && v != std::floor(v)) {
            OPENVDB_THROW(openvdb::ValueError, where() << ": " << quote(token)
                << " is not an integer");
        }
        return true;
    }

    [[noreturn]] void truncated(const PlyElement& e, uint64_t done) const
    {
        OPENVDB_THROW(openvdb::IoError, mName << ": truncated: expected " << e.count << " "
            << plural(e.name) << ", file ends after " << done);
    }
    [[noreturn]] void tooFew(const PlyElement& e, uint64_t) const
    {
        OPENVDB_THROW(openvdb::ValueError, where() << ": too few values for "
            << singular(e.name) << " (" << e.properties.size() << " properties)");
    }

private:
    const std::string& mName;
    std::string_view mBody;
    size_t mPos = 0;
    size_t mLine;
    std::vector<std::string_view> mTokens;
    size_t mNext = 0;
};

/// Where the properties the mesh needs sit in an element's property list (-1: absent).
struct Roles
{
    int x = -1, y = -1, z = -1, red = -1, green = -1, blue = -1, indices = -1;

    bool hasColour() const { return red >= 0 && green >= 0 && blue >= 0; }
};

Roles
findRoles(const PlyElement& e)
{
    Roles r;
    for (size_t i = 0; i < e.properties.size(); ++i) {
        const std::string& n = e.properties[i].name;
        const int k = int(i);
        if (e.properties[i].isList) {
            if ((n == "vertex_indices" || n == "vertex_index") && r.indices < 0) r.indices = k;
            continue;
        }
        if (n == "x") r.x = k;
        else if (n == "y") r.y = k;
        else if (n == "z") r.z = k;
        else if (n == "red" || n == "diffuse_red") r.red = k;
        else if (n == "green" || n == "diffuse_green") r.green = k;
        else if (n == "blue" || n == "diffuse_blue") r.blue = k;
    }
    return r;
}

class PlyMeshBuilder
{
public:
    explicit PlyMeshBuilder(TriangleMesh& mesh): mMesh(mesh) {}

    int32_t material(const std::array<double, 3>& c)
    {
        // Exact deduplication on the float values (+0.f folds -0 into 0).
        const Vec3f albedo{float(c[0]) + 0.f, float(c[1]) + 0.f, float(c[2]) + 0.f};
        std::array<uint32_t, 3> key;
        std::memcpy(key.data(), albedo.asPointer(), sizeof(key));
        const auto found = mIndex.find(key);
        if (found != mIndex.end()) return found->second;
        const int32_t id = int32_t(mMesh.materials.size());
        Material m;
        std::ostringstream name;
        name << std::setprecision(6) << "rgb(" << 255.0 * albedo[0] << ","
             << 255.0 * albedo[1] << "," << 255.0 * albedo[2] << ")";
        m.name = name.str();
        m.albedo = albedo;
        mMesh.materials.push_back(m);
        mIndex.emplace(key, id);
        return id;
    }

private:
    TriangleMesh& mMesh;
    std::map<std::array<uint32_t, 3>, int32_t> mIndex;
};

/// An element's red, green and blue as read, with what each reads as 1 (255 for uchar).
template<typename Reader>
std::pair<std::array<double, 3>, std::array<double, 3>>
colourOf(const PlyElement& e, const Roles& roles, const std::vector<double>& values,
    const Reader& reader, uint64_t i)
{
    std::array<double, 3> raw, scale;
    const int idx[3] = {roles.red, roles.green, roles.blue};
    for (int ch = 0; ch < 3; ++ch) {
        raw[ch] = values[idx[ch]];
        scale[ch] = colourScale(e.properties[idx[ch]].type);
        if (!(raw[ch] >= 0.0 && raw[ch] <= scale[ch])) {
            OPENVDB_THROW(openvdb::ValueError, reader.where() << ": " << singular(e.name) << " "
                << i << ": colour value " << formatNumber(raw[ch]) << " outside [0, "
                << scale[ch] << "]");
        }
    }
    return {raw, scale};
}

template<typename Reader>
void
readPlyBody(Reader& reader, const std::vector<PlyElement>& elements, size_t vertexCount,
    TriangleMesh& mesh)
{
    // Vertex colours are kept as read (0..255 for uchar) with the divisor that maps them to
    // [0, 1]: sums of raw integers are exact, so a triangle's mean colour (and so its material)
    // does not depend on its vertex order. Kept until the end: faces may come first.
    std::vector<std::array<float, 3>> vertexColours;
    double vertexScale = 1.0;
    bool faceColours = false;
    struct PendingFace { size_t firstTriangle, triangles; std::array<double, 3> colour; };
    std::vector<PendingFace> colouredFaces;
    std::vector<PolygonFan> fans;   // polygons of more than 3 vertices, checked at the end

    std::vector<uint32_t> polygon;
    for (const PlyElement& e : elements) {
        // Nothing to read (and a binary loop over a huge count of them would spin for nothing).
        if (e.properties.empty()) continue;
        const Roles roles = findRoles(e);
        const bool isVertex = e.name == "vertex", isFace = e.name == "face";
        // Never more than the body could hold (the header check bounds e.count by the bytes).
        if (isVertex) {
            mesh.points.resize(size_t(e.count));
            if (roles.hasColour()) {
                vertexColours.resize(size_t(e.count));
                vertexScale = colourScale(e.properties[roles.red].type);
            }
        }
        if (isFace) faceColours = roles.hasColour();
        std::vector<double> values(e.properties.size());
        for (uint64_t i = 0; i < e.count; ++i) {
            if (!reader.beginElement()) reader.truncated(e, i);
            polygon.clear();
            for (size_t p = 0; p < e.properties.size(); ++p) {
                const PlyProperty& prop = e.properties[p];
                if (!prop.isList) {
                    if (!reader.value(prop.type, values[p])) reader.tooFew(e, i);
                    continue;
                }
                double n;
                if (!reader.value(prop.countType, n)) reader.tooFew(e, i);
                if (!(n >= 0.0)) {
                    OPENVDB_THROW(openvdb::ValueError, reader.where() << ": " << singular(e.name)
                        << " " << i << ": negative list length " << formatNumber(n));
                }
                const bool keep = isFace && int(p) == roles.indices;
                // Items are read one by one, so a huge length runs out of data, not memory.
                for (double k = 0; k < n; ++k) {
                    double v;
                    if (!reader.value(prop.type, v)) reader.tooFew(e, i);
                    if (!keep) continue;
                    if (!(v >= 0.0 && v < double(vertexCount))) {
                        OPENVDB_THROW(openvdb::ValueError, reader.where() << ": face " << i
                            << ": vertex index " << formatNumber(v) << (vertexCount
                                ? " out of range [0, " + std::to_string(vertexCount - 1) + "]"
                                : std::string(" but the file has no vertices")));
                    }
                    polygon.push_back(uint32_t(v));
                }
            }
            reader.endElement();

            if (isVertex) {
                const double x = values[roles.x], y = values[roles.y], z = values[roles.z];
                if (!fitsFloat(x) || !fitsFloat(y) || !fitsFloat(z)) {
                    OPENVDB_THROW(openvdb::ValueError, reader.where() << ": vertex " << i
                        << ": coordinates (" << x << ", " << y << ", " << z
                        << ") are not finite floats");
                }
                mesh.points[i] = Vec3f(float(x), float(y), float(z));
                if (roles.hasColour()) {
                    const auto [raw, scale] = colourOf(e, roles, values, reader, i);
                    for (int ch = 0; ch < 3; ++ch) {
                        // A channel of another type than red is brought to red's scale.
                        vertexColours[i][ch] = float(scale[ch] == vertexScale
                            ? raw[ch] : raw[ch] / scale[ch] * vertexScale);
                    }
                }
            } else if (isFace) {
                if (polygon.size() < 3) {
                    OPENVDB_THROW(openvdb::ValueError, reader.where() << ": face " << i
                        << " has " << polygon.size() << " vertices (at least 3 needed)");
                }
                const size_t first = mesh.triangles.size();
                // A fan now (the vertices may come after the faces); concave polygons are
                // re-triangulated at the end.
                if (polygon.size() > 3) fans.push_back({first, uint32_t(polygon.size() - 2)});
                for (size_t k = 1; k + 1 < polygon.size(); ++k) {
                    mesh.triangles.emplace_back(polygon[0], polygon[k], polygon[k + 1]);
                }
                if (faceColours) {
                    const auto [raw, scale] = colourOf(e, roles, values, reader, i);
                    colouredFaces.push_back({first, mesh.triangles.size() - first,
                        {raw[0] / scale[0], raw[1] / scale[1], raw[2] / scale[2]}});
                }
            }
        }
    }

    triangulatePolygons(mesh.points, mesh.triangles, fans);

    // Face colours win over vertex colours when a file has both.
    PlyMeshBuilder builder(mesh);
    if (faceColours) {
        mesh.triangleMaterials.resize(mesh.triangles.size());
        for (const PendingFace& f : colouredFaces) {
            const int32_t m = builder.material(f.colour);
            std::fill_n(mesh.triangleMaterials.begin() + f.firstTriangle, f.triangles, m);
        }
    } else if (!vertexColours.empty()) {
        mesh.triangleMaterials.resize(mesh.triangles.size());
        for (size_t t = 0; t < mesh.triangles.size(); ++t) {
            std::array<double, 3> c;
            for (int ch = 0; ch < 3; ++ch) {
                const Vec3I& tri = mesh.triangles[t];
                c[ch] = (double(vertexColours[tri[0]][ch]) + vertexColours[tri[1]][ch]
                    + vertexColours[tri[2]][ch]) / (3.0 * vertexScale);
            }
            mesh.triangleMaterials[t] = builder.material(c);
        }
    }
}

std::string
readStream(std::istream& in, const std::string& name)
{
    std::string data;
    char buffer[1 << 16];
    while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
        data.append(buffer, size_t(in.gcount()));
    }
    if (in.bad()) OPENVDB_THROW(openvdb::IoError, name << ": read error");
    return data;
}

enum class PlyFormat { None, Ascii, Little, Big };

/// What a PLY header says, and where its body starts.
struct PlyHeader
{
    PlyFormat format = PlyFormat::None;
    std::vector<PlyElement> elements;
    size_t pos = 0;    // offset of the body in the data
    size_t line = 0;   // number of the header's last line
};

/// The header's lines: CR stripped, counted for messages.
struct HeaderLines
{
    const std::string& data;
    size_t pos = 0;    // where the next line starts
    size_t line = 0;   // number of the line last read

    bool next(std::string_view& out)
    {
        if (pos >= data.size()) return false;
        size_t nl = data.find('\n', pos);
        if (nl == std::string::npos) nl = data.size();
        out = std::string_view(data).substr(pos, nl - pos);
        if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
        pos = nl + 1;
        ++line;
        return true;
    }
};

/// `element NAME COUNT`
PlyElement
parseElementLine(const std::vector<std::string_view>& tokens, const std::string& where,
    size_t line)
{
    unsigned long long count = 0;
    bool ok = tokens.size() == 3;
    if (ok) {
        const char* end = tokens[2].data() + tokens[2].size();
        const auto [ptr, ec] = std::from_chars(tokens[2].data(), end, count);
        ok = ec == std::errc() && ptr == end;
    }
    if (!ok) {
        OPENVDB_THROW(openvdb::ValueError, where << ": expected 'element NAME COUNT'"
            << (tokens.size() == 3 ? ", bad count " + quote(tokens[2]) : ""));
    }
    return {std::string(tokens[1]), count, line, {}};
}

/// `property TYPE NAME` or `property list COUNT ITEM NAME`
PlyProperty
parsePropertyLine(const std::vector<std::string_view>& tokens, const std::string& where)
{
    PlyProperty p;
    if (tokens.size() == 5 && tokens[1] == "list") {
        p.isList = true;
        if (!plyType(tokens[2], p.countType) || !plyType(tokens[3], p.type)) {
            OPENVDB_THROW(openvdb::ValueError, where << ": unknown list types "
                << quote(tokens[2]) << " " << quote(tokens[3]));
        }
        if (!isInteger(p.countType)) {
            OPENVDB_THROW(openvdb::ValueError, where << ": list count type "
                << quote(tokens[2]) << " is not an integer type");
        }
        p.name = std::string(tokens[4]);
    } else if (tokens.size() == 3) {
        if (!plyType(tokens[1], p.type)) {
            OPENVDB_THROW(openvdb::ValueError, where << ": unknown property type "
                << quote(tokens[1]));
        }
        p.name = std::string(tokens[2]);
    } else {
        OPENVDB_THROW(openvdb::ValueError, where
            << ": expected 'property TYPE NAME' or 'property list COUNT ITEM NAME'");
    }
    return p;
}

/// The header, up to and including `end_header`.
PlyHeader
readPlyHeader(const std::string& data, const std::string& name)
{
    HeaderLines lines{data};
    std::string_view text;
    if (!lines.next(text) || text != "ply") {
        OPENVDB_THROW(openvdb::ValueError, name << ": not a PLY file (no 'ply' line first)");
    }
    PlyHeader header;
    std::vector<std::string_view> tokens;
    bool ended = false;
    while (!ended && lines.next(text)) {
        split(text, tokens);
        if (tokens.empty()) continue;
        const std::string_view key = tokens[0];
        const std::string where = at(name, lines.line);
        if (key == "comment" || key == "obj_info") continue;
        if (key == "end_header") {
            ended = true;
        } else if (key == "format") {
            if (tokens.size() != 3) {
                OPENVDB_THROW(openvdb::ValueError, where << ": expected 'format TYPE 1.0'");
            }
            if (tokens[1] == "ascii") header.format = PlyFormat::Ascii;
            else if (tokens[1] == "binary_little_endian") header.format = PlyFormat::Little;
            else if (tokens[1] == "binary_big_endian") header.format = PlyFormat::Big;
            else {
                OPENVDB_THROW(openvdb::ValueError, where << ": unknown format "
                    << quote(tokens[1]));
            }
        } else if (key == "element") {
            header.elements.push_back(parseElementLine(tokens, where, lines.line));
        } else if (key == "property") {
            if (header.elements.empty()) {
                OPENVDB_THROW(openvdb::ValueError, where << ": property before any element");
            }
            header.elements.back().properties.push_back(parsePropertyLine(tokens, where));
        } else {
            OPENVDB_THROW(openvdb::ValueError, where << ": unexpected header line "
                << quote(text));
        }
    }
    if (!ended) OPENVDB_THROW(openvdb::ValueError, name << ": header has no end_header");
    if (header.format == PlyFormat::None) {
        OPENVDB_THROW(openvdb::ValueError, name << ": no format line");
    }
    header.pos = lines.pos;
    header.line = lines.line;
    return header;
}

/// What the header promises, checked before anything is sized from it; the vertex element.
const PlyElement&
checkPlyHeader(const PlyHeader& header, const std::string& data, const std::string& name)
{
    const std::vector<PlyElement>& elements = header.elements;
    const PlyElement* vertex = nullptr;
    const PlyElement* face = nullptr;
    for (const PlyElement& e : elements) {
        const std::string where = at(name, e.line);
        const Roles roles = findRoles(e);
        if (e.name == "vertex") {
            if (vertex) OPENVDB_THROW(openvdb::ValueError, where << ": second vertex element");
            vertex = &e;
            if (roles.x < 0 || roles.y < 0 || roles.z < 0) {
                OPENVDB_THROW(openvdb::ValueError, where << ": vertex element lacks x, y or z");
            }
        } else if (e.name == "face") {
            if (face) OPENVDB_THROW(openvdb::ValueError, where << ": second face element");
            face = &e;
            if (roles.indices < 0) {
                OPENVDB_THROW(openvdb::ValueError, where
                    << ": face element has no vertex_indices list");
            }
            if (!isInteger(e.properties[roles.indices].type)) {
                OPENVDB_THROW(openvdb::ValueError, where
                    << ": face vertex indices are not of an integer type");
            }
        }
    }
    if (!vertex) OPENVDB_THROW(openvdb::ValueError, name << ": no vertex element");
    if (!face || face->count == 0) OPENVDB_THROW(openvdb::ValueError, name << ": no triangles");
    // Every element with properties takes at least one byte, in any format. A header claiming
    // more elements than there are bytes left is not a file cut short but a corrupt or hostile
    // one: refuse it before anything is sized from the count. Smaller shortfalls are found
    // while reading and reported as truncation, with how far the data got.
    const uint64_t bytes = data.size() - std::min(header.pos, data.size());
    uint64_t claimed = 0;
    for (const PlyElement& e : elements) {
        if (e.properties.empty()) continue;
        claimed += std::min<uint64_t>(e.count, bytes + 1);
        if (e.count > bytes || claimed > bytes) {
            OPENVDB_THROW(openvdb::ValueError, at(name, e.line) << ": header claims "
                << e.count << " " << plural(e.name) << " but only " << bytes
                << " bytes of data follow it");
        }
    }
    if (vertex->count > std::numeric_limits<uint32_t>::max()) {
        OPENVDB_THROW(openvdb::ValueError, name << ": " << vertex->count
            << " vertices: more than 32-bit indices can address");
    }
    return *vertex;
}

TriangleMesh
parsePly(const std::string& data, const std::string& name)
{
    const PlyHeader header = readPlyHeader(data, name);
    const PlyElement& vertex = checkPlyHeader(header, data, name);
    const size_t pos = header.pos;

    TriangleMesh mesh;
    if (header.format == PlyFormat::Ascii) {
        AsciiReader reader(name, std::string_view(data).substr(pos), header.line + 1);
        readPlyBody(reader, header.elements, size_t(vertex.count), mesh);
    } else {
        const uint16_t one = 1;
        unsigned char first;
        std::memcpy(&first, &one, 1);
        const bool hostLittle = first == 1;
        BinaryReader reader(name, data.data() + pos, data.data() + data.size(),
            (header.format == PlyFormat::Little) != hostLittle);
        readPlyBody(reader, header.elements, size_t(vertex.count), mesh);
    }
    if (mesh.triangles.empty()) OPENVDB_THROW(openvdb::ValueError, name << ": no triangles");
    return mesh;
}

} // namespace


TriangleMesh
readPly(std::istream& in, const std::string& name)
{
    return parsePly(readStream(in, name), name);
}


TriangleMesh
readPly(const std::string& path)
{
    std::ifstream in;
    openFile(in, path, path);
    return parsePly(readStream(in, path), path);
}

} // namespace vdbrad
