//! Cooperative interruption: long kernels call [`check_interrupt`] between chunks of work (rows,
//! tiles) and return [`RgbdError::Interrupted`] once the binding saw Ctrl-C and called
//! [`request_interrupt`]. A request is cleared when the last running kernel has returned, so it
//! never leaks into the next call.
//!
//! The request is process-wide: Ctrl-C on the main thread also stops kernels that other Python
//! threads run at that moment (they raise `KeyboardInterrupt` too), and a call started on another
//! thread before those have returned can see the request. A per-call token would need every
//! kernel to take one; for an interactive Ctrl-C this coarser rule is what users expect.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crate::{Result, RgbdError};

static PENDING: AtomicBool = AtomicBool::new(false);
static RUNNING: AtomicUsize = AtomicUsize::new(0);

/// `Err(Interrupted)` once an interrupt was requested while kernels run.
#[inline]
pub fn check_interrupt() -> Result<()> {
    if PENDING.load(Ordering::Relaxed) {
        Err(RgbdError::Interrupted)
    } else {
        Ok(())
    }
}

/// Asks every running kernel to stop at its next check.
pub fn request_interrupt() {
    PENDING.store(true, Ordering::Relaxed);
}

/// Asks the kernels running now to stop at their next check, as Ctrl-C does (for a caller whose
/// kernel runs on another thread, which sees no signal); nothing when none runs, where a request
/// would outlive them and stop the next call.
pub fn interrupt_running() {
    if RUNNING.load(Ordering::SeqCst) > 0 {
        PENDING.store(true, Ordering::SeqCst);
        // The last one may have returned between the two steps, clearing nothing: clear it here.
        if RUNNING.load(Ordering::SeqCst) == 0 {
            PENDING.store(false, Ordering::SeqCst);
        }
    }
}

/// Forgets the calls the process was running and any pending request: for a forked child, whose
/// copy of the counter still counts the calls the parent's other threads were in at the fork
/// (those threads do not exist in the child, so the count never fell to 0 and one Ctrl-C there
/// stopped every later call). Only sound in a fresh fork, where no kernel runs.
pub fn reset_after_fork() {
    RUNNING.store(0, Ordering::SeqCst);
    PENDING.store(false, Ordering::SeqCst);
}

/// Marks a kernel call as running until dropped (see [`running`]).
#[must_use = "the call counts as running only while the guard lives"]
pub struct Running(());

/// Registers a running kernel call; the pending interrupt is cleared when the last one ends.
pub fn running() -> Running {
    RUNNING.fetch_add(1, Ordering::SeqCst);
    Running(())
}

impl Drop for Running {
    fn drop(&mut self) {
        if RUNNING.fetch_sub(1, Ordering::SeqCst) == 1 {
            PENDING.store(false, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_stops_running_kernels_and_then_clears() {
        let guard = running();
        assert!(check_interrupt().is_ok());
        request_interrupt();
        assert_eq!(check_interrupt(), Err(RgbdError::Interrupted));
        drop(guard);
        assert!(check_interrupt().is_ok());
        // Without a running kernel the request is dropped (one test: the flags are global).
        interrupt_running();
        assert!(check_interrupt().is_ok());
        let guard = running();
        interrupt_running();
        assert_eq!(check_interrupt(), Err(RgbdError::Interrupted));
        drop(guard);
        assert!(check_interrupt().is_ok());
        // A fork's inherited count (a call of another thread at the fork) is forgotten.
        let inherited = running();
        interrupt_running();
        std::mem::forget(inherited);
        reset_after_fork();
        assert!(check_interrupt().is_ok());
        let guard = running();
        drop(guard);
        assert_eq!(RUNNING.load(Ordering::SeqCst), 0);
    }
}
