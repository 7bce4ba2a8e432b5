//! The solver's hottest loops on the processor's widest vectors. The build targets plain x86-64; [`widest!`]
//! gives each stencil product, transfer, smoothing update, dot product and scaled maximum a second copy
//! compiled for AVX2 with FMA, run where the processor has it. Both copies do the same operations in the
//! same order: bit for bit the same results. One loop is written out with AVX2 instructions
//! (`Real::four_run` in `level`); a test holds it to the plain sums. See `docs/dev/ablation.md`, "Kernels".

/// Whether the processor has AVX2 and FMA (the standard library caches the answer).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn avx2() -> bool { std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") }

/// `[vis] fn name<T: Bound>(args) -> R => body { … }` defines `body`, an `#[inline(always)]` function of those
/// arguments with that block (attributes written before `body` go on it), and `name`, which calls `body`
/// from a copy compiled for AVX2 and FMA where the processor has them, else from a plain one. The body must
/// be inlined into that copy to be compiled for it (a closure handed to a generic copy was not).
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
