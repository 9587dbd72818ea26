#pragma once
// Private to dicer/: function multi-versioning for the kernels (plain loops
// over contiguous arrays). Each marked function is built for AVX2 (and,
// DICER_WIDE_CLONES, AVX-512 where it pays: 64-bit integer multiplies, and
// rows of a small element, which 8 lanes cover in one vector) beside
// baseline x86-64, chosen at load time. Floating-point kernels stay
// bit-identical across clones: plain IEEE mul/add/sub in source order with
// contraction off.
// Not under ThreadSanitizer: GCC 12's ifunc resolver for target_clones runs
// before the TSan runtime is up and crashes the binary at start-up.
// DICER_CLONES_AVX2_AT_MOST / DICER_CLONES_NONE (CMake DICER_KERNEL_CLONES):
// no AVX-512 clone / no clone at all, so that an AVX-512 machine runs
// (and tests) the code other machines run. The AVX2 clones differ from
// the AVX-512 ones in more than width: GCC 12.2 once miscompiled one of
// them (sweep.cpp, hash_lines) while the AVX-512 clone was right.
#ifndef DICER_CLONES_CHOSEN
#error "dicer/clones.hpp: add this source to the kernel sources in CMakeLists.txt (set_source_files_properties beside DICER_KERNEL_CLONES), or the choice of clones never reaches it"
#endif
#if defined(__SANITIZE_THREAD__) || defined(DICER_CLONES_NONE)
#define DICER_CLONES
#define DICER_WIDE_CLONES
#elif defined(DICER_CLONES_AVX2_AT_MOST)
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#define DICER_WIDE_CLONES DICER_CLONES
#elif defined(__clang__)  // the fuzz build: Clang 14 clones no arch= levels
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#define DICER_WIDE_CLONES DICER_CLONES
#else
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#define DICER_WIDE_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#endif
