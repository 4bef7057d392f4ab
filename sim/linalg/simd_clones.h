#pragma once
// INCISE_SIMD_CLONES on a function: an AVX2+FMA clone next to the baseline one, picked at load
// time by the CPU (GCC on x86-64 Linux); elsewhere nothing. For loops over struct-of-arrays
// lanes that the compiler vectorizes (the K x kernel, rotation extraction).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__gnu_linux__)
#define INCISE_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define INCISE_SIMD_CLONES
#endif
