//! The command line's commands (this module belongs to the `envis` binary, not to the library):
//! `main.rs` parses the arguments and calls these.

pub mod commands;
pub mod demo;
pub mod scene;
pub mod sequence;

/// A panic (a bug, or a library that panics on a condition it does not report) prints one line
/// and exits with code 101, like every other error; `RUST_BACKTRACE` set keeps Rust's own report.
pub fn one_line_panics() {
    if std::env::var_os("RUST_BACKTRACE").is_some() {
        return;
    }
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let first = msg.lines().next().unwrap_or("");
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("envis: error: internal failure: {first}{at} (RUST_BACKTRACE=1 for details)");
    }));
}
