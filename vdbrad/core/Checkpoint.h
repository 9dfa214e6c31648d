// Checkpoint: a solver's resumable state, as named arrays, and its file format.
//
// A long solve on a render farm may be killed (pre-emption, a time limit). With
// `--checkpoint FILE --checkpoint-every K` the tool saves, every K iterations, everything the
// next iteration reads: the iterate, the sums an in-place update keeps, the closed-room weights
// measured by the first sweep, the Anderson history, the residuals. `--resume FILE` restores
// it into a solver set up from the same input and options, and the remaining iterations then
// compute exactly what an uninterrupted run would: the output bits are identical (tested).
//
// File layout (little-endian): "VDBRADCK", format version (u32), fingerprint (u64: the input
// scene and the options that change the iterates, so that a checkpoint cannot be resumed
// against another problem), section count (u32), then per section: name length (u32), name,
// element type (u8), element count (u64), the elements; last, an FNV-1a hash (u64) of all the
// bytes before it, so that a truncated or corrupted checkpoint is refused rather than resumed.
// Files are written atomically (GridIO's writeFileAtomic): a kill while saving leaves the
// previous checkpoint intact.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace vdbrad {

/// FNV-1a hash of @a size bytes, continuing from @a seed (chain calls to hash several arrays).
uint64_t hashBytes(const void* data, size_t size, uint64_t seed = 14695981039346656037ULL);

class SolverState
{
public:
    /// Store an array under @a name (replacing any), one of float, double, int64_t, uint8_t.
    template<typename T> void put(const std::string& name, const T* data, size_t count);
    template<typename T> void put(const std::string& name, const std::vector<T>& v)
    {
        put(name, v.data(), v.size());
    }

    /// @brief The array stored under @a name.
    /// @throw openvdb::ValueError if it is missing, of another type, or (when @a expected is
    ///        not npos) not exactly @a expected elements long
    template<typename T>
    std::vector<T> get(const std::string& name, size_t expected = npos) const;
    bool has(const std::string& name) const { return mSections.count(name) != 0; }

    /// The checkpoint file's bytes, stamped with @a fingerprint.
    std::string serialize(uint64_t fingerprint) const;

    /// @brief Parse a checkpoint file's bytes.
    /// @throw openvdb::IoError    not a checkpoint, another format version, truncated, corrupt
    /// @throw openvdb::ValueError its fingerprint is not @a fingerprint (another scene or other
    ///        options)
    static SolverState parse(const std::string& bytes, uint64_t fingerprint);

    static constexpr size_t npos = size_t(-1);

private:
    struct Section
    {
        uint8_t type = 0;
        uint64_t count = 0;
        std::string bytes;
    };
    std::map<std::string, Section> mSections;
};

} // namespace vdbrad
