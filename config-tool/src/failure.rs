//! How a command failed: the message to print and the exit status (docs/config-tool.md).
//! The one place an `error:` prefix is written.

use std::fmt::Display;

use robot_compiler::source::LoadError;
use robot_net::demo::Verdict;
use robot_net::NetError;

/// The exit statuses.
pub mod exit {
    /// Anything else that went wrong (bad robot, no medium, nodes that never started).
    pub const ERROR: u8 = 1;
    /// A bad command line (clap's usage errors, and a missing `--keys` for a secured robot).
    pub const USAGE: u8 = 2;
    /// A node did not activate its table (refused, or stopped answering).
    pub const PUSH_FAILED: u8 = 3;
    /// A cycle did not produce the declared sequence.
    pub const MISMATCH: u8 = 4;
    /// A node faulted (a watchdog, a peer's fault, a link alarm in a stalled machine).
    pub const FAULTED: u8 = 5;
    /// The machine's state refuses the command, nothing was sent: `start` of a machine
    /// not homed, `home` or `start` of one faulted or moving.
    pub const REFUSED: u8 = 6;
}

/// A command that failed: what to print (nothing if it was printed already), and the exit
/// status.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct Failure {
    pub code: u8,
    pub message: String,
}

impl Failure {
    /// `error: WHAT`, status 1.
    pub fn error(what: impl Display) -> Failure {
        Failure {
            code: exit::ERROR,
            message: format!("error: {what}"),
        }
    }

    /// `error: WHAT`, status 2: the command line lacks something (as clap's usage errors).
    pub fn usage(what: impl Display) -> Failure {
        Failure {
            code: exit::USAGE,
            message: format!("error: {what}"),
        }
    }

    /// `error: WHAT`, status 6: the machine's state refuses the command.
    pub fn refused(what: impl Display) -> Failure {
        Failure {
            code: exit::REFUSED,
            message: format!("error: {what}"),
        }
    }

    /// Status 1, the reason already printed (diagnostics, a counterexample, a diff).
    pub fn reported() -> Failure {
        Failure {
            code: exit::ERROR,
            message: String::new(),
        }
    }

    /// Printed as it is (it says what went wrong itself).
    pub fn as_is(code: u8, message: impl Into<String>) -> Failure {
        Failure {
            code,
            message: message.into(),
        }
    }

    /// How a demo ended, as the command's result.
    pub fn of_verdict(verdict: Verdict) -> Result<(), Failure> {
        let (code, message) = match verdict {
            Verdict::Matched => return Ok(()),
            Verdict::PushFailed => (exit::PUSH_FAILED, "demo: the push failed"),
            Verdict::Mismatch => (
                exit::MISMATCH,
                "demo: a cycle did not match its declared sequence",
            ),
            Verdict::Faulted => (exit::FAULTED, "demo: the machine faulted"),
        };
        Err(Failure::as_is(code, message))
    }
}

impl From<NetError> for Failure {
    fn from(e: NetError) -> Failure {
        match e {
            // Rendered diagnostics: they say `error` themselves.
            NetError::Robot(rendered) => Failure::as_is(exit::ERROR, rendered),
            NetError::Load(e) => Failure::from(e),
            e => Failure::error(e),
        }
    }
}

impl From<LoadError> for Failure {
    fn from(e: LoadError) -> Failure {
        match e {
            // `FILE:LINE:COL: error: ...`, as a diagnostic.
            LoadError::NotUtf8 { .. } => Failure::as_is(exit::ERROR, e.to_string()),
            LoadError::Read { .. } => Failure::error(e),
        }
    }
}

impl From<medium::BridgeError> for Failure {
    fn from(e: medium::BridgeError) -> Failure {
        Failure::error(e)
    }
}
