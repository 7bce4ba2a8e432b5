//! The adapter's safety net: every engine call runs on a worker thread while this thread
//! waits without the GIL and polls for signals, so that Ctrl-C and SIGTERM stop long work
//! (the engine checks `inkwarp_core::interrupt` between steps), and a panic in the engine
//! becomes `inkwarp.errors.InternalError` instead of crossing into Python.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicPtr, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use inkwarp_core::interrupt;
use pyo3::prelude::*;

/// How often the waiting thread looks for signals.
const POLL: Duration = Duration::from_millis(50);

/// The engine's threads' stack: deep enough for any recursion the engine does.
const STACK_BYTES: usize = 64 << 20;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    use inkwarp_core::limits;
    m.add("MAX_SIDE_PX", limits::MAX_SIDE_PX)?;
    m.add("MAX_PIXELS", limits::MAX_PIXELS)?;
    m.add("MAX_COORD_PX", limits::MAX_COORD_PX)?;
    m.add("MAX_TIME_S", limits::MAX_TIME_S)?;
    m.add("MIN_FPS", limits::MIN_FPS)?;
    m.add("MAX_FPS", limits::MAX_FPS)?;
    m.add_function(wrap_pyfunction!(crate::limits::check_size, m)?)?;
    m.add_function(wrap_pyfunction!(crate::limits::_solve_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    m.add_function(wrap_pyfunction!(_after_fork, m)?)?;
    Ok(())
}

/// Forgets the parent's thread pool in a forked child (`os.register_at_fork`), so that its
/// first engine call builds its own (see [`pool`]) whatever its process id.
#[pyfunction]
fn _after_fork() {
    POOL.store(std::ptr::null_mut(), Ordering::Release);
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
    inkwarp_error(py, "InternalError", &message).unwrap_or_else(|e| e)
}

/// `inkwarp.errors.InputError` (an `InkwarpError` and a `ValueError`) for an argument or input the engine
/// refuses; a plain `ValueError` where that class cannot be had.
pub fn input_error(message: impl std::fmt::Display) -> PyErr {
    let message = message.to_string();
    Python::attach(|py| inkwarp_error(py, "InputError", &message).unwrap_or_else(|_| pyo3::exceptions::PyValueError::new_err(message)))
}

/// The exception `inkwarp.errors.<class>` carrying `message`.
fn inkwarp_error(py: Python<'_>, class: &str, message: &str) -> PyResult<PyErr> {
    Ok(PyErr::from_value(py.import("inkwarp.errors")?.getattr(class)?.call1((message,))?))
}

/// The engine's thread pool and the process it belongs to.
struct Pool {
    pid: u32,
    pool: rayon::ThreadPool,
}

static POOL: AtomicPtr<Pool> = AtomicPtr::new(std::ptr::null_mut());

/// The engine's thread pool, this process's own. A forked process inherits its parent's
/// pool without the pool's threads (`fork` copies only the calling thread), so work handed
/// to it would wait forever: a child forked after the engine ran (the default start method
/// of `multiprocessing` on Linux before Python 3.14) builds a pool of its own on its first
/// call: Python forgets the parent's after a fork ([`_after_fork`]), and a pool is this
/// process's only if its id is. The parent's is left as it is, never dropped: its locks
/// may have been held by threads that do not exist in the child.
#[allow(unsafe_code)] // pointers from `Box::into_raw`, stored once and never freed
fn pool() -> Result<&'static rayon::ThreadPool, String> {
    let pid = std::process::id();
    let current = POOL.load(Ordering::Acquire);
    // SAFETY: a pointer stored in POOL comes from `Box::into_raw` and is never freed.
    if let Some(p) = unsafe { current.as_ref() }.filter(|p| p.pid == pid) {
        return Ok(&p.pool);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("inkwarp-pool-{i}"))
        .stack_size(STACK_BYTES)
        .build()
        .map_err(|e| e.to_string())?;
    let fresh = Box::into_raw(Box::new(Pool { pid, pool }));
    match POOL.compare_exchange(current, fresh, Ordering::AcqRel, Ordering::Acquire) {
        // SAFETY: as above; `fresh` is stored now and never freed.
        Ok(_) => Ok(unsafe { &(*fresh).pool }),
        Err(other) => {
            // Another thread of this process stored its pool first: use that one.
            // SAFETY: `fresh` was never shared; `other` is a stored pointer.
            drop(unsafe { Box::from_raw(fresh) });
            Ok(unsafe { &(*other).pool })
        }
    }
}

/// Runs `work` on a worker thread with the GIL released, polling for signals every
/// [`POLL`]; `work` runs on [`pool`]. A signal whose handler raises (KeyboardInterrupt, the CLI's SIGTERM) asks the
/// engine to stop, waits for it, and returns that exception; a panic becomes
/// `InternalError`.
pub fn run_engine<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> T + Send,
{
    let pool = engine_pool()?;
    run_engine_outside_pool(py, move || pool.install(work))
}

/// [`pool`], or the `OSError` a caller raises.
pub fn engine_pool() -> PyResult<&'static rayon::ThreadPool> {
    pool().map_err(|e| pyo3::exceptions::PyOSError::new_err(format!("could not start the engine's threads ({e})")))
}

/// [`run_engine`] for work that waits on the engine's own threads (a frame stream's
/// workers): it runs on the worker thread itself, as a job of the pool would keep a
/// thread that the frames it waits for may need (rayon runs any queued job on a thread
/// that waits for its own).
pub fn run_engine_outside_pool<T, F>(py: Python<'_>, work: F) -> PyResult<T>
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
