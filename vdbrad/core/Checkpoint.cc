#include "vdbrad/core/Checkpoint.h"

#include <openvdb/Exceptions.h>

#include <cstring>
#include <type_traits>

namespace vdbrad {

namespace {

constexpr char kCheckpointMagic[8] = {'V', 'D', 'B', 'R', 'A', 'D', 'C', 'K'};
constexpr uint32_t kVersion = 1;

template<typename T> constexpr uint8_t typeTag();
template<> constexpr uint8_t typeTag<float>() { return 1; }
template<> constexpr uint8_t typeTag<double>() { return 2; }
template<> constexpr uint8_t typeTag<int64_t>() { return 3; }
template<> constexpr uint8_t typeTag<uint8_t>() { return 4; }

size_t
tagSize(uint8_t tag)
{
    switch (tag) {
        case 1: return 4;
        case 2: return 8;
        case 3: return 8;
        case 4: return 1;
        default: return 0;
    }
}

bool
littleEndian()
{
    const uint32_t one = 1;
    uint8_t first;
    std::memcpy(&first, &one, 1);
    return first == 1;
}

template<typename T>
void
append(std::string& out, T v)
{
    static_assert(std::is_trivially_copyable<T>::value, "raw bytes");
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

// Reads fixed-size values off the bytes, refusing to run past their end.
struct Cursor
{
    const std::string& bytes;
    size_t at = 0;

    void need(size_t n) const
    {
        if (n > bytes.size() - at) OPENVDB_THROW(openvdb::IoError, "truncated checkpoint");
    }
    template<typename T> T read()
    {
        need(sizeof(T));
        T v;
        std::memcpy(&v, bytes.data() + at, sizeof v);
        at += sizeof v;
        return v;
    }
    std::string take(size_t n)
    {
        need(n);
        std::string s = bytes.substr(at, n);
        at += n;
        return s;
    }
};

} // namespace

uint64_t
hashBytes(const void* data, size_t size, uint64_t seed)
{
    const unsigned char* p = static_cast<const unsigned char*>(data);
    uint64_t h = seed;
    for (size_t i = 0; i < size; ++i) {
        h ^= p[i];
        h *= 1099511628211ULL;
    }
    return h;
}

template<typename T>
void
SolverState::put(const std::string& name, const T* data, size_t count)
{
    Section s;
    s.type = typeTag<T>();
    s.count = count;
    s.bytes.assign(reinterpret_cast<const char*>(data), count * sizeof(T));
    mSections[name] = std::move(s);
}

template<typename T>
std::vector<T>
SolverState::get(const std::string& name, size_t expected) const
{
    const auto it = mSections.find(name);
    if (it == mSections.end()) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoint has no '" << name << "'");
    }
    const Section& s = it->second;
    if (s.type != typeTag<T>()) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoint's '" << name << "' has another type");
    }
    if (expected != npos && s.count != expected) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoint's '" << name << "' has " << s.count
            << " values, expected " << expected);
    }
    std::vector<T> v(size_t(s.count));
    if (!v.empty()) std::memcpy(v.data(), s.bytes.data(), s.bytes.size());
    return v;
}

#define VDBRAD_STATE_TYPE(T) \
    template void SolverState::put<T>(const std::string&, const T*, size_t); \
    template std::vector<T> SolverState::get<T>(const std::string&, size_t) const;
VDBRAD_STATE_TYPE(float)
VDBRAD_STATE_TYPE(double)
VDBRAD_STATE_TYPE(int64_t)
VDBRAD_STATE_TYPE(uint8_t)
#undef VDBRAD_STATE_TYPE

std::string
SolverState::serialize(uint64_t fingerprint) const
{
    if (!littleEndian()) {
        OPENVDB_THROW(openvdb::NotImplementedError, "checkpoints need a little-endian machine");
    }
    std::string out(kCheckpointMagic, sizeof kCheckpointMagic);
    append(out, kVersion);
    append(out, fingerprint);
    append(out, uint32_t(mSections.size()));
    for (const auto& [name, s] : mSections) {
        append(out, uint32_t(name.size()));
        out += name;
        append(out, s.type);
        append(out, s.count);
        out += s.bytes;
    }
    append(out, hashBytes(out.data(), out.size()));
    return out;
}

SolverState
SolverState::parse(const std::string& bytes, uint64_t fingerprint)
{
    if (!littleEndian()) {
        OPENVDB_THROW(openvdb::NotImplementedError, "checkpoints need a little-endian machine");
    }
    if (bytes.size() < sizeof kCheckpointMagic || std::memcmp(bytes.data(), kCheckpointMagic, sizeof kCheckpointMagic) != 0) {
        OPENVDB_THROW(openvdb::IoError, "not a vdbrad checkpoint");
    }
    if (bytes.size() < sizeof kCheckpointMagic + 4 + 8 + 4 + 8) {
        OPENVDB_THROW(openvdb::IoError, "truncated checkpoint");
    }
    uint64_t stored;
    std::memcpy(&stored, bytes.data() + bytes.size() - 8, 8);
    if (stored != hashBytes(bytes.data(), bytes.size() - 8)) {
        OPENVDB_THROW(openvdb::IoError, "corrupt or truncated checkpoint (checksum mismatch)");
    }
    const std::string body = bytes.substr(0, bytes.size() - 8);
    Cursor c{body, sizeof kCheckpointMagic};
    const uint32_t version = c.read<uint32_t>();
    if (version != kVersion) {
        OPENVDB_THROW(openvdb::IoError, "checkpoint format " << version << ", this vdbrad reads "
            << kVersion);
    }
    if (c.read<uint64_t>() != fingerprint) {
        OPENVDB_THROW(openvdb::ValueError, "the checkpoint belongs to another input or other "
            "solver options");
    }
    SolverState state;
    const uint32_t sections = c.read<uint32_t>();
    for (uint32_t k = 0; k < sections; ++k) {
        const uint32_t length = c.read<uint32_t>();
        const std::string name = c.take(length);
        Section s;
        s.type = c.read<uint8_t>();
        s.count = c.read<uint64_t>();
        const size_t size = tagSize(s.type);
        if (size == 0) OPENVDB_THROW(openvdb::IoError, "corrupt checkpoint (unknown type)");
        if (s.count > (body.size() - c.at) / size) {
            OPENVDB_THROW(openvdb::IoError, "truncated checkpoint");
        }
        s.bytes = c.take(size_t(s.count) * size);
        state.mSections[name] = std::move(s);
    }
    if (c.at != body.size()) OPENVDB_THROW(openvdb::IoError, "corrupt checkpoint (trailing bytes)");
    return state;
}

} // namespace vdbrad
