//! Errors reported by the scene loaders.

use std::fmt;

/// At most this many characters of file text are shown in a message.
const SHOWN_CHARS: usize = 80;

/// File text (a line, a token, a name) for an error message: invalid UTF-8 is replaced, control
/// characters are escaped (`\t`, `\u{1b}`), and text longer than [`SHOWN_CHARS`] characters is
/// cut, ending in `…`.
pub(crate) fn show(text: impl AsRef<[u8]>) -> String {
    let bytes = text.as_ref();
    let head = &bytes[..bytes.len().min(4 * SHOWN_CHARS)];
    let head_text = String::from_utf8_lossy(head);
    let mut chars = head_text.chars();
    let mut shown = String::new();
    for c in chars.by_ref().take(SHOWN_CHARS) {
        if c.is_control() {
            shown.extend(c.escape_default());
        } else {
            shown.push(c);
        }
    }
    if chars.next().is_some() || head.len() < bytes.len() {
        shown.push('…');
    }
    shown
}

/// The extensions of the formats the loaders read, for messages.
pub const FORMATS: &str = ".ply, .obj, .pcd, .las, .laz, .copc.laz, .e57, .xyz, .txt, .pts, .csv";

/// Where in a file a problem was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number of a text file.
    Line(usize),
    /// Byte offset into a binary file (or the binary part of a file).
    ByteOffset(u64),
    /// The position is not known (reported by a third-party parser, or a whole-file check).
    Unknown,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}: "),
            Location::ByteOffset(n) => write!(f, "byte offset {n}: "),
            Location::Unknown => Ok(()),
        }
    }
}

/// A failure to load a scene file. The message always starts with the file name, then the
/// location when known, then what was expected and what was found (for [`LoadError::Io`], the
/// cause is the `source()`).
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read. The operating system's reason is the error's `source()`
    /// (not repeated in this message, so a report that prints the chain shows it once).
    #[error("{file}: cannot read file")]
    Io {
        /// The file, as given by the caller.
        file: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The extension does not name a supported format.
    #[error("{file}: unsupported file type {extension:?}; expected one of {FORMATS}")]
    UnknownFormat {
        /// The file, as given by the caller.
        file: String,
        /// The extension that was found (empty when there is none).
        extension: String,
    },
    /// The path names a directory, not a file.
    #[error("{file}: is a directory; expected a point-cloud file ({FORMATS})")]
    Directory {
        /// The directory, as given by the caller.
        file: String,
    },
    /// The content does not match the format.
    #[error("{file}: {location}{message}")]
    Parse {
        /// The file, as given by the caller.
        file: String,
        /// Where the problem was found.
        location: Location,
        /// What was expected and what was found.
        message: String,
    },
}

impl LoadError {
    /// A parse error at `location` in `file`.
    pub fn parse(file: &str, location: Location, message: impl Into<String>) -> Self {
        LoadError::Parse {
            file: file.to_owned(),
            location,
            message: message.into(),
        }
    }

    /// A parse error on 1-based text line `line`.
    pub fn at_line(file: &str, line: usize, message: impl Into<String>) -> Self {
        Self::parse(file, Location::Line(line), message)
    }

    /// A parse error at byte `offset` of a binary file.
    pub fn at_byte(file: &str, offset: usize, message: impl Into<String>) -> Self {
        Self::parse(file, Location::ByteOffset(offset as u64), message)
    }

    /// A parse error without a known location.
    pub fn whole(file: &str, message: impl Into<String>) -> Self {
        Self::parse(file, Location::Unknown, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn show_escapes_control_characters_and_bounds_length() {
        assert_eq!(show("plain text"), "plain text");
        assert_eq!(
            show(b"a\tb\x1b[31mc\r\n\x00"),
            "a\\tb\\u{1b}[31mc\\r\\n\\u{0}"
        );
        assert_eq!(show(b"bad \xff utf-8"), "bad \u{fffd} utf-8");
        let long = "x".repeat(200);
        assert_eq!(show(&long), format!("{}…", "x".repeat(SHOWN_CHARS)));
        assert_eq!(show("x".repeat(SHOWN_CHARS)), "x".repeat(SHOWN_CHARS));
    }
}
