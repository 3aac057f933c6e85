//! The Python exception hierarchy, the one mapping from the core error enum to it, the single
//! helper that runs core code without the GIL, and the single helper that borrows numpy memory.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread;
use std::time::Duration;

use numpy::{Element, PyArrayMethods, PyReadonlyArray, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyMemoryError, PyValueError};
use pyo3::prelude::*;
use rgbd_error::RgbdError as CoreError;

create_exception!(
    _rgbd_rs,
    RgbdError,
    PyValueError,
    "Base class of every rgbd_rs error (a ValueError)."
);
create_exception!(
    _rgbd_rs,
    InvalidArgumentError,
    RgbdError,
    "An argument is out of range or of the wrong kind."
);
create_exception!(
    _rgbd_rs,
    ShapeMismatchError,
    RgbdError,
    "An array does not have the shape its companions or the camera imply."
);

/// Maps a core error to its Python exception, message unchanged: one variant, one class.
pub fn to_py(err: CoreError) -> PyErr {
    let msg = err.to_string();
    match err {
        CoreError::InvalidArgument { .. } => InvalidArgumentError::new_err(msg),
        CoreError::ShapeMismatch { .. } => ShapeMismatchError::new_err(msg),
        CoreError::Interrupted => PyKeyboardInterrupt::new_err("interrupted in the native core"),
        CoreError::OutOfMemory { .. } => PyMemoryError::new_err(msg),
    }
}

/// `ShapeMismatchError` with `msg` (for shape checks done in the binding itself).
pub fn shape_err(msg: String) -> PyErr {
    ShapeMismatchError::new_err(msg)
}

/// How often a waiting caller looks for Ctrl-C while a kernel runs on another thread.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// The process that imported the module. rayon's global pool belongs to it: a forked child
/// (multiprocessing's default start method on Linux, torch DataLoader workers) inherits the
/// pool's bookkeeping but none of its threads, and a parallel kernel there would wait for them
/// forever.
static PARENT: OnceLock<u32> = OnceLock::new();
/// A forked child's own pool, built at its first call (keyed by pid: a grandchild builds anew).
static CHILD_POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// The pool of kernels a caller runs on a worker thread beside other native calls (`fuse()`'s
/// LC beside its input checks): in the global pool those calls' jobs would queue behind the
/// kernel's until it ended. Keyed by pid as [`CHILD_POOL`]; as many threads as the global pool.
static SIDE_POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// Which rayon pool a kernel runs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pool {
    /// The process's pool (a forked child's own, see [`in_own_pool`]).
    Global,
    /// [`SIDE_POOL`].
    Side,
}

/// The pool in `slot` for this process, built with `threads` threads at the first call.
fn pool_of(
    slot: &Mutex<Option<(u32, Arc<rayon::ThreadPool>)>>,
    threads: usize,
) -> Arc<rayon::ThreadPool> {
    let pid = std::process::id();
    let mut slot = slot.lock().unwrap_or_else(|e| e.into_inner());
    match slot.as_ref() {
        Some((owner, pool)) if *owner == pid => Arc::clone(pool),
        _ => match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
            Ok(pool) => {
                let pool = Arc::new(pool);
                // A pool inherited through a fork is leaked, never dropped: dropping it would
                // wake its threads, which do not exist here, through locks one of them may have
                // held at the fork.
                if let Some(stale) = slot.replace((pid, Arc::clone(&pool))) {
                    std::mem::forget(stale);
                }
                pool
            }
            // No thread to be had: the caller's catch_unwind makes this an RgbdError instead
            // of a hang.
            Err(e) => panic!("could not start worker threads: {e}"),
        },
    }
}

/// Records the importing process (called once, when the module is created).
pub fn record_parent() {
    PARENT.get_or_init(std::process::id);
}

/// Whether this process is a fork of the one that imported the module.
pub fn is_fork_child() -> bool {
    let pid = std::process::id();
    *PARENT.get_or_init(|| pid) != pid
}

/// Runs `f` where its rayon work can run: directly in the importing process, in a pool of the
/// child's own after a fork (see [`PARENT`]).
fn in_own_pool<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    if !is_fork_child() {
        return f();
    }
    pool_of(&CHILD_POOL, crate::fork_child_threads()).install(f)
}

thread_local! {
    /// The pool the kernels this thread calls run in (see [`use_side_pool`]).
    static POOL: std::cell::Cell<Pool> = const { std::cell::Cell::new(Pool::Global) };
}

/// Makes the kernels the calling thread starts run in [`SIDE_POOL`] (`on`) or the process's pool:
/// for a Python worker thread that runs native calls beside those of another thread (`fuse()`'s
/// matcher beside its ToF upsampling, its LC beside its input checks). Each thread starts with
/// the process's pool.
#[pyfunction]
pub fn use_side_pool(on: bool) {
    POOL.with(|p| p.set(if on { Pool::Side } else { Pool::Global }));
}

/// Runs `f` in the pool the calling thread asked for (see [`use_side_pool`]); the pool is read
/// on the calling thread, `f` may run on another.
fn in_pool<T: Send>(pool: Pool, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Pool::Global => in_own_pool(f),
        Pool::Side => pool_of(&SIDE_POOL, crate::num_threads()).install(f),
    }
}

/// The pool the calling thread asked for.
fn chosen_pool() -> Pool {
    POOL.with(std::cell::Cell::get)
}

/// Runs `f` with the GIL released; a panic becomes `RgbdError` instead of crossing into Python.
pub fn run<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, CoreError> + Send,
{
    let _running = rgbd_error::running();
    let pool = chosen_pool();
    finish(py.detach(|| catch_unwind(AssertUnwindSafe(|| in_pool(pool, f)))))
}

/// [`run`] for kernels that can take seconds: `f` runs on a scoped thread while this thread
/// polls for signals; Ctrl-C asks the kernel to stop at its next `check_interrupt` (between rows)
/// and raises `KeyboardInterrupt` once it has.
pub fn run_interruptible<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, CoreError> + Send,
{
    let pool = chosen_pool();
    let _running = rgbd_error::running();
    let mut signal: Option<PyErr> = None;
    let out = py.detach(|| {
        thread::scope(|s| {
            // The result comes back through a channel, so the caller wakes the moment it is sent
            // (polling `is_finished` would round every call up to the polling period).
            let (tx, rx) = mpsc::channel();
            s.spawn(move || {
                // The receiver lives until the scope ends, so this send cannot fail.
                let _ = tx.send(catch_unwind(AssertUnwindSafe(|| in_pool(pool, f))));
            });
            loop {
                match rx.recv_timeout(SIGNAL_POLL) {
                    Ok(out) => break out,
                    Err(RecvTimeoutError::Timeout) if signal.is_none() => {
                        if let Err(e) = Python::attach(|py| py.check_signals()) {
                            rgbd_error::request_interrupt();
                            signal = Some(e);
                        }
                    }
                    // Asked again at every poll until the worker returns: another call ending
                    // in between may have cleared the shared request.
                    Err(RecvTimeoutError::Timeout) => rgbd_error::request_interrupt(),
                    // The worker ended without sending: it can only have panicked past
                    // catch_unwind, which the scope re-raises when it joins.
                    Err(RecvTimeoutError::Disconnected) => {
                        break Err(Box::new("worker thread ended without a result"))
                    }
                }
            }
        })
    });
    match signal {
        Some(e) => Err(e),
        None => finish(out),
    }
}

fn finish<T>(out: std::thread::Result<Result<T, CoreError>>) -> PyResult<T> {
    match out {
        Ok(res) => res.map_err(to_py),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(RgbdError::new_err(format!(
                "internal error in the native core (please report): {what}"
            )))
        }
    }
}

/// Borrows a numpy array's memory as a row-major slice. Every borrow goes through here, so a
/// Fortran-ordered, strided or unaligned array is refused (the public wrappers copy those once)
/// instead of being read in the wrong order.
pub fn borrow<'a, T: Element, Dim: numpy::ndarray::Dimension>(
    arg: &str,
    a: &'a PyReadonlyArray<'_, T, Dim>,
) -> PyResult<&'a [T]> {
    let aligned = (a.data() as usize).is_multiple_of(std::mem::align_of::<T>());
    match a.as_slice() {
        Ok(s) if aligned && (a.is_c_contiguous()) => Ok(s),
        _ => Err(InvalidArgumentError::new_err(format!(
            "{arg}: got a non-C-contiguous or unaligned array, expected a C-contiguous aligned \
             array (the public rgbd_rs functions copy such arrays; the native module does not)"
        ))),
    }
}
