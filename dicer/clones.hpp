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
#if defined(__SANITIZE_THREAD__)
#define DICER_CLONES
#define DICER_WIDE_CLONES
#elif defined(__clang__)  // the fuzz build: Clang 14 clones no arch= levels
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#define DICER_WIDE_CLONES DICER_CLONES
#else
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#define DICER_WIDE_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#endif
