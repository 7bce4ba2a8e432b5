//! Wall-clock timing for reports. `std::time::Instant::now` panics on
//! `wasm32-unknown-unknown` (there is no clock there), so the browser build gets an
//! `Instant` whose elapsed time is always zero: its reports say 0 s.

#[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
pub(crate) use std::time::Instant;

#[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
#[derive(Clone, Copy)]
pub(crate) struct Instant;

#[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
impl Instant {
    pub(crate) fn now() -> Self { Instant }

    pub(crate) fn elapsed(&self) -> std::time::Duration { std::time::Duration::ZERO }
}
