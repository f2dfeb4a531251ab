//! The library's error type: every failure a user can cause, with the place
//! in the input that caused it.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A position in a source file (1-based line and column).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceLoc {
    /// The file, as the user named it.
    pub file: Arc<Path>,
    /// Line, from 1.
    pub line: u32,
    /// Column in characters, from 1.
    pub column: u32,
}

impl SourceLoc {
    /// The location of byte `offset` in `text`, which was read from `file`.
    pub fn from_offset(file: &Arc<Path>, text: &str, offset: usize) -> SourceLoc {
        let offset = offset.min(text.len());
        let before = &text[..floor_char_boundary(text, offset)];
        let line = before.matches('\n').count() as u32 + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = before[line_start..].chars().count() as u32 + 1;
        SourceLoc {
            file: file.clone(),
            line,
            column,
        }
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

impl fmt::Display for SourceLoc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.column)
    }
}

/// Everything that can go wrong between a scene file and an image.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A problem in a scene description, with where it is and which key.
    #[error("{}", format_scene_error(.loc, .key, .message))]
    Scene {
        /// Where in which file, if the scene came from a file.
        loc: Option<SourceLoc>,
        /// The offending key (e.g. `shape[2].radius`), if one is to blame.
        key: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{}: {message}", .path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// An option or argument has an unusable value.
    #[error("{0}")]
    Invalid(String),
    /// An error that stopped a load, with the warnings given before it,
    /// so that one run can report every problem it found (the command line
    /// prints them, then the error). Its message is the error's.
    #[error("{error}")]
    WithWarnings {
        /// The error.
        error: Box<Error>,
        /// The warnings given before it, in order.
        warnings: Vec<String>,
    },
}

fn format_scene_error(loc: &Option<SourceLoc>, key: &Option<String>, message: &str) -> String {
    let mut s = String::new();
    if let Some(l) = loc {
        s.push_str(&format!("{l}: "));
    }
    if let Some(k) = key {
        s.push_str(&format!("`{k}`: "));
    }
    s.push_str(message);
    s
}

impl Error {
    /// A scene error at `loc` about `key`.
    pub fn scene(loc: Option<SourceLoc>, key: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Scene {
            loc,
            key: Some(key.into()),
            message: message.into(),
        }
    }

    /// A file error.
    pub fn file(path: impl AsRef<Path>, message: impl fmt::Display) -> Error {
        Error::File {
            path: path.as_ref().to_path_buf(),
            message: message.to_string(),
        }
    }

    /// This error with `earlier` — warnings given before it — ahead of any
    /// it already carries.
    pub fn with_warnings(self, mut earlier: Vec<String>) -> Error {
        if earlier.is_empty() {
            return self;
        }
        let (error, later) = self.into_parts();
        earlier.extend(later);
        Error::WithWarnings {
            error: Box::new(error),
            warnings: earlier,
        }
    }

    /// The warnings given before this error (none for most errors).
    pub fn warnings(&self) -> &[String] {
        match self {
            Error::WithWarnings { warnings, .. } => warnings,
            _ => &[],
        }
    }

    /// The error itself and the warnings given before it.
    pub fn into_parts(self) -> (Error, Vec<String>) {
        match self {
            Error::WithWarnings { error, warnings } => (*error, warnings),
            error => (error, Vec::new()),
        }
    }
}

/// `Result` with the library's error.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_become_lines_and_columns() {
        let f: Arc<Path> = Arc::from(Path::new("a.toml"));
        let text = "x = 1\ny = é2\n";
        let l = SourceLoc::from_offset(&f, text, 0);
        assert_eq!((l.line, l.column), (1, 1));
        let l = SourceLoc::from_offset(&f, text, text.find('2').unwrap());
        assert_eq!((l.line, l.column), (2, 6));
        assert_eq!(l.to_string(), "a.toml:2:6");
    }

    #[test]
    fn warnings_travel_with_an_error_in_order_without_changing_its_message() {
        let e = Error::Invalid("bad".into());
        assert!(matches!(e.with_warnings(Vec::new()), Error::Invalid(_)));
        let e = Error::Invalid("bad".into())
            .with_warnings(vec!["second".into()])
            .with_warnings(vec!["first".into()]);
        assert_eq!(e.to_string(), "bad");
        assert_eq!(e.warnings(), ["first", "second"]);
        let (inner, warnings) = e.into_parts();
        assert!(matches!(inner, Error::Invalid(_)));
        assert_eq!(warnings.len(), 2);
    }

    #[test]
    fn scene_errors_name_place_and_key() {
        let f: Arc<Path> = Arc::from(Path::new("s.toml"));
        let e = Error::scene(
            Some(SourceLoc {
                file: f,
                line: 3,
                column: 10,
            }),
            "shape[0].radius",
            "must be positive, got -1",
        );
        assert_eq!(
            e.to_string(),
            "s.toml:3:10: `shape[0].radius`: must be positive, got -1"
        );
    }
}
