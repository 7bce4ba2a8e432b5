//! The solver's hottest loops on the processor's widest vectors.
//!
//! The build targets plain x86-64, whose vectors are 128 bits wide; most x86-64
//! processors made since 2013–2015 (Intel Haswell, AMD Excavator and later, some low-end
//! models excepted) have 256-bit ones (AVX2, with FMA). The stencil products of every level,
//! the transfers' plain rows, the smoothing steps' updates, and the dot products and scaled
//! maxima of the levels vectorise across nodes, so [`widest!`] gives each a
//! second copy compiled for AVX2, run where the processor has it (checked at run time),
//! else the plain one. Their operations and their order are the same in both (no multiply
//! is fused with its add unless written so), so the results are bit for bit the same.
//! One loop the compiler did not vectorise is written out with AVX2 instructions instead:
//! four coarse nodes with stencils of their own on one vector (`Real::four_run` in
//! `level`, their coefficients laid out tap by tap in `level::Fours`). Both copies call it
//! where the processor has AVX2, so a test holds it to the plain sums node by node rather
//! than to the plain copy.
//!
//! Check the copy's code after writing a body: the compiler may build a closure the body
//! calls (or one it hands to `Option::map_or`) apart, as a plain function outside the copy;
//! a branch in a body's loop, or a loop over pairs that writes each pair whole, can keep
//! it scalar (`docs/dev/ablation.md`, "Kernels").

/// Whether the processor has AVX2 and FMA (the standard library caches the answer).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn avx2() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
}

/// `[vis] fn name<T: Bound>(args) -> R => body { … }` defines `body`, an `#[inline(always)]`
/// function of those arguments with that block (attributes written before `body` go on
/// it), and `name`, which calls `body` from a copy compiled for AVX2 and FMA where the
/// processor has them (see [`avx2`]), else from a plain one. The body must be inlined into
/// that copy to be compiled for it: a closure handed to a generic copy was not (its binary
/// had no 256-bit instruction). Tests call `body` to compare the two copies.
macro_rules! widest {
    (
        $(#[$attr:meta])* $vis:vis fn $name:ident $(<$($t:ident: $bound:path),+>)? ($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? =>
        $(#[$body_attr:meta])* $body:ident $block:block
    ) => {
        $(#[$attr])*
        $vis fn $name $(<$($t: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if $crate::solve::wide::avx2() {
                #[target_feature(enable = "avx2,fma")]
                #[allow(unsafe_code)]
                unsafe fn avx2 $(<$($t: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                // SAFETY: the processor has AVX2 and FMA, checked just above.
                #[allow(unsafe_code)]
                return unsafe { avx2($($arg),*) };
            }
            $body($($arg),*)
        }

        $(#[$body_attr])*
        #[inline(always)]
        fn $body $(<$($t: $bound),+>)? ($($arg: $ty),*) $(-> $ret)? $block
    };
}
pub(crate) use widest;
