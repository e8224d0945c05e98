//! The `omcl` command-line tool.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    quiet_contained_panics();
    let args = cli::parse();
    if !args.handles_signals() {
        clean_up_on_interrupt();
    }
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if omcl::io::atomic::interrupted() {
                // The handler is removing what the command was writing
                // (the error is likely its doing) and then ends omcl.
                loop {
                    std::thread::park();
                }
            }
            eprintln!("error: {}", chain_message(&e));
            match e.downcast_ref::<cli::Exit>() {
                Some(exit) => ExitCode::from(exit.code),
                None => ExitCode::FAILURE,
            }
        }
    }
}

/// Ctrl-C (SIGINT) and SIGTERM (`scancel`, `kill`): the temporary file
/// being written and a folder the command made and is filling are removed
/// (`omcl::io::atomic::remove_interrupted`), then omcl ends as the signal
/// ends a program (the default action, re-raised), so a shell loop or a
/// batch system sees the signal, not an exit code. A signal the shell
/// set to be ignored (SIGINT for `omcl ... &` in a script) stays ignored.
/// Without the handler the signal ends omcl at once and a map being saved
/// leaves its hidden `.omcl-*.tmp` behind.
fn clean_up_on_interrupt() {
    use tokio::signal::unix::{SignalKind, signal};
    const SIGINT: i32 = 2;
    const SIGTERM: i32 = 15;
    let ignored = ignored_signals();
    let Ok(rt) = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()
    else {
        return;
    };
    // Registered before the command starts, so no signal is missed; a
    // signal that is ignored gets no handler (installing one would undo
    // the ignoring).
    let listen = |kind: SignalKind, sig: i32| {
        (ignored & (1 << (sig - 1)) == 0)
            .then(|| rt.block_on(async { signal(kind).ok() }))
            .flatten()
    };
    let int = listen(SignalKind::interrupt(), SIGINT);
    let term = listen(SignalKind::terminate(), SIGTERM);
    if int.is_none() && term.is_none() {
        return;
    }
    std::thread::spawn(move || {
        let sig = rt.block_on(async move {
            let wait = |s: Option<tokio::signal::unix::Signal>, n: i32| async move {
                match s {
                    Some(mut s) => {
                        s.recv().await;
                        n
                    }
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                n = wait(int, SIGINT) => n,
                n = wait(term, SIGTERM) => n,
            }
        });
        omcl::io::atomic::remove_interrupted();
        let _ = signal_hook::low_level::emulate_default_handler(sig);
        // Not reached unless the default action could not be restored.
        std::process::exit(128 + sig);
    });
}

/// The signals this process was started with set to be ignored (bit
/// `n - 1` for signal `n`), from `/proc/self/status`'s `SigIgn`; none when
/// it cannot be read.
fn ignored_signals() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("SigIgn:"))
                .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        })
        .unwrap_or(0)
}

/// The LAZ decoder (crate `laz`) asserts on some corrupt streams; the LAS
/// reader catches that and reports the file as corrupt. Its panic message
/// would only add noise before that error, so the hook drops it; every other
/// panic is printed as usual. Output into a closed pipe (`omcl map classes
/// semantickitti | head -1`) panics in `println!`: the reader has gone, so
/// omcl ends quietly with 141, as a program the pipe's signal stops.
fn quiet_contained_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let contained = info
            .location()
            .is_some_and(|l| l.file().contains("/laz-") || l.file().contains("\\laz-"));
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or_default();
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        if !contained {
            default(info);
        }
    }));
}

/// The error and its causes joined by ": ", each cause left out when the
/// message before it already ends with it: the library's errors name their
/// file and include their source (for callers that print only the top
/// error), which anyhow's `{:#}` would print twice.
fn chain_message(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if msg.ends_with(&c) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&c);
    }
    msg
}

#[cfg(test)]
mod tests {
    use super::chain_message;

    /// clap's own checks of every command's arguments (two options with
    /// one short name, a default its parser refuses, ...), which otherwise
    /// run only when that command is parsed in a debug build. They need
    /// debug assertions, which the test profile keeps (`cargo test
    /// --release` would pass this vacuously).
    #[test]
    fn every_command_line_is_well_formed() {
        super::cli::command().debug_assert();
    }

    #[test]
    fn a_cause_already_in_the_message_is_printed_once() {
        #[derive(Debug, thiserror::Error)]
        #[error("data.npy: {source}")]
        struct Named {
            source: std::io::Error,
        }
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let e = anyhow::Error::new(Named { source: io }).context("frame 3");
        assert_eq!(chain_message(&e), "frame 3: data.npy: No such file");
        // A cause not yet in the message is kept.
        let e = anyhow::anyhow!("disk full").context("writing out.tum");
        assert_eq!(chain_message(&e), "writing out.tum: disk full");
    }
}
