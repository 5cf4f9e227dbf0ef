//! A small or read-only disk for a test: a tmpfs it mounts (the tests run
//! as root), unmounted when dropped.

use std::path::PathBuf;
use std::process::Command;

/// A tmpfs mounted at a path (the tests run as root), unmounted on drop:
/// a small or read-only disk for the tests of what a full or read-only
/// file system does.
#[derive(Debug)]
pub struct Tmpfs(pub PathBuf);

impl Tmpfs {
    /// A tmpfs of `size` (`mount`'s `size=` option, e.g. `2m`) at `path`.
    pub fn mount(path: PathBuf, size: &str) -> Self {
        Self::with_options(path, &format!("size={size}"))
    }

    /// A read-only tmpfs at `path`.
    pub fn read_only(path: PathBuf) -> Self {
        Self::with_options(path, "ro,size=1m")
    }

    fn with_options(path: PathBuf, options: &str) -> Self {
        std::fs::create_dir_all(&path).unwrap();
        let status = Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs"])
            .arg(&path)
            .status()
            .expect("running mount");
        assert!(status.success(), "mounting a tmpfs needs root");
        Self(path)
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}
