//! Progress on standard error: bars on a terminal; in a log (standard
//! error redirected, as under Slurm or `nohup`) a plain line every 10 s
//! (`OMCL_PROGRESS_EVERY_S` sets it; the first after 2 s, or the interval
//! if shorter) instead of nothing, so that a long run's log says how far
//! it is, and a short or failing command's log holds only what it says.
//! A log that got progress lines gets a last one when the work is done
//! ([`finish`]), so that it does not end at 97/100.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

/// How often a progress line goes into a log, by default.
pub const LOG_EVERY: Duration = Duration::from_secs(10);

/// The first progress line of a log waits this long (a short command's
/// log gets none).
const LOG_FIRST: Duration = Duration::from_secs(2);

/// The log interval: `OMCL_PROGRESS_EVERY_S` (seconds, >= 0), else
/// [`LOG_EVERY`].
fn log_every() -> Duration {
    std::env::var("OMCL_PROGRESS_EVERY_S")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .and_then(|s| Duration::try_from_secs_f64(s).ok())
        .unwrap_or(LOG_EVERY)
}

/// A bar for `len` steps of `what`.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    bar_of(len, what, "")
}

/// A bar for `len` `unit` of `what` ("scanning", "frames").
pub fn bar_of(len: u64, what: &str, unit: &str) -> ProgressBar {
    let template = if logging() {
        "{prefix}: {pos}/{len} {msg} (elapsed {elapsed}, left about {eta})"
    } else {
        "{prefix:>12} [{bar:30}] {pos}/{len} {msg} ({eta})"
    };
    let style = ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    // Builders, which do not draw: the first state drawn (a log's first
    // line) has the prefix and the unit.
    ProgressBar::with_draw_target(Some(len), target())
        .with_prefix(what.to_string())
        .with_message(unit.to_string())
        .with_style(style)
}

/// A spinner for work of unknown length.
pub fn spinner(what: &str) -> ProgressBar {
    let style = if logging() {
        ProgressStyle::with_template("{msg} (elapsed {elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner())
    } else {
        ProgressStyle::default_spinner()
    };
    let pb = ProgressBar::with_draw_target(None, target())
        .with_message(what.to_string())
        .with_style(style);
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Ends `pb`'s work: the bar is cleared from a terminal; a log that got
/// progress lines (the bar lived past the first line's delay) gets a last
/// one, `what: N/N unit (done in 12s)` (a spinner: its message and the
/// time). An error path drops the bar
/// instead, and its message is the log's last line.
pub fn finish(pb: &ProgressBar) {
    // Once: a second call says nothing.
    if pb.is_finished() {
        return;
    }
    pb.finish_and_clear();
    if !logging() || pb.elapsed() < log_every().min(LOG_FIRST) {
        return;
    }
    let done = indicatif::HumanDuration(pb.elapsed());
    let line = match pb.length() {
        Some(len) => format!("{}: {}/{len} {}", pb.prefix(), pb.position(), pb.message()),
        None => pb.message(),
    };
    let line = line.split_whitespace().collect::<Vec<_>>().join(" ");
    eprintln!("{line} (done in {done})");
}

/// Standard error is not a terminal: progress goes to a log.
fn logging() -> bool {
    !std::io::stderr().is_terminal()
}

/// Where bars draw: the terminal, or a log's lines.
pub fn target() -> ProgressDrawTarget {
    if logging() {
        ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::new()), 1)
    } else {
        ProgressDrawTarget::stderr()
    }
}

/// A terminal that writes a bar's state as one line of standard error at
/// most every [`log_every`] (the first after [`LOG_FIRST`]), and drops the
/// cursor moves.
#[derive(Debug)]
struct LogLines {
    every: Duration,
    state: Mutex<LogState>,
}

#[derive(Debug)]
struct LogState {
    line: String,
    /// When a line may next be written.
    next: Instant,
}

impl LogLines {
    fn new() -> LogLines {
        let every = log_every();
        LogLines {
            every,
            state: Mutex::new(LogState {
                line: String::new(),
                next: Instant::now() + every.min(LOG_FIRST),
            }),
        }
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        160
    }
    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.write_str(s)
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        st.line.push_str(s);
        Ok(())
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let line = std::mem::take(&mut st.line);
        // An empty message leaves two spaces in the template's line.
        let line = line.split_whitespace().collect::<Vec<_>>().join(" ");
        let now = Instant::now();
        if now >= st.next && !line.is_empty() {
            st.next = now + self.every;
            eprintln!("{line}");
        }
        Ok(())
    }
}

/// The bar of a map built in two passes (`map cloud` on a sequence folder
/// or on LAS/LAZ files and tiles): the first pass (reading only, for the
/// grid's centre) and the second (mapping) each with its own length and
/// ETA, then a spinner while the map is finished (its voxels sorted, its
/// features merged) instead of a bar stuck at N/N.
pub struct TwoPasses {
    bar: ProgressBar,
    mapping: bool,
    finishing: Option<ProgressBar>,
}

impl TwoPasses {
    /// Bars for `len` `unit` a pass (0: set by the first update).
    pub fn new(len: u64, unit: &str) -> Self {
        TwoPasses {
            bar: bar_of(len, "pass 1 of 2, the grid's centre", unit),
            mapping: false,
            finishing: None,
        }
    }

    /// `done` of `total` in the first pass (`mapping` false) or the second.
    pub fn update(&mut self, mapping: bool, done: u64, total: u64) {
        if mapping != self.mapping || done == 1 {
            self.mapping = mapping;
            self.bar.set_length(total);
            if mapping {
                self.bar.set_prefix("pass 2 of 2, mapping");
            }
            // The ETA from this pass's rate; elapsed counts both.
            self.bar.reset_eta();
        }
        self.bar.set_position(done);
        if mapping && done == total && self.finishing.is_none() {
            finish(&self.bar);
            self.finishing = Some(spinner("finishing the map"));
        }
    }

    /// Ends the bar and the spinner.
    pub fn finish(self) {
        finish(&self.bar);
        if let Some(s) = self.finishing {
            finish(&s);
        }
    }
}
