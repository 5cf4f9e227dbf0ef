//! A private iceoryx2 root per test ([`PrivateRoot`]), so that what a
//! test's processes leave in shared memory can be counted exactly.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};

use crate::{Proc, Scratch};

/// An iceoryx2 root of one test's own: a directory for iceoryx2's files and
/// a `/dev/shm` name prefix, written to a config file that the processes get
/// through `SIMBUS_IOX2_CONFIG`. What the test's processes leave behind can
/// then be counted exactly, whatever else runs on the machine. Removes its
/// shared memory on drop, even when the test fails.
#[derive(Debug)]
pub struct PrivateRoot {
    scratch: Scratch,
    prefix: String,
    config: PathBuf,
}

impl PrivateRoot {
    /// A fresh root for test `tag`.
    pub fn new(tag: &str) -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let scratch = Scratch::new(tag);
        let prefix = format!("iox2_{tag}{}x{n}_", std::process::id());
        let root = scratch.path().join("iox2");
        let config = scratch.write(
            "iox2.toml",
            format!(
                "[global]\nroot-path = \"{}/\"\nprefix = \"{prefix}\"\n",
                root.display()
            )
            .as_bytes(),
        );
        Self {
            scratch,
            prefix,
            config,
        }
    }

    /// The environment that puts a process in this root.
    pub fn env(&self) -> [(&'static str, &std::ffi::OsStr); 1] {
        [("SIMBUS_IOX2_CONFIG", self.config.as_os_str())]
    }

    /// The `/dev/shm` name prefix of this root.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// `sim-server --world <world> <args>` in this root.
    pub fn server(&self, world: &str, args: &[&str]) -> Proc {
        let mut all = vec!["--world", world];
        all.extend_from_slice(args);
        Proc::spawn_env("sim-server", &all, &self.env())
    }

    /// `sim-client --world <world> --timeout <timeout> <args>` in this
    /// root, started.
    pub fn client(&self, world: &str, timeout: &str, args: &[&str]) -> Proc {
        let mut all = vec!["--world", world, "--timeout", timeout];
        all.extend_from_slice(args);
        Proc::spawn_env("sim-client", &all, &self.env())
    }

    /// iceoryx2's directory of this root.
    pub fn directory(&self) -> PathBuf {
        self.scratch.path().join("iox2")
    }

    /// The `/dev/shm` files of this root, but iceoryx2's global id counter
    /// (`…global_mgmt`, shared by every process of a root by design).
    pub fn shared_memory(&self) -> Vec<String> {
        std::fs::read_dir("/dev/shm")
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|name| name.starts_with(&self.prefix) && !name.ends_with(".global_mgmt"))
            .collect()
    }

    /// Every file under this root's iceoryx2 directory (nodes, services).
    pub fn files(&self) -> Vec<String> {
        fn walk(dir: &std::path::Path, out: &mut Vec<String>) {
            for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
                let path = entry.path();
                if path.is_dir() {
                    walk(&path, out);
                } else {
                    out.push(path.display().to_string());
                }
            }
        }
        let mut out = Vec::new();
        walk(&self.directory(), &mut out);
        out
    }
}

impl Drop for PrivateRoot {
    fn drop(&mut self) {
        for entry in std::fs::read_dir("/dev/shm")
            .into_iter()
            .flatten()
            .flatten()
        {
            if entry
                .file_name()
                .to_string_lossy()
                .starts_with(&self.prefix)
            {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
}
