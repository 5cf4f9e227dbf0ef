//! The one way the gateway takes its locks.

use std::sync::{Mutex, MutexGuard};

/// Locks `m`, even if a thread panicked holding it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
