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
    // `fuzz!` makes any panic that leaves the reader an abort, which AFL++
    // records as a crash; panics the readers contain themselves (the LAZ
    // decoder's) are not findings and never reach it.
    afl::fuzz!(|data: &[u8]| {
        targets::run(target, data);
    });
}
