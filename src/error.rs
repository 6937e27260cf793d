//! The command's error kinds: usage errors (exit status 2) and the one-line rendering of any
//! error chain.

use std::fmt;

/// An invalid argument: reported like clap's own errors, with exit status 2.
#[derive(Debug)]
pub struct UsageError(pub String);

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// A [`UsageError`] with a formatted message.
macro_rules! usage {
    ($($arg:tt)*) => {
        $crate::error::UsageError(format!($($arg)*))
    };
}

/// The error chain as one line. Library errors already name their file and often repeat their
/// source's message, so a cause whose text is already there is left out.
pub fn one_line(err: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    message.replace(['\r', '\n'], " ")
}
