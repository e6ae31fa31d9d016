// LINNET_SIMD_CLONES: builds a function twice on x86-64 with GCC, for the baseline and for AVX2, and lets the loader
// pick one for the CPU (GCC's target_clones, an ifunc). For image row kernels that the compiler vectorises: AVX2 holds
// twice the lanes of the baseline's SSE2. Meant for integer kernels and for float code without reassociation (AVX2
// implies no FMA contraction), so both clones give the same results.
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__gnu_linux__)
#define LINNET_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LINNET_SIMD_CLONES
#endif
