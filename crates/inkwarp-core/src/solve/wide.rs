//! The solver's hottest loops on the processor's widest vectors.
//!
//! The build targets plain x86-64, whose vectors are 128 bits wide; nearly every x86-64
//! processor since about 2015 has 256-bit ones (AVX2, with FMA). The stencil products of
//! every level and the conjugate gradient's update vectorise across nodes, so each has a
//! second copy compiled for AVX2, run where the processor has it (checked at run time),
//! else the plain one. Their operations and their
//! order are the same in both (no multiply is fused with its add unless written so), so
//! the results are bit for bit the same.

/// Whether the processor has AVX2 and FMA (the standard library caches the answer).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn avx2() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
}
