// Seeds: each fuzz target writes its own seed corpus, so no binary inputs are committed.
//
// scripts/fuzz.sh sets VDBRAD_FUZZ_SEEDS to the target's corpus folder. A target calls writeSeeds
// from LLVMFuzzerInitialize, which libFuzzer runs before it reads the corpus; without the variable
// (reproducing a crash by hand) it writes nothing.
#pragma once

#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace vdbrad {
namespace fuzz {

inline void
writeSeeds(const std::vector<std::string>& seeds)
{
    const char* dir = std::getenv("VDBRAD_FUZZ_SEEDS");
    if (!dir || !*dir) return;
    for (size_t i = 0; i < seeds.size(); ++i) {
        std::ofstream(std::string(dir) + "/seed-" + std::to_string(i), std::ios::binary)
            << seeds[i];
    }
}

} // namespace fuzz
} // namespace vdbrad
