//! One AFL++ harness binary for every parser: the target's name is the
//! first argument (`omcl-fuzz ply`; `omcl-fuzz --list` names them all).

mod targets;

use targets::Target;

fn main() {
    let Some(name) = std::env::args().nth(1) else {
        eprintln!("usage: omcl-fuzz TARGET   (omcl-fuzz --list names the targets)");
        std::process::exit(2);
    };
    if name == "--list" {
        for t in Target::ALL {
            println!("{}", t.name());
        }
        return;
    }
    let Some(target) = Target::from_name(&name) else {
        eprintln!("omcl-fuzz: unknown target '{name}' (omcl-fuzz --list names them)");
        std::process::exit(2);
    };
    // `fuzz_nohook!`: a panic that leaves the reader is caught by afl's loop
    // and turned into an abort, which AFL++ records as a crash. `fuzz!`
    // would abort from a panic hook before unwinding, and so also on panics
    // the readers contain on purpose (the LAZ decoder's assertions, which
    // `io::las` reports as a corrupt file).
    afl::fuzz_nohook!(|data: &[u8]| {
        targets::run(target, data);
    });
}
