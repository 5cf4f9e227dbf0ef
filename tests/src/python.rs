//! A Python virtual environment for the tests that check simbus's output
//! with tools simbus did not write (the `mcap` reader from PyPI, CARLA's
//! own client library and pytest for the gateway, the Foxglove protocol's
//! `websockets` and `protobuf`, Zenoh's Python API and `rosbags`' ROS 2
//! CDR decoder for the Zenoh bridge). It is created once per target
//! directory (`target/simbus-venv`), under a lock, with the exact pins of
//! `tests/python/requirements.txt`, and made again whenever that file
//! changes; nothing is assumed installed but `python3`.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The file that pins every Python package the tests use:
/// `tests/python/requirements.txt`.
pub fn python_requirements() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("python")
        .join("requirements.txt")
}

/// The venv's `python`, creating the venv on first use and again when
/// [`python_requirements`] changed since it was made (every test process
/// shares it; a lock file keeps two from building it at once).
pub fn python() -> PathBuf {
    let target = crate::bin("sim-client")
        .parent()
        .and_then(|profile| profile.parent())
        .expect("target/<profile>/sim-client")
        .to_path_buf();
    let venv = target.join("simbus-venv");
    let python = venv.join("bin").join("python");
    // The stamp: the requirements the venv was made from, word for word.
    let stamp = venv.join("simbus-requirements.txt");
    let requirements = python_requirements();
    let wanted = std::fs::read_to_string(&requirements)
        .unwrap_or_else(|e| panic!("reading {}: {e}", requirements.display()));
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(target.join("simbus-venv.lock"))
        .expect("venv lock file");
    // SAFETY: flock(2) on a file descriptor this process owns; it is
    // released when `lock` is closed at the end of this function.
    let locked = unsafe { libc::flock(std::os::fd::AsRawFd::as_raw_fd(&lock), libc::LOCK_EX) };
    assert_eq!(
        locked,
        0,
        "locking the venv: {}",
        std::io::Error::last_os_error()
    );
    if std::fs::read_to_string(&stamp).ok().as_deref() == Some(wanted.as_str()) && python.exists() {
        return python;
    }
    let run = |command: &mut Command| {
        let output = command.output().expect("running python3");
        assert!(
            output.status.success(),
            "{command:?} failed: {}\n{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
    };
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
