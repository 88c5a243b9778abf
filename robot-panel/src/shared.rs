//! The live machine shared by the feed, the radio thread and the page's streams: a
//! version that moves with every change, and a wait for the next one.

use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::Duration;

use crate::live::Live;

pub struct Shared {
    inner: Mutex<(u64, Live)>,
    changed: Condvar,
}

impl Shared {
    pub fn new(live: Live) -> Shared {
        Shared {
            inner: Mutex::new((0, live)),
            changed: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, (u64, Live)> {
        // A thread that panicked holding it left a consistent value (every update is
        // whole): keep serving it.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Changes the machine; `f` says whether anything changed (the streams are woken).
    pub fn update(&self, f: impl FnOnce(&mut Live) -> bool) {
        let mut g = self.lock();
        if f(&mut g.1) {
            g.0 = g.0.wrapping_add(1);
            self.changed.notify_all();
        }
    }

    /// The machine now, and its version.
    pub fn read<R>(&self, f: impl FnOnce(&Live) -> R) -> (u64, R) {
        let g = self.lock();
        (g.0, f(&g.1))
    }

    /// Waits until the version is not `seen` any more, at most `timeout`; the version.
    pub fn wait_change(&self, seen: u64, timeout: Duration) -> u64 {
        let g = self.lock();
        let (g, _) = self
            .changed
            .wait_timeout_while(g, timeout, |g| g.0 == seen)
            .unwrap_or_else(|e| e.into_inner());
        g.0
    }
}
