//! Security posture: what a world puts in shared memory and in iceoryx2's
//! directory is its owner's alone — files 0600 or read-only to the owner,
//! directories closed to other users — so another user on the machine can
//! neither read frames and sensor data nor write into a world.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use simbus_tests::{bin, unique_world, ChildGuard, PrivateRoot};

/// Every file under `dir` (recursively) and its mode.
fn modes(dir: &Path, out: &mut Vec<(String, u32, bool)>) {
    for entry in std::fs::read_dir(dir).expect("reading the iceoryx2 root") {
        let entry = entry.expect("a directory entry");
        let meta = entry.metadata().expect("metadata");
        let mode = meta.permissions().mode() & 0o777;
        out.push((entry.path().display().to_string(), mode, meta.is_dir()));
        if meta.is_dir() {
            modes(&entry.path(), out);
        }
    }
}

#[test]
fn a_worlds_shared_memory_and_files_are_its_owners_alone() {
    let private = PrivateRoot::new("security");
    let root = private.directory();
    let world = unique_world("security");
    let run = |program: &str, args: &[&str]| {
        let mut command = Command::new(bin(program));
        command
            .args(["--world", world.as_str()])
            .args(args)
            .envs(private.env())
            .env("RUST_LOG", "warn")
            .stdin(Stdio::null());
        command
    };
    let server = run(
        "sim-server",
        &["--scene", "default", "--fixed-delta-seconds", "0.01"],
    )
    .stdout(Stdio::null())
    .stderr(Stdio::null())
    .spawn()
    .expect("sim-server");
    let _server = ChildGuard::new(server, Duration::from_secs(5));
    // A client that makes the server create sensor memory and reads frames.
    for args in [
        &[
            "--timeout",
            "20",
            "sensor",
            "spawn",
            "depth",
            "--size",
            "64,48",
        ][..],
        &["--timeout", "20", "watch", "--frames", "3"][..],
    ] {
        let out = run("sim-client", args).output().expect("sim-client");
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // Shared memory: the world's segments (frames, sensors, every port's
    // data and connections).
    let segments: Vec<_> = std::fs::read_dir("/dev/shm")
        .expect("/dev/shm")
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with(private.prefix())
        })
        .map(|e| {
            let mode = e.metadata().expect("metadata").permissions().mode() & 0o777;
            (e.file_name().to_string_lossy().into_owned(), mode)
        })
        .collect();
    assert!(
        segments.len() > 10,
        "the world's shared memory was not found: {segments:?}"
    );
    // The one exception is iceoryx2's own: its 16-byte counter of unique
    // ids (`…global_mgmt`), 0666 by iceoryx2's design, holds no world data.
    let open: Vec<_> = segments
        .iter()
        .filter(|(name, m)| m & 0o077 != 0 && !name.ends_with(".global_mgmt"))
        .collect();
    assert!(open.is_empty(), "segments other users may open: {open:?}");
    // iceoryx2's directory: node and service files, and their directories.
    let mut files = Vec::new();
    modes(&root, &mut files);
    assert!(!files.is_empty(), "nothing under {}", root.display());
    let open: Vec<_> = files
        .iter()
        .filter(|(_, mode, dir)| {
            if *dir {
                mode & 0o007 != 0
            } else {
                mode & 0o077 != 0
            }
        })
        .collect();
    assert!(open.is_empty(), "files other users may open: {open:?}");
}
