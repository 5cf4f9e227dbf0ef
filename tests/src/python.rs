//! A Python virtual environment for the tests that check simbus's output
//! with tools simbus did not write (the `mcap` reader from PyPI, CARLA's
//! own client library and pytest for the gateway, the Foxglove protocol's
//! `websockets` and `protobuf`, Zenoh's Python API and `rosbags`' ROS 2
//! CDR decoder for the Zenoh bridge). It is
//! created once per target directory, under a lock, with pinned packages;
//! nothing is assumed installed but `python3`.

use std::path::PathBuf;
use std::process::Command;

/// The pinned packages the Python checks use.
pub const PYTHON_REQUIREMENTS: &[&str] = &[
    "mcap==1.2.2",
    "zstandard==0.25.0",
    "lz4==4.4.5",
    "carla==0.9.16",
    "pytest==8.3.4",
    "iniconfig==2.3.1",
    "packaging==26.3",
    "pluggy==1.7.0",
    "msgpack==1.1.0",
    "websockets==15.0.1",
    "protobuf==5.29.5",
    "eclipse-zenoh==1.10.2",
    "rosbags==0.11.9",
    "apsw==3.54.1.0",
    "backports.zstd==1.8.0",
    "numpy==2.4.6",
    "ruamel.yaml==0.19.1",
    "typing_extensions==4.16.0",
];

/// The venv's `python`, creating the venv on first use (every test
/// process shares it; a lock file keeps two from building it at once).
pub fn python() -> PathBuf {
    let target = crate::bin("sim-client")
        .parent()
        .and_then(|profile| profile.parent())
        .expect("target/<profile>/sim-client")
        .to_path_buf();
    let venv = target.join("simbus-venv");
    let python = venv.join("bin").join("python");
    let marker = venv.join("simbus-requirements.txt");
    let wanted = PYTHON_REQUIREMENTS.join("\n");
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
    if std::fs::read_to_string(&marker).ok().as_deref() == Some(wanted.as_str()) && python.exists()
    {
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
        ])
        .args(PYTHON_REQUIREMENTS));
    std::fs::write(&marker, wanted).expect("venv marker");
    python
}
