//! One error type for the library: every message is a single line that names what was wrong
//! (and, for files, which file).

use std::path::{Path, PathBuf};

#[derive(Debug)]
pub enum Error {
    /// A file could not be used: which file, and why.
    File { path: PathBuf, problem: String },
    /// An argument or option is out of its domain.
    Invalid(String),
}

impl Error {
    pub fn file(path: impl AsRef<Path>, problem: impl Into<String>) -> Self {
        Error::File {
            path: path.as_ref().to_path_buf(),
            problem: one_line(problem.into()),
        }
    }
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(one_line(msg.into()))
    }
}

fn one_line(s: String) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Error::File { path, problem } => write!(f, "{}: {}", path.display(), problem),
            Error::Invalid(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;
