#include "vdbrad/core/GridIO.h"

#include "vdbrad/core/CrashGuard.h"

#include <openvdb/io/Stream.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <istream>
#include <iterator>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

namespace vdbrad {

namespace {

// An istream over bytes we already hold, without copying them into a stringstream.
// OpenVDB 10 does not check every read: past the end of a truncated file it would use
// uninitialised sizes (a "string" of gigabytes). So past the end this buffer serves a block of
// zeros (sizes read as 0, failing fast) and remembers the overrun, which marks the file truncated.
class MemoryBuffer : public std::streambuf
{
public:
    explicit MemoryBuffer(const std::string& bytes)
        : mBegin(const_cast<char*>(bytes.data()))
        , mEnd(mBegin + bytes.size())
    {
        setg(mBegin, mBegin, mEnd);
    }
    bool overran() const { return mOverran; }

protected:
    int_type underflow() override
    {
        if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
        if (mOverran) return traits_type::eof();   // the zero block is spent too
        mOverran = true;
        setg(mZeros, mZeros, mZeros + sizeof(mZeros));
        return traits_type::to_int_type(*gptr());
    }
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        if (mOverran) return pos_type(off_type(-1));
        char* target = dir == std::ios_base::beg ? mBegin + off
            : dir == std::ios_base::cur ? gptr() + off : mEnd + off;
        if (target < mBegin || target > mEnd) return pos_type(off_type(-1));
        setg(mBegin, target, mEnd);
        return pos_type(target - mBegin);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode mode) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, mode);
    }

private:
    char* mBegin;
    char* mEnd;
    bool mOverran = false;
    char mZeros[4096] = {};
};

// "VDB " as the little-endian int64 OpenVDB writes first (io/Archive.cc: OPENVDB_MAGIC).
constexpr unsigned char kVdbMagic[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0};

std::string
systemError(const std::string& what, const std::string& path)
{
    return what + " '" + path + "': " + std::strerror(errno);
}

// OpenVDB's parse errors can quote garbage read from a corrupt file (a "name" megabytes long):
// keep one short printable line.
std::string
shortReason(const std::exception& e)
{
    std::string out;
    for (const char* p = e.what(); p && *p && out.size() < 160; ++p) {
        const char c = (*p >= 32 && *p < 127) ? *p : ' ';
        if (c == ' ' && (out.empty() || out.back() == ' ')) continue;
        out += c;
    }
    if (!out.empty() && out.back() == ' ') out.pop_back();
    return out;
}

// OpenVDB's parse of bytes already known to start with the magic number.
VdbFile
parseUnguarded(const std::string& bytes)
{
    openvdb::initialize();
    MemoryBuffer buffer(bytes);
    std::istream in(&buffer);
    VdbFile file;
    try {
        openvdb::io::Stream stream(in, /*delayLoad=*/false);
        file.metadata = stream.getMetadata();
        file.grids = *stream.getGrids();
        if (buffer.overran() || in.fail()) {
            OPENVDB_THROW(openvdb::IoError, "unexpected end of data");
        }
    } catch (const std::exception& e) {
        if (buffer.overran()) OPENVDB_THROW(openvdb::IoError, "truncated VDB file");
        // Corrupt sizes also make OpenVDB allocate absurd amounts (std::bad_alloc, length_error).
        OPENVDB_THROW(openvdb::IoError, "corrupt or truncated VDB file (" << shortReason(e) << ")");
    }
    if (file.grids.empty()) {
        OPENVDB_THROW(openvdb::IoError, "no grids in the file (truncated?)");
    }
    if (!file.metadata) file.metadata = std::make_shared<openvdb::MetaMap>();
    return file;
}

// Touches every leaf buffer (its first and last value), one thread: a leaf the reader left
// without a buffer or with a wild one fails here rather than in the parent.
struct TouchLeaves
{
    template<typename GridT>
    void operator()(const GridT& grid) const
    {
        using LeafT = typename GridT::TreeType::LeafNodeType;
        for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) {
            const typename GridT::ValueType first = leaf->getValue(0);
            const typename GridT::ValueType last = leaf->getValue(LeafT::SIZE - 1);
            sink = sink + (first == last);
        }
    }
    static volatile unsigned sink;
};
volatile unsigned TouchLeaves::sink = 0;

} // namespace

VdbFile
parseVdb(const std::string& bytes)
{
    if (bytes.empty()) OPENVDB_THROW(openvdb::IoError, "empty file");
    if (bytes.size() < sizeof(kVdbMagic) || std::memcmp(bytes.data(), kVdbMagic, sizeof(kVdbMagic)) != 0) {
        OPENVDB_THROW(openvdb::IoError, "not a VDB file (bad magic number)");
    }
    // OpenVDB 10 reads a file from a newer version as its own, with a warning, and garbage
    // results; older than the root-node map, it allocates gigabytes before failing.
    uint32_t version = 0;
    if (bytes.size() >= sizeof(kVdbMagic) + sizeof(version)) {
        std::memcpy(&version, bytes.data() + sizeof(kVdbMagic), sizeof(version));
    }
    if (version < openvdb::OPENVDB_FILE_VERSION_ROOTNODE_MAP
        || version > openvdb::OPENVDB_FILE_VERSION) {
        OPENVDB_THROW(openvdb::IoError, "unsupported VDB file format version " << version
            << " (OpenVDB " << openvdb::getLibraryVersionString() << " reads versions "
            << openvdb::OPENVDB_FILE_VERSION_ROOTNODE_MAP << " to " << openvdb::OPENVDB_FILE_VERSION
            << ")");
    }
    openvdb::initialize();   // before the fork: the child then inherits the registries
    runGuarded([&] {
        VdbFile file = parseUnguarded(bytes);
        for (const auto& g : file.grids) g->apply<openvdb::GridTypes>(TouchLeaves());
        // Freeing everything lets glibc catch heap corruption here, not in the parent.
        file.grids.clear();
    }, bytes.size());
    return parseUnguarded(bytes);
}

VdbFile
readVdbFile(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) OPENVDB_THROW(openvdb::IoError, systemError("cannot open", path));
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
        OPENVDB_THROW(openvdb::IoError, "'" << path << "' is a directory");
    }
    return readVdbStream(in);
}

VdbFile
readVdbStream(std::istream& in)
{
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) OPENVDB_THROW(openvdb::IoError, "read error");
    return parseVdb(bytes);
}

std::string
serializeVdb(const VdbFile& file)
{
    openvdb::initialize();
    std::ostringstream os(std::ios::binary);
    openvdb::io::Stream stream(os);
    stream.write(file.grids, file.metadata ? *file.metadata : openvdb::MetaMap());
    if (!os) OPENVDB_THROW(openvdb::IoError, "failed to serialise the VDB file");
    return std::move(os).str();
}

void
writeFileAtomic(const std::string& path, const std::string& bytes)
{
    std::string dir = ".";
    const size_t slash = path.find_last_of('/');
    if (slash != std::string::npos) dir = slash == 0 ? "/" : path.substr(0, slash);
    const std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
    std::string tmpl = dir + "/." + base + ".vdbrad-XXXXXX";
    std::vector<char> name(tmpl.begin(), tmpl.end());
    name.push_back('\0');
    const int fd = ::mkstemp(name.data());
    if (fd < 0) OPENVDB_THROW(openvdb::IoError, systemError("cannot create a file in", dir));
    const std::string tmp(name.data());
    auto fail = [&](const std::string& what) {
        const std::string msg = systemError(what, path);
        ::close(fd);
        ::unlink(tmp.c_str());
        OPENVDB_THROW(openvdb::IoError, msg);
    };
    size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0) {
            if (errno == EINTR) continue;
            fail("cannot write");
        }
        done += size_t(n);
    }
    // mkstemp creates 0600; give the file the permissions a plain create would have.
    const mode_t mask = ::umask(0);
    ::umask(mask);
    ::fchmod(fd, 0666 & ~mask);
    if (::fsync(fd) != 0) fail("cannot flush");
    if (::close(fd) != 0) {
        const std::string msg = systemError("cannot close", path);
        ::unlink(tmp.c_str());
        OPENVDB_THROW(openvdb::IoError, msg);
    }
    if (::rename(tmp.c_str(), path.c_str()) != 0) {
        const std::string msg = systemError("cannot rename the output to", path);
        ::unlink(tmp.c_str());
        OPENVDB_THROW(openvdb::IoError, msg);
    }
}

void
writeVdbFile(const VdbFile& file, const std::string& path)
{
    writeFileAtomic(path, serializeVdb(file));
}

} // namespace vdbrad
