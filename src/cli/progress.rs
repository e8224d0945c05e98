//! Progress on standard error: bars on a terminal; in a log (standard
//! error redirected, as under Slurm or `nohup`) a plain line every
//! [`LOG_EVERY`] instead of nothing, so that a long run's log says how far
//! it is.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

/// How often a progress line goes into a log.
pub const LOG_EVERY: Duration = Duration::from_secs(10);

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
    let pb = ProgressBar::with_draw_target(None, target());
    if logging()
        && let Ok(style) = ProgressStyle::with_template("{msg} (elapsed {elapsed})")
    {
        pb.set_style(style);
    }
    pb.set_message(what.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Standard error is not a terminal: progress goes to a log.
fn logging() -> bool {
    !std::io::stderr().is_terminal()
}

/// Where bars draw: the terminal, or a log's lines.
pub fn target() -> ProgressDrawTarget {
    if logging() {
        ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::default()), 1)
    } else {
        ProgressDrawTarget::stderr()
    }
}

/// A terminal that writes a bar's state as one line of standard error at
/// most every [`LOG_EVERY`] (the first at once), and drops the cursor
/// moves.
#[derive(Debug, Default)]
struct LogLines {
    state: Mutex<LogState>,
}

#[derive(Debug, Default)]
struct LogState {
    line: String,
    last: Option<Instant>,
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
        let line = line.trim();
        let due = st.last.is_none_or(|t| t.elapsed() >= LOG_EVERY);
        if due && !line.is_empty() {
            st.last = Some(Instant::now());
            eprintln!("{line}");
        }
        Ok(())
    }
}
