//! A lock for Python objects used from several threads, whose calls take turns in the
//! order they arrive.
//!
//! A call holds the lock while it computes with the GIL released, and needs the GIL again
//! to return its results; a call that waited for the lock *with* the GIL would deadlock
//! with it. So waiting happens with the GIL released, and, so that a thread calling in a
//! tight loop cannot take the lock again before a waiting one (it holds the GIL when the
//! lock frees), each call draws a ticket and the lock goes to tickets in order.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::ops::{Deref, DerefMut};
use std::sync::{Condvar, Mutex, MutexGuard};

/// `T` behind a lock handed out in arrival order (see the module docs).
pub(crate) struct Turns<T> {
    value: Mutex<T>,
    /// (next ticket to draw, ticket being served).
    tickets: Mutex<(u64, u64)>,
    served: Condvar,
    what: &'static str,
}

/// Access to the value for one call; the next ticket is served when it is dropped.
pub(crate) struct Turn<'a, T> {
    guard: Option<MutexGuard<'a, T>>,
    turns: &'a Turns<T>,
}

impl<T: Send> Turns<T> {
    /// `value`, named `what` in the error of a call after a panic in another.
    pub(crate) fn new(value: T, what: &'static str) -> Self {
        Turns {
            value: Mutex::new(value),
            tickets: Mutex::new((0, 0)),
            served: Condvar::new(),
            what,
        }
    }

    fn tickets(&self) -> MutexGuard<'_, (u64, u64)> {
        self.tickets.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Wait for this call's turn (without the GIL when another call holds the lock).
    pub(crate) fn lock(&self, py: Python<'_>) -> PyResult<Turn<'_, T>> {
        let mine = {
            let mut t = self.tickets();
            t.0 += 1;
            t.0 - 1
        };
        if self.tickets().1 != mine {
            // Waiting, not working: outside soundloc's pool, whose threads the call being
            // served needs (a waiter on one would leave it fewer, or none).
            py.allow_threads(|| {
                let mut t = self.tickets();
                while t.1 != mine {
                    t = self.served.wait(t).unwrap_or_else(|p| p.into_inner());
                }
            });
        }
        // Only the ticket being served locks the value, and the one before released it
        // before passing the turn on: this does not wait.
        let mut turn = Turn {
            guard: None,
            turns: self,
        };
        match self.value.lock() {
            Ok(g) => turn.guard = Some(g),
            // Dropping `turn` passes the turn on.
            Err(_) => {
                return Err(PyRuntimeError::new_err(format!(
                    "the {} failed in another thread",
                    self.what
                )))
            }
        }
        Ok(turn)
    }
}

impl<T> Deref for Turn<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.guard.as_deref().expect("held until dropped")
    }
}

impl<T> DerefMut for Turn<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.guard.as_deref_mut().expect("held until dropped")
    }
}

impl<T> Drop for Turn<'_, T> {
    fn drop(&mut self) {
        self.guard.take();
        let mut t = self.turns.tickets.lock().unwrap_or_else(|p| p.into_inner());
        t.1 += 1;
        drop(t);
        self.turns.served.notify_all();
    }
}
