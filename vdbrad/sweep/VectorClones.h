// VectorClones: compile a hot loop several times, for AVX-512, AVX2 and plain x86-64, and let
// the loader pick the best the CPU has (GCC's function multiversioning). The library stays one
// portable binary while its few vectorisable sweep kernels use the wide units where they exist.
// Only on integer kernels or ones whose float operations a vector lane performs in the same order;
// the library builds with -ffp-contract=off (CMakeLists.txt), so the AVX-512 clone, which could
// fuse a product and a sum, does not, and every clone gives the bits of the plain one.
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define VDBRAD_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VDBRAD_VECTOR_CLONES
#endif
