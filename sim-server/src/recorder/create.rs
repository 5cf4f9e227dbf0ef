//! Why a recording could not start, in words that name the path and the
//! real cause: the MCAP writer's own I/O error says only "I/O error from
//! writing, or reading a compression stream", so the file is created here
//! first and a failure is told as the file system's reason.

use std::fs::File;
use std::io;
use std::path::Path;

/// The longest file name (one path component) Linux file systems take, bytes.
const NAME_MAX: usize = 255;

/// Why the recorder could not start; the client gets it as the refusal's
/// message.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The file could not be created.
    #[error("cannot create {path}: {cause}")]
    Create {
        /// The path asked for.
        path: String,
        /// Why.
        cause: CreateCause,
    },
    /// The file was created but its header could not be written.
    #[error("cannot write the header of {path}: {}", describe(error))]
    Header {
        /// The file.
        path: String,
        /// What the MCAP writer said.
        error: mcap::McapError,
    },
    /// The writer thread could not start.
    #[error("cannot start the recorder thread: {0}")]
    Thread(io::Error),
}

/// Why a file could not be created, told from the file system's error and
/// a look at the path.
#[derive(Debug)]
pub enum CreateCause {
    /// Its directory does not exist.
    NoDirectory(String),
    /// A part of the path is a file, not a directory.
    NotADirectory(String),
    /// The path is a directory.
    IsADirectory,
    /// This server may not create files in the directory.
    PermissionDenied(String),
    /// A name in the path is longer than a file system takes.
    NameTooLong {
        /// The name (its start).
        name: String,
        /// Its length, bytes.
        bytes: usize,
    },
    /// The directory is on a read-only file system.
    ReadOnly(String),
    /// The directory exists but takes no new files (`/proc`, `/sys`).
    NoNewFiles(String),
    /// Anything else, as the file system said it.
    Other(io::Error),
}

impl std::fmt::Display for CreateCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoDirectory(dir) => write!(f, "no such directory: {dir}"),
            Self::NotADirectory(file) => write!(f, "{file} is a file, not a directory"),
            Self::IsADirectory => f.write_str("it is a directory; name a file in it"),
            Self::PermissionDenied(dir) => {
                write!(
                    f,
                    "permission denied: the server may not create files in {dir}"
                )
            }
            Self::NameTooLong { name, bytes } => write!(
                f,
                "the name {name}… is {bytes} bytes long; a file name may have at most {NAME_MAX}"
            ),
            Self::ReadOnly(dir) => write!(f, "{dir} is on a read-only file system"),
            Self::NoNewFiles(dir) => write!(f, "{dir} does not take new files"),
            Self::Other(e) => write!(f, "{e}"),
        }
    }
}

/// An MCAP writer's error with its I/O cause spelled out.
pub(crate) fn describe(error: &mcap::McapError) -> String {
    match error {
        mcap::McapError::Io(e) => e.to_string(),
        e => e.to_string(),
    }
}

/// Creates (or truncates) the file at `path`, or says why it cannot.
pub(crate) fn create_file(path: &str) -> Result<File, StartError> {
    File::create(path).map_err(|error| StartError::Create {
        path: path.to_string(),
        cause: cause(Path::new(path), error),
    })
}

/// Why creating `path` failed with `error`.
fn cause(path: &Path, error: io::Error) -> CreateCause {
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let shown = dir.display().to_string();
    let long_name = || {
        path.components()
            .map(|c| c.as_os_str().to_string_lossy())
            .find(|name| name.len() > NAME_MAX)
            .map(|name| CreateCause::NameTooLong {
                bytes: name.len(),
                name: name.chars().take(24).collect(),
            })
    };
    match error.kind() {
        io::ErrorKind::IsADirectory => CreateCause::IsADirectory,
        io::ErrorKind::InvalidFilename => long_name().unwrap_or(CreateCause::Other(error)),
        io::ErrorKind::PermissionDenied => CreateCause::PermissionDenied(shown),
        io::ErrorKind::ReadOnlyFilesystem => CreateCause::ReadOnly(shown),
        io::ErrorKind::NotADirectory => match first_file(dir) {
            Some(file) => CreateCause::NotADirectory(file),
            None => CreateCause::Other(error),
        },
        io::ErrorKind::NotFound => match std::fs::metadata(dir) {
            Ok(meta) if meta.is_dir() => CreateCause::NoNewFiles(shown),
            Ok(_) => CreateCause::NotADirectory(shown),
            Err(_) => match first_file(dir) {
                Some(file) => CreateCause::NotADirectory(file),
                None => CreateCause::NoDirectory(shown),
            },
        },
        _ => CreateCause::Other(error),
    }
}

/// The first ancestor of `dir` (or `dir` itself) that exists and is not a
/// directory.
fn first_file(dir: &Path) -> Option<String> {
    let mut ancestors: Vec<&Path> = dir.ancestors().collect();
    ancestors.reverse();
    ancestors
        .into_iter()
        .find(|p| std::fs::metadata(p).is_ok_and(|m| !m.is_dir()))
        .map(|p| p.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(path: &str) -> String {
        match create_file(path) {
            Ok(_) => panic!("{path} was created"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn each_failure_names_the_path_and_its_real_cause() {
        let dir = std::env::temp_dir().join(format!("simbus-create-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let dir_text = dir.display().to_string();
        let file = dir.join("plain");
        std::fs::write(&file, b"x").unwrap();
        let file_text = file.display().to_string();

        let missing = format!("{dir_text}/nonexistdir/x.mcap");
        assert_eq!(
            message(&missing),
            format!("cannot create {missing}: no such directory: {dir_text}/nonexistdir")
        );
        assert_eq!(
            message(&dir_text),
            format!("cannot create {dir_text}: it is a directory; name a file in it")
        );
        let under_file = format!("{file_text}/x.mcap");
        assert_eq!(
            message(&under_file),
            format!("cannot create {under_file}: {file_text} is a file, not a directory")
        );
        let long = format!("{dir_text}/{}.mcap", "n".repeat(300));
        let said = message(&long);
        assert!(
            said.starts_with(&format!("cannot create {long}: the name nnnn")),
            "{said}"
        );
        assert!(
            said.ends_with("is 305 bytes long; a file name may have at most 255"),
            "{said}"
        );
        assert_eq!(
            message("/proc/x.mcap"),
            "cannot create /proc/x.mcap: /proc does not take new files"
        );
        // sysfs refuses new files to root too.
        assert_eq!(
            message("/sys/x.mcap"),
            "cannot create /sys/x.mcap: permission denied: the server may not create files in /sys"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
