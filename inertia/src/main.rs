//! `inertia`: see `inertia --help`.
fn main() {
    eprintln!("inertia: no subcommand yet");
    std::process::exit(2);
}
