//! The command line's error: a message for the user and the process exit code.

use std::fmt;

/// Exit code for bad input: an unreadable or invalid file, a bad option value.
pub const EXIT_INPUT: i32 = 1;
/// Exit code for bad command-line usage (as clap uses), or a bad `JELLO_SIMD`.
pub const EXIT_USAGE: i32 = 2;
/// Exit code for a simulation that blew up.
pub const EXIT_BLOW_UP: i32 = 3;
/// Exit code for a failed write.
pub const EXIT_IO: i32 = 4;

/// A failure to report on stderr before exiting with `code`.
#[derive(Debug)]
pub struct CliError {
    /// What happened, naming the file and line where there is one.
    pub message: String,
    /// Process exit code.
    pub code: i32,
}

impl CliError {
    /// Bad input (exit 1).
    pub fn input(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: EXIT_INPUT,
        }
    }

    /// Bad command-line usage (exit 2).
    pub fn usage(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: EXIT_USAGE,
        }
    }

    /// A blow-up (exit 3).
    pub fn blow_up(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: EXIT_BLOW_UP,
        }
    }

    /// A failed write (exit 4).
    pub fn io(message: impl Into<String>) -> Self {
        CliError {
            message: message.into(),
            code: EXIT_IO,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl From<jello_io::FileError> for CliError {
    fn from(e: jello_io::FileError) -> Self {
        match e.kind {
            jello_io::FileErrorKind::Input => CliError::input(e.message),
            jello_io::FileErrorKind::Write => CliError::io(e.message),
        }
    }
}
