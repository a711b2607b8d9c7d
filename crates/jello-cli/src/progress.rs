//! A one-line progress bar on stderr, drawn only when stderr is a terminal.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// Redraw at most this often.
const REDRAW: Duration = Duration::from_millis(100);

/// Progress of a run of `total` steps.
pub struct Progress {
    total: u64,
    start: Instant,
    last_draw: Option<Instant>,
    enabled: bool,
}

impl Progress {
    /// A bar for `total` steps; silent when `quiet` or when stderr is not a terminal.
    pub fn new(total: u64, quiet: bool) -> Self {
        Progress {
            total,
            start: Instant::now(),
            last_draw: None,
            enabled: !quiet && std::io::stderr().is_terminal(),
        }
    }

    /// Notes that `done` steps are finished; redraws when due.
    #[inline]
    pub fn update(&mut self, done: u64) {
        if !self.enabled || done % 64 != 0 {
            return;
        }
        let now = Instant::now();
        if self.last_draw.is_some_and(|t| now - t < REDRAW) {
            return;
        }
        self.last_draw = Some(now);
        let frac = done as f64 / self.total.max(1) as f64;
        let width = 30;
        let filled = ((frac * width as f64) as usize).min(width);
        let elapsed = self.start.elapsed().as_secs_f64();
        let rate = done as f64 / elapsed.max(1e-9);
        let eta = (self.total - done) as f64 / rate.max(1e-9);
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r[{}{}] {:3.0}% {done}/{} steps  {:.0} steps/s  ETA {:.0} s ",
            "#".repeat(filled),
            " ".repeat(width - filled),
            frac * 100.0,
            self.total,
            rate,
            eta
        );
        let _ = err.flush();
    }

    /// Clears the bar.
    pub fn finish(&mut self) {
        if self.enabled && self.last_draw.is_some() {
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r{}\r", " ".repeat(79));
            let _ = err.flush();
        }
    }
}
