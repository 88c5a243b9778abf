//! What the commands print. A command's output whose reader went away (`config-tool check
//! r.ron | head -1`, a supervisor that dropped its pipe) is not the command's failure: the
//! rest of what it prints is lost and it finishes what it does (a push pushes, a server
//! serves), its exit status its own. The watchers (`monitor`, `alarms --watch`), whose only
//! work is printing, end there, as a filter does. Any other failure to write the output (a
//! full disk) fails the command once it has done its work: `main` asks [`failed`].
//!
//! `out!` / `outln!` print on standard output, `err!` / `errln!` on standard error; unlike
//! `print!` they never panic.

use std::fmt;
use std::io::{self, Write};
use std::sync::Mutex;

/// The first failure to write standard output other than its reader going away.
static FAILED: Mutex<Option<String>> = Mutex::new(None);

/// Writes `args` on standard output (see the module). False once its reader went away or
/// it failed: a watcher stops there.
pub fn print(args: fmt::Arguments) -> bool {
    let mut out = io::stdout().lock();
    noted(out.write_fmt(args))
}

/// Writes `args` on standard error, ignoring a failure (there is nowhere left to say it).
pub fn eprint(args: fmt::Arguments) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// Flushes standard output; its failure, unless its reader went away, fails the command.
pub fn flush() {
    noted(io::stdout().lock().flush());
}

/// The first failure to write standard output (not a reader that went away), as the
/// command's error.
pub fn failed() -> Option<String> {
    FAILED.lock().map_or(None, |f| f.clone())
}

fn noted(written: io::Result<()>) -> bool {
    match written {
        Ok(()) => true,
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => false,
        Err(e) => {
            if let Ok(mut failed) = FAILED.lock() {
                failed.get_or_insert_with(|| format!("cannot write standard output: {e}"));
            }
            false
        }
    }
}

/// `print!` that never panics (see the module); true while the output is written.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::out::print(format_args!($($arg)*))
    };
}

/// `println!` that never panics (see the module); true while the output is written.
macro_rules! outln {
    () => {
        $crate::out::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` that never panics.
macro_rules! err {
    ($($arg:tt)*) => {
        $crate::out::eprint(format_args!($($arg)*))
    };
}

/// `eprintln!` that never panics.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::out::eprint(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {err, errln, out, outln};
