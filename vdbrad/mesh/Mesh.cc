// Mesh: readMesh, which picks the reader for a file's format (ObjReader.cc, PlyReader.cc).
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/MeshParsing.h"

#include <openvdb/Exceptions.h>

#include <cctype>
#include <cstring>
#include <fstream>

namespace vdbrad {

TriangleMesh
readMesh(const std::string& path)
{
    std::ifstream in;
    parsing::openFile(in, path, path);
    char magic[4] = {};
    in.read(magic, 4);
    if (in.gcount() == 4 && std::memcmp(magic, "ply", 3) == 0 &&
        (magic[3] == '\n' || magic[3] == '\r')) {
        in.close();
        return readPly(path);
    }
    in.close();
    const size_t dot = path.rfind('.');
    const size_t slash = path.rfind('/');
    std::string ext;
    if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) {
        ext = path.substr(dot + 1);
        for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    }
    if (ext == "obj") return readObj(path);
    if (ext == "ply") return readPly(path);
    OPENVDB_THROW(openvdb::ValueError, path
        << ": unknown mesh format (supported: Wavefront .obj, .ply)");
}

} // namespace vdbrad
