//! A request to stop long work early (Ctrl-C, SIGTERM, a closed editor tab).
//!
//! Front ends call [`request`] from wherever they notice the signal (the Python adapter
//! polls for signals while the engine runs on another thread); long loops in the engine
//! (solver cycles, frames, the rows of a dense method) call [`requested`] between steps
//! and return their area's "interrupted" error. [`clear`] resets the flag before new work.
//!
//! The flag is one atomic boolean for the process: an interrupt stops every solve that is
//! running, which is what a user pressing Ctrl-C means.

use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks every running solve and render to stop at its next check.
pub fn request() { REQUESTED.store(true, Ordering::Relaxed) }

/// Whether a stop has been requested since the last [`clear`].
pub fn requested() -> bool { REQUESTED.load(Ordering::Relaxed) }

/// What work stopped this way says, wherever it is reported.
pub const STOPPED: &str = "stopped: interrupted (Ctrl-C or SIGTERM)";

/// `value`, or `stopped` where a stop was requested meanwhile: work it cut short (a frame
/// drawn in part) is never handed on as if it were whole.
pub fn unless_requested<T, E>(value: T, stopped: E) -> Result<T, E> { if requested() { Err(stopped) } else { Ok(value) } }

/// Forgets an earlier request, before new work starts.
pub fn clear() { REQUESTED.store(false, Ordering::Relaxed) }
