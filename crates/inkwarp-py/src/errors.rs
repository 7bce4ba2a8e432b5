//! The adapter's safety net: every engine call runs on a worker thread while this thread
//! waits without the GIL and polls for signals, so that Ctrl-C and SIGTERM stop long work
//! (the engine checks `inkwarp_core::interrupt` between steps), and a panic in the engine
//! becomes `inkwarp.errors.InternalError` instead of crossing into Python.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc;
use std::time::Duration;

use inkwarp_core::interrupt;
use pyo3::prelude::*;

/// How often the waiting thread looks for signals.
const POLL: Duration = Duration::from_millis(50);

/// The worker's stack: deep enough for any recursion the engine does.
const STACK_BYTES: usize = 64 << 20;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    use inkwarp_core::limits;
    m.add("MAX_SIDE_PX", limits::MAX_SIDE_PX)?;
    m.add("MAX_PIXELS", limits::MAX_PIXELS)?;
    m.add("MAX_COORD_PX", limits::MAX_COORD_PX)?;
    m.add("MAX_TIME_S", limits::MAX_TIME_S)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}

/// Panics inside the engine's worker thread, so that tests can check the net that turns a
/// panic into `InternalError`.
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    run_engine(py, || -> () { panic!("a panic raised on purpose by _panic_for_tests") })
}

/// `KeyboardInterrupt` for an engine call that stopped because a stop was requested (the
/// engine's `Interrupted`): raised when the request came from elsewhere than this call's
/// own signal check (which raises the signal's own exception), so that an interrupted
/// solve never surfaces as a `ValueError`.
pub fn interrupted(what: &str) -> PyErr {
    pyo3::exceptions::PyKeyboardInterrupt::new_err(format!("{what} stopped: interrupted"))
}

/// `inkwarp.errors.InternalError` for a panic's payload.
pub fn internal_error(py: Python<'_>, payload: &(dyn Any + Send)) -> PyErr {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string());
    let message = format!(
        "internal error in inkwarp's engine ({what}); this is a bug in inkwarp, please report \
         it with the input that caused it"
    );
    let build = || -> PyResult<PyErr> {
        let class = py.import("inkwarp.errors")?.getattr("InternalError")?;
        Ok(PyErr::from_value(class.call1((message.clone(),))?))
    };
    build().unwrap_or_else(|e| e)
}

/// Runs `work` on a worker thread with the GIL released, polling for signals every
/// [`POLL`]. A signal whose handler raises (KeyboardInterrupt, the CLI's SIGTERM) asks the
/// engine to stop, waits for it, and returns that exception; a panic becomes
/// `InternalError`.
pub fn run_engine<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> T + Send,
{
    std::thread::scope(|scope| {
        let (done_tx, done_rx) = mpsc::channel::<()>();
        let worker = std::thread::Builder::new()
            .name("inkwarp-engine".into())
            .stack_size(STACK_BYTES)
            .spawn_scoped(scope, move || {
                let result = catch_unwind(AssertUnwindSafe(work));
                let _ = done_tx.send(());
                result
            });
        let worker = match worker {
            Ok(worker) => worker,
            Err(err) => {
                return Err(pyo3::exceptions::PyOSError::new_err(format!(
                    "could not start the engine's thread ({err})"
                )))
            }
        };
        // Only this thread receives; the lock makes the receiver shareable with `detach`.
        let done_rx = std::sync::Mutex::new(done_rx);
        let mut signal: Option<PyErr> = None;
        loop {
            let waited = py.detach(|| match done_rx.lock() {
                Ok(rx) => rx.recv_timeout(POLL),
                Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
            });
            if !matches!(waited, Err(mpsc::RecvTimeoutError::Timeout)) {
                break;
            }
            if signal.is_none() {
                if let Err(err) = py.check_signals() {
                    interrupt::request();
                    signal = Some(err);
                }
            }
        }
        let joined = py.detach(|| worker.join());
        if let Some(err) = signal {
            interrupt::clear();
            return Err(err);
        }
        match joined {
            Ok(Ok(value)) => Ok(value),
            Ok(Err(payload)) | Err(payload) => Err(internal_error(py, payload.as_ref())),
        }
    })
}
