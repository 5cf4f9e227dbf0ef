//! A Python virtual environment for the tests that check simbus's output
//! with tools simbus did not write (the `mcap` reader from PyPI, CARLA's
//! own client library and pytest for the gateway, the Foxglove protocol's
//! `websockets` and `protobuf`, Zenoh's Python API and `rosbags`' ROS 2
//! CDR decoder for the Zenoh bridge). It is created once per target
//! directory (`target/simbus-venv`), under a lock, with the exact pins of
//! `tests/python/requirements.txt`, and made again whenever that file
//! changes; nothing is assumed installed but `python3`.
//!
//! [`python_with_simbus`] also builds the `simbus` package from this
//! checkout (`sim-client/python`, with the pinned maturin, in the tests'
//! own cargo profile so it shares their artifacts) and installs it there.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The file that pins every Python package the tests use:
/// `tests/python/requirements.txt`.
pub fn python_requirements() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("python")
        .join("requirements.txt")
}

/// `target/`, where the binaries' profile directories are.
fn target_dir() -> PathBuf {
    crate::bin("sim-client")
        .parent()
        .and_then(|profile| profile.parent())
        .expect("target/<profile>/sim-client")
        .to_path_buf()
}

/// Runs `command`, panicking with its output when it fails.
fn run(command: &mut Command) -> String {
    let output = command.output().expect("running a Python tool");
    assert!(
        output.status.success(),
        "{command:?} failed: {}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Holds an exclusive `flock(2)` on `path` while it lives.
struct Locked {
    _file: std::fs::File,
}

impl Locked {
    fn new(path: &Path) -> Self {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .unwrap_or_else(|e| panic!("lock file {}: {e}", path.display()));
        // SAFETY: flock(2) on a file descriptor this process owns; it is
        // released when the file is closed.
        let locked = unsafe { libc::flock(std::os::fd::AsRawFd::as_raw_fd(&file), libc::LOCK_EX) };
        assert_eq!(
            locked,
            0,
            "locking {}: {}",
            path.display(),
            std::io::Error::last_os_error()
        );
        Self { _file: file }
    }
}

/// The venv's `python` (see [`python`]) with the `simbus` package built
/// from this checkout and installed, fresh: maturin builds the extension
/// in the profile of these tests' binaries (nothing to build when
/// nothing changed), and pip installs the wheel over the last one.
pub fn python_with_simbus() -> PathBuf {
    let python = python();
    let target = target_dir();
    let profile = crate::bin("sim-client")
        .parent()
        .and_then(|p| p.file_name())
        .map(|p| p.to_string_lossy().into_owned())
        .expect("target/<profile>");
    let profile = if profile == "debug" {
        "dev".to_owned()
    } else {
        profile
    };
    let _lock = Locked::new(&target.join("simbus-wheel.lock"));
    let wheels = target.join("simbus-wheels");
    let _ = std::fs::remove_dir_all(&wheels);
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../sim-client/python/Cargo.toml");
    let maturin = python.with_file_name("maturin");
    run(Command::new(&maturin)
        .args(["build", "--quiet", "--profile", &profile, "--manifest-path"])
        .arg(&manifest)
        .arg("--out")
        .arg(&wheels)
        .arg("--interpreter")
        .arg(&python));
    let wheel = std::fs::read_dir(&wheels)
        .expect("maturin's wheel directory")
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .find(|path| path.extension().is_some_and(|e| e == "whl"))
        .expect("maturin built no wheel");
    run(Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
        ])
        .args(["--force-reinstall", "--no-deps"])
        .arg(&wheel));
    python
}

/// The venv's `python`, creating the venv on first use and again when
/// [`python_requirements`] changed since it was made (every test process
/// shares it; a lock file keeps two from building it at once).
pub fn python() -> PathBuf {
    let target = target_dir();
    let venv = target.join("simbus-venv");
    let python = venv.join("bin").join("python");
    // The stamp: the requirements the venv was made from, word for word.
    let stamp = venv.join("simbus-requirements.txt");
    let requirements = python_requirements();
    let wanted = std::fs::read_to_string(&requirements)
        .unwrap_or_else(|e| panic!("reading {}: {e}", requirements.display()));
    let _lock = Locked::new(&target.join("simbus-venv.lock"));
    if std::fs::read_to_string(&stamp).ok().as_deref() == Some(wanted.as_str()) && python.exists() {
        return python;
    }
    let _ = std::fs::remove_dir_all(&venv);
    run(Command::new("python3").args(["-m", "venv"]).arg(&venv));
    run(Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "-r",
        ])
        .arg(&requirements));
    std::fs::write(&stamp, wanted).expect("venv stamp");
    python
}
