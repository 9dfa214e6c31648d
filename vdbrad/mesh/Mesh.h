// Mesh: triangle meshes read from OBJ (with MTL materials) and PLY files, the voxelizer's input.
//
// Only what the voxelizer needs is kept: positions, triangles (convex polygons fan-triangulated,
// others ear-clipped: MeshParsing.h), per triangle the material it was drawn with and the OBJ
// object or group it belongs to, and what the reader had to work around (warnings). Texture
// coordinates and vertex normals are ignored: the voxelizer takes each triangle's orientation
// from its winding (counter-clockwise seen from outside, as OBJ and PLY exporters write it). The
// readers: ObjReader.cc, PlyReader.cc.
#pragma once

#include <openvdb/Types.h>

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace vdbrad {

/// A surface material: the MTL fields a diffuse radiosity scene uses.
struct Material
{
    std::string name;
    /// Diffuse reflectance (MTL `Kd`), each channel in [0, 1]. A material without `Kd` gets
    /// 0.5, vdbrad's default --albedo, rather than MTL's 0.8: an uncoloured material then looks
    /// like the rest of an uncoloured scene.
    openvdb::Vec3f albedo{0.5f};
    /// Emitted radiosity (MTL `Ke`), each channel >= 0.
    openvdb::Vec3f emission{0.f};
    /// Reflectance of a glossy lobe (MTL `Ks`), each channel in [0, 1]. Where albedo + specular
    /// exceeds 1 in a channel (MTL files often have it) the voxelizer scales both by
    /// 1 / reflectance(): a surface reflects no more light than it receives.
    openvdb::Vec3f specular{0.f};
    /// The lobe's roughness (Brdf.h): MTL's PBR `Pr` if given, else from the Phong exponent `Ns`
    /// (Brdf::roughnessFromExponent); 0.5 when neither is given.
    float roughness = 0.5f;
    /// The largest albedo + specular over the channels.
    float reflectance() const;
};

struct TriangleMesh
{
    std::vector<openvdb::Vec3f> points;
    /// Vertex indices into points, counter-clockwise seen from the side the normal points to.
    std::vector<openvdb::Vec3I> triangles;
    /// Per triangle: index into materials, or -1 for "no material" (the scene's default albedo,
    /// no emission). Empty when the file has no materials at all.
    std::vector<int32_t> triangleMaterials;
    std::vector<Material> materials;
    /// Per triangle: index into groups, the OBJ object or group (`o` / `g`) it was drawn in.
    /// Empty when the file names none (PLY files never do).
    std::vector<int32_t> triangleGroups;
    /// Object and group names, in order of their first face.
    std::vector<std::string> groups;
    /// What the reader worked around, one line each, "file:line: what" (a material library
    /// found only by its file name, or not at all): for the caller to show, as the tool does.
    std::vector<std::string> warnings;

    bool hasMaterials() const { return !materials.empty(); }
    bool hasGroups() const { return !groups.empty(); }
    /// True if some material has a glossy lobe (specular > 0).
    bool hasSpecular() const;
};

/// @brief Read a Wavefront OBJ file; `mtllib` files are looked up beside it.
/// @details Uses `v` (a w or colour after x y z is ignored) and `f` (v, v/vt, v//vn, v/vt/vn;
/// negative indices count back from the last vertex so far; polygons triangulated, degenerate
/// triangles kept), `mtllib` (one or more names), `usemtl`, `o` and `g`; ignores everything
/// else. CRLF, tabs, comments and trailing-backslash continuations are fine.
///
/// A `mtllib` name is resolved as written, relative to the OBJ's folder (Windows backslashes
/// read as slashes); failing that, by its file name alone in the OBJ's folder (exporters write
/// the folder the MTL was in on the author's machine), with a warning. A library found neither
/// way is a warning, not an error, as in Blender: its `usemtl` names become materials with the
/// default albedo (0.5) that emit nothing.
///
/// In MTL files only `newmtl`, `Kd`, `Ke`, `Ks` (one value: grey, or three), `Ns` and `Pr`
/// matter; a name defined twice keeps its first definition; `Ke` may exceed 1 (it is radiosity).
/// Triangles before any `usemtl`, or in a file without `mtllib`, get material -1.
///
/// `o NAME` and `g NAME` (the rest of the line) both start a group, the last one seen naming
/// the faces that follow (faces before either: "default", the OBJ spec's default group); group
/// ids count from 0 in order of each name's first face. A file with neither leaves
/// triangleGroups empty.
/// @throw openvdb::IoError  unreadable file or unreadable (existing) MTL file
/// @throw openvdb::ValueError malformed content, naming the file and line (e.g. "cube.obj:12:
///        face index 9 out of range [1, 8]"), non-finite coordinates, Kd outside [0, 1], Ke < 0,
///        a `usemtl` name no library found defines (when every library was found), no triangles
TriangleMesh readObj(const std::string& path);

/// @brief Parse OBJ text from @a in. @a name labels errors; `mtllib` names are resolved against
/// @a folder (empty: materials are not loaded and `usemtl` is ignored).
TriangleMesh readObj(std::istream& in, const std::string& name, const std::string& folder);

/// @brief Read a PLY file: ascii, binary_little_endian or binary_big_endian; `vertex` elements
/// with x, y, z (any numeric type), `face` elements with a vertex_indices (or vertex_index)
/// list (polygons triangulated as in OBJ files); other elements and properties are skipped. Optional
/// per-vertex or per-face red/green/blue (uchar 0..255, ushort 0..65535 or float 0..1) become
/// materials named like "rgb(255,0,0)" (0..255 scale), one per distinct colour, used as albedo
/// with no emission: a triangle takes its face's colour, else the mean of its vertices'.
/// @throw openvdb::IoError  unreadable file, or data ending before the header's counts
///        ("x.ply: truncated: expected 8 vertices, file ends after 5")
/// @throw openvdb::ValueError malformed header or text (naming the line), index out of range,
///        non-finite coordinates, a face with fewer than 3 vertices, a count larger than the
///        file could hold (refused before any memory is reserved from it), no triangles
TriangleMesh readPly(const std::string& path);
TriangleMesh readPly(std::istream& in, const std::string& name);

/// @brief Read @a path as OBJ or PLY, chosen by its first bytes ("ply\n") or else its extension
/// (.obj, .ply, any case).
/// @throw as readObj / readPly; openvdb::ValueError for any other format
TriangleMesh readMesh(const std::string& path);

} // namespace vdbrad
