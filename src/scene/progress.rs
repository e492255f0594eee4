//! A minimal progress bar on stderr for long loads and preprocessing, shown only when stderr is
//! a terminal (never in pipes, logs or tests). The newest bar's stage and percentage are also
//! published process-wide ([`current`]) for the viewer's load screen.

use std::io::{self, IsTerminal, Write};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The newest bar's label and percentage.
static CURRENT: Mutex<Option<(&'static str, usize)>> = Mutex::new(None);

/// The stage the newest progress bar counts and its percentage, if one was made.
pub fn current() -> Option<(&'static str, usize)> {
    CURRENT.lock().ok().and_then(|c| *c)
}

fn publish(label: &'static str, percent: usize) {
    if let Ok(mut c) = CURRENT.lock() {
        *c = Some((label, percent));
    }
}

/// A shared, thread-safe bar: workers call [`Progress::advance`] with the units they finished.
pub(crate) struct Progress {
    label: &'static str,
    total: usize,
    done: AtomicUsize,
    shown: AtomicUsize,
    enabled: bool,
}

impl Progress {
    /// A bar over `total` units, drawn only when `wanted` and stderr is a terminal.
    pub(crate) fn new(label: &'static str, total: usize, wanted: bool) -> Self {
        if total > 0 {
            publish(label, 0);
        }
        Progress {
            label,
            total,
            done: AtomicUsize::new(0),
            shown: AtomicUsize::new(0),
            enabled: wanted && io::stderr().is_terminal(),
        }
    }

    /// Records `n` more finished units and redraws when the percentage changed.
    pub(crate) fn advance(&self, n: usize) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        let percent = (done * 100 / self.total.max(1)).min(100);
        if percent > self.shown.fetch_max(percent, Ordering::Relaxed) {
            publish(self.label, percent);
            if !self.enabled {
                return;
            }
            let filled = percent * 30 / 100;
            let bar = format!("{}{}", "#".repeat(filled), " ".repeat(30 - filled));
            let mut err = io::stderr().lock();
            // A failed progress write is harmless; the computation goes on.
            let _ = write!(err, "\r{:<8} [{bar}] {percent:3}%", self.label);
            let _ = err.flush();
        }
    }

    /// Ends the bar's line.
    pub(crate) fn finish(&self) {
        if self.enabled {
            eprintln!();
        }
    }
}
