// ObjReader: Wavefront OBJ files and their MTL material libraries (Mesh.h: readObj), read as
// untrusted text (MeshParsing.h).
#include "vdbrad/mesh/Mesh.h"

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/mesh/MeshParsing.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <fstream>
#include <limits>
#include <sys/stat.h>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

namespace vdbrad {

namespace {

using openvdb::Vec3f;
using namespace parsing;   // MeshParsing.h

// ---- OBJ and MTL text --------------------------------------------------------------------------

bool
equalsNoCase(std::string_view a, std::string_view b)
{
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
        return std::tolower(static_cast<unsigned char>(x)) ==
            std::tolower(static_cast<unsigned char>(y));
    });
}

bool
parseInt(std::string_view s, long long& v)
{
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    const char* end = s.data() + s.size();
    const auto [ptr, ec] = std::from_chars(s.data(), end, v);
    return !s.empty() && ec == std::errc() && ptr == end;
}

/// Lines of OBJ and MTL text: CR stripped, lines ending in a backslash joined to the next.
class LineReader
{
public:
    LineReader(std::istream& in, const std::string& name): mIn(in), mName(name) {}

    /// False at the end; @a line is the number of the (first physical) line of the text.
    bool next(std::string& text, size_t& line)
    {
        if (!std::getline(mIn, text)) return finish();
        line = ++mLine;
        stripCr(text);
        while (!text.empty() && text.back() == '\\') {
            text.back() = ' ';
            if (!std::getline(mIn, mMore)) break;
            ++mLine;
            stripCr(mMore);
            text += mMore;
        }
        return true;
    }

private:
    static void stripCr(std::string& s)
    {
        if (!s.empty() && s.back() == '\r') s.pop_back();
    }
    bool finish()
    {
        if (mIn.bad()) OPENVDB_THROW(openvdb::IoError, mName << ": read error");
        return false;
    }

    std::istream& mIn;
    const std::string& mName;
    std::string mMore;
    size_t mLine = 0;
};

/// The text after @a keyword (a token of @a line), for names that may contain spaces
/// ("usemtl Material 1").
std::string_view
restOfLine(std::string_view line, std::string_view keyword)
{
    return trim(line.substr(size_t(keyword.data() - line.data()) + keyword.size()));
}

} // namespace

bool
TriangleMesh::hasSpecular() const
{
    for (const Material& m : materials) {
        if (m.specular != openvdb::Vec3f(0.f)) return true;
    }
    return false;
}

float
Material::reflectance() const
{
    float worst = 0.f;
    for (int i = 0; i < 3; ++i) worst = std::max(worst, albedo[i] + specular[i]);
    return worst;
}

namespace {

// ---- MTL ---------------------------------------------------------------------------------------

struct MaterialTable
{
    std::vector<Material> materials;
    std::unordered_map<std::string, int32_t> index;
    std::unordered_set<int32_t> pbrRoughness;   // materials whose roughness came from Pr
};

/// Reads `Kd` / `Ke`: one value (grey) or three. Stops at a trailing comment.
Vec3f
parseColour(const std::vector<std::string_view>& tokens, const std::string& where)
{
    std::vector<double> values;
    for (size_t i = 1; i < tokens.size() && tokens[i][0] != '#'; ++i) {
        double v;
        if (!parseDouble(tokens[i], v)) {
            // "Kd spectral file.rfl" and "Kd xyz ..." exist in the MTL spec; silently using the
            // default colour instead would be worse than saying so.
            OPENVDB_THROW(openvdb::ValueError, where << ": " << tokens[0]
                << ": expected numbers (r g b), got " << quote(tokens[i]));
        }
        values.push_back(v);
    }
    if (values.size() != 1 && values.size() != 3) {
        OPENVDB_THROW(openvdb::ValueError, where << ": " << tokens[0]
            << " needs 1 (grey) or 3 (r g b) values, got " << values.size());
    }
    if (values.size() == 1) values.resize(3, values[0]);
    Vec3f c;
    for (int i = 0; i < 3; ++i) {
        if (!fitsFloat(values[i])) {
            OPENVDB_THROW(openvdb::ValueError, where << ": " << tokens[0] << " value "
                << formatNumber(values[i]) << " is not a finite float");
        }
        c[i] = float(values[i]);
    }
    return c;
}

/// Appends the materials of one MTL file. A name already defined (here or in an earlier library)
/// keeps its first definition, so triangles never change colour halfway through a file.
void
readMtl(const std::string& path, const std::string& context, MaterialTable& table)
{
    std::ifstream in;
    openFile(in, path, context + ": material library '" + path + "'");
    LineReader lines(in, path);
    std::string text;
    size_t line = 0;
    std::vector<std::string_view> tokens;
    int32_t current = -1;
    bool skipping = false;   // inside a duplicate definition
    while (lines.next(text, line)) {
        split(text, tokens);
        if (tokens.empty() || tokens[0][0] == '#') continue;
        const std::string_view key = tokens[0];
        const std::string where = at(path, line);
        if (equalsNoCase(key, "newmtl")) {
            const std::string name(restOfLine(text, key));
            if (name.empty()) {
                OPENVDB_THROW(openvdb::ValueError, where << ": newmtl without a name");
            }
            skipping = table.index.count(name) > 0;
            if (skipping) continue;
            current = int32_t(table.materials.size());
            table.index.emplace(name, current);
            Material m;
            m.name = name;
            // MTL's own default Kd is 0.8, but a material that sets no colour should look like
            // the rest of an uncoloured vdbrad scene: the tool's default --albedo, 0.5.
            m.albedo = Vec3f(0.5f);
            table.materials.push_back(m);
        } else if (equalsNoCase(key, "Kd") || equalsNoCase(key, "Ke")
                   || equalsNoCase(key, "Ks")) {
            if (current < 0 && !skipping) {
                OPENVDB_THROW(openvdb::ValueError, where << ": " << key << " before any newmtl");
            }
            const Vec3f c = parseColour(tokens, where);
            const bool emission = equalsNoCase(key, "Ke");
            for (int i = 0; i < 3; ++i) {
                if (!emission ? (c[i] < 0.f || c[i] > 1.f) : c[i] < 0.f) {
                    OPENVDB_THROW(openvdb::ValueError, where << ": " << key << " value "
                        << formatNumber(c[i]) << (!emission ? " outside [0, 1]" : " is negative"));
                }
            }
            if (skipping) continue;
            Material& m = table.materials[current];
            (emission ? m.emission : equalsNoCase(key, "Kd") ? m.albedo : m.specular) = c;
        } else if (equalsNoCase(key, "Ns") || equalsNoCase(key, "Pr")) {
            if (current < 0 && !skipping) {
                OPENVDB_THROW(openvdb::ValueError, where << ": " << key << " before any newmtl");
            }
            double v;
            if (tokens.size() < 2 || !parseDouble(tokens[1], v) || !std::isfinite(v)) {
                OPENVDB_THROW(openvdb::ValueError, where << ": " << key << " needs a number");
            }
            const bool pbr = equalsNoCase(key, "Pr");
            if (pbr ? (v < 0.0 || v > 1.0) : v < 0.0) {
                OPENVDB_THROW(openvdb::ValueError, where << ": " << key << " value "
                    << formatNumber(v) << (pbr ? " outside [0, 1]" : " is negative"));
            }
            if (skipping) continue;
            Material& m = table.materials[current];
            // Pr (PBR roughness) wins over Ns whichever comes first.
            if (pbr) {
                m.roughness = float(std::clamp(v, Brdf::kMinRoughness, 1.0));
                table.pbrRoughness.insert(current);
            } else if (!table.pbrRoughness.count(current)) {
                m.roughness = float(Brdf::roughnessFromExponent(v));
            }
        }
        // Everything else (Ka, d, illum, maps, other PBR extensions) does not affect the
        // light vdbrad solves.
    }
}

// ---- OBJ ---------------------------------------------------------------------------------------

std::string
joinPath(const std::string& folder, const std::string& name)
{
    if (!name.empty() && name[0] == '/') return name;
    return folder + "/" + name;
}

bool
isFile(const std::string& path)
{
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string
parentFolder(const std::string& path)
{
    const size_t slash = path.rfind('/');
    if (slash == std::string::npos) return ".";
    return slash == 0 ? "/" : path.substr(0, slash);
}

/// Where a `mtllib` name points: as written, relative to the OBJ's folder; else its file name
/// alone in that folder (exporters keep the folder the MTL had on the author's machine); else
/// nowhere (empty). @a byName tells which.
std::string
findLibrary(const std::string& folder, std::string name, bool& byName)
{
    // Windows exporters write "mtllib .\materials\a.mtl".
    std::replace(name.begin(), name.end(), '\\', '/');
    byName = false;
    const std::string written = joinPath(folder, name);
    if (isFile(written)) return written;
    const size_t slash = name.rfind('/');
    if (slash == std::string::npos || slash + 1 == name.size()) return {};
    const std::string beside = folder + "/" + name.substr(slash + 1);
    byName = isFile(beside);
    return byName ? beside : std::string();
}

/// One OBJ read, statement by statement: the mesh so far, its materials and groups, and the
/// face indices checked at the end.
class ObjParser
{
public:
    ObjParser(const std::string& name, const std::string& folder): mName(name), mFolder(folder) {}

    /// `v x y z`
    void vertex(const std::vector<std::string_view>& tokens, size_t line);
    /// `f v1 v2 v3 ...`: a fan of triangles.
    void face(const std::vector<std::string_view>& tokens, size_t line);
    /// `mtllib file ...`: the material libraries, read at once.
    void mtllib(const std::string& text, const std::vector<std::string_view>& tokens,
        size_t line);
    /// `usemtl name`: the material of the faces that follow.
    void usemtl(const std::string& text, std::string_view key, size_t line);
    /// `o name` / `g name`: the group of the faces that follow.
    void group(const std::string& text, std::string_view key);
    /// The checks that need the whole file, then the mesh.
    TriangleMesh finish();

private:
    const std::string& mName;
    const std::string& mFolder;
    TriangleMesh mMesh;
    MaterialTable mTable;
    std::unordered_set<std::string> mLibraries;   // mtllib names already handled
    bool mHaveLibrary = false, mMissingLibrary = false;
    int32_t mCurrent = -1;
    // Groups (`o` / `g`): ids in order of each name's first face.
    std::unordered_map<std::string, int32_t> mGroupIds;
    std::string mGroupName = "default";
    int32_t mGroupId = -1;
    bool mHaveGroups = false;
    std::vector<PolygonFan> mFans;   // polygons of more than 3 vertices, checked at the end
    // A positive index may name a vertex defined further down (the spec does not forbid it and
    // some writers emit faces first), so those are checked at the end, in file order.
    std::vector<std::pair<size_t, long long>> mForward;
    std::vector<uint32_t> mPolygon;
};

void
ObjParser::vertex(const std::vector<std::string_view>& tokens, size_t line)
{
    Vec3f p;
    for (int i = 0; i < 3; ++i) {
        double v;
        if (size_t(i + 1) >= tokens.size() || tokens[i + 1][0] == '#') {
            OPENVDB_THROW(openvdb::ValueError, at(mName, line)
                << ": vertex needs 3 coordinates, got " << i);
        }
        if (!parseDouble(tokens[i + 1], v)) {
            OPENVDB_THROW(openvdb::ValueError, at(mName, line)
                << ": bad vertex coordinate " << quote(tokens[i + 1]));
        }
        if (!fitsFloat(v)) {
            OPENVDB_THROW(openvdb::ValueError, at(mName, line)
                << ": vertex coordinate " << formatNumber(v)
                << " is not a finite float");
        }
        p[i] = float(v);
    }
    if (mMesh.points.size() >= std::numeric_limits<uint32_t>::max()) {
        OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": more than 2^32-1 vertices");
    }
    mMesh.points.push_back(p);   // a fourth (w) value and vertex colours are ignored
}

void
ObjParser::face(const std::vector<std::string_view>& tokens, size_t line)
{
    std::vector<uint32_t>& polygon = mPolygon;
    polygon.clear();
    const long long count = static_cast<long long>(mMesh.points.size());
    for (size_t i = 1; i < tokens.size() && tokens[i][0] != '#'; ++i) {
        // v, v/vt, v//vn, v/vt/vn: only v matters.
        const std::string_view v = tokens[i].substr(0, tokens[i].find('/'));
        long long k;
        if (!parseInt(v, k)) {
            OPENVDB_THROW(openvdb::ValueError, at(mName, line)
                << ": bad face vertex " << quote(tokens[i]));
        }
        if (k == 0) {
            OPENVDB_THROW(openvdb::ValueError, at(mName, line)
                << ": face index 0 (OBJ indices start at 1)");
        }
        if (k < 0) {
            if (-k > count) {
                OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": face index " << k
                    << (count ? " out of range [-" + std::to_string(count) + ", -1]"
                              : std::string(" but no vertex is defined yet")));
            }
            k += count + 1;   // relative: -1 is the last vertex defined so far
        } else if (k > count) {
            if (k > static_cast<long long>(std::numeric_limits<uint32_t>::max())) {
                OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": face index " << k
                    << " out of range");
            }
            mForward.emplace_back(line, k);
        }
        polygon.push_back(uint32_t(k - 1));
    }
    if (polygon.size() < 3) {
        OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": face with "
            << polygon.size() << " vertices (at least 3 needed)");
    }
    // A fan now (vertices may still be to come); concave polygons are re-triangulated
    // at the end.
    if (polygon.size() > 3) {
        mFans.push_back({mMesh.triangles.size(), uint32_t(polygon.size() - 2)});
    }
    if (mGroupId < 0) {
        mGroupId = mGroupIds.emplace(mGroupName, int32_t(mMesh.groups.size())).first->second;
        if (size_t(mGroupId) == mMesh.groups.size()) mMesh.groups.push_back(mGroupName);
    }
    for (size_t i = 1; i + 1 < polygon.size(); ++i) {
        mMesh.triangles.emplace_back(polygon[0], polygon[i], polygon[i + 1]);
        mMesh.triangleMaterials.push_back(mCurrent);
        mMesh.triangleGroups.push_back(mGroupId);
    }
}

void
ObjParser::mtllib(const std::string& text, const std::vector<std::string_view>& tokens,
    size_t line)
{
    const std::string_view key = tokens[0];
    if (tokens.size() < 2) {
        OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": mtllib without a file");
    }
    if (mFolder.empty()) return;
    // Several names may follow; a single name with spaces in it is taken whole when such
    // a file exists (Blender writes the file name unquoted).
    const std::string whole(restOfLine(text, key));
    std::vector<std::string> names;
    bool byName = false;
    if (tokens.size() > 2 && !findLibrary(mFolder, whole, byName).empty()) {
        names.push_back(whole);
    } else {
        for (size_t i = 1; i < tokens.size(); ++i) names.emplace_back(tokens[i]);
    }
    for (const std::string& lib : names) {
        if (!mLibraries.insert(lib).second) continue;   // named again: nothing new
        const std::string found = findLibrary(mFolder, lib, byName);
        if (found.empty()) {
            // As Blender does: the scene still loads, its materials plain.
            mMesh.warnings.push_back(at(mName, line) + ": material library '" + lib
                + "' not found: its materials get albedo 0.5 and no emission");
            mMissingLibrary = true;
            continue;
        }
        if (byName) {
            mMesh.warnings.push_back(at(mName, line) + ": material library '" + lib
                + "' not found as written; using '" + found.substr(mFolder.size() + 1)
                + "' beside the OBJ");
        }
        readMtl(found, at(mName, line), mTable);
    }
    mHaveLibrary = true;
}

void
ObjParser::usemtl(const std::string& text, std::string_view key, size_t line)
{
    if (!mHaveLibrary) return;   // no library: the scene's default material
    const std::string material(restOfLine(text, key));
    const auto found = mTable.index.find(material);
    if (found != mTable.index.end()) {
        mCurrent = found->second;
    } else if (mMissingLibrary) {
        // Presumably defined in the library that is missing: a plain material of its
        // own, so its faces are still told apart (material names, albedo grid).
        mCurrent = int32_t(mTable.materials.size());
        mTable.index.emplace(material, mCurrent);
        Material m;
        m.name = material;
        mTable.materials.push_back(m);
    } else {
        OPENVDB_THROW(openvdb::ValueError, at(mName, line) << ": unknown material "
            << quote(material) << " (not in the mtllib files)");
    }
}

void
ObjParser::group(const std::string& text, std::string_view key)
{
    // The last `o` or `g` names the faces that follow; a bare `g` is the default group.
    const std::string_view group = restOfLine(text, key);
    mGroupName = group.empty() ? "default" : std::string(group);
    mHaveGroups = true;
    mGroupId = -1;   // found or made at the next face
}

TriangleMesh
ObjParser::finish()
{
    for (const auto& [faceLine, k] : mForward) {
        if (k > static_cast<long long>(mMesh.points.size())) {
            OPENVDB_THROW(openvdb::ValueError, at(mName, faceLine) << ": face index " << k
                << " out of range [1, " << mMesh.points.size() << "]");
        }
    }
    if (mMesh.triangles.empty()) OPENVDB_THROW(openvdb::ValueError, mName << ": no triangles");
    triangulatePolygons(mMesh.points, mMesh.triangles, mFans);
    mMesh.materials = std::move(mTable.materials);
    if (mMesh.materials.empty()) mMesh.triangleMaterials.clear();
    if (!mHaveGroups) {
        mMesh.triangleGroups.clear();
        mMesh.groups.clear();
    }
    return std::move(mMesh);
}

} // namespace


TriangleMesh
readObj(std::istream& in, const std::string& name, const std::string& folder)
{
    ObjParser parser(name, folder);
    LineReader lines(in, name);
    std::string text;
    size_t line = 0;
    std::vector<std::string_view> tokens;
    while (lines.next(text, line)) {
        split(text, tokens);
        if (tokens.empty() || tokens[0][0] == '#') continue;
        const std::string_view key = tokens[0];
        if (key == "v") {
            parser.vertex(tokens, line);
        } else if (key == "f") {
            parser.face(tokens, line);
        } else if (key == "mtllib") {
            parser.mtllib(text, tokens, line);
        } else if (key == "usemtl") {
            parser.usemtl(text, key, line);
        } else if (key == "o" || key == "g") {
            parser.group(text, key);
        }
        // vt, vn, vp, s, l, p, and the many statements exporters add: nothing to voxelize.
    }
    return parser.finish();
}


TriangleMesh
readObj(const std::string& path)
{
    std::ifstream in;
    openFile(in, path, path);
    return readObj(in, path, parentFolder(path));
}

} // namespace vdbrad
