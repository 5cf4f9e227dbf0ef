//! Another user on the same machine: iceoryx2's shared directory belongs to
//! whoever ran an iceoryx2 program first (mode 0750), so a second user
//! cannot create a node at all. simbus says so, naming the directory and
//! the fix, and the documented fix — a per-user root path and prefix in an
//! iceoryx2 configuration named by `SIMBUS_IOX2_CONFIG` — works.
//!
//! Switching users needs root, as these machines run their tests.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use simbus_tests::{bin, server, unique_world, ChildGuard};

const NOBODY: u32 = 65534;

/// A copy of the binary `name` that user `nobody` may run.
fn runnable_copy(dir: &Path, name: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let to = dir.join(name);
    std::fs::copy(bin(name), &to).unwrap();
    std::fs::set_permissions(&to, std::fs::Permissions::from_mode(0o755)).unwrap();
    to
}

/// `program args` as user nobody, with `env`.
fn as_nobody(program: &Path, args: &[&str], env: &[(&str, &str)]) -> Command {
    let mut command = Command::new(program);
    command
        .args(args)
        .envs(env.iter().copied())
        .env("RUST_LOG", "warn")
        .current_dir("/")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // SAFETY: setgroups/setgid/setuid are async-signal-safe and the
    // closure allocates nothing.
    unsafe {
        command.pre_exec(|| {
            if libc::setgroups(0, std::ptr::null()) != 0
                || libc::setgid(NOBODY) != 0
                || libc::setuid(NOBODY) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    command
}

#[test]
fn another_user_gets_the_directory_and_the_fix_named_and_the_fix_works() {
    assert_eq!(
        // SAFETY: geteuid(2) has no preconditions.
        unsafe { libc::geteuid() },
        0,
        "this test switches to user nobody and needs root"
    );
    // A root server makes sure the root-owned shared directory exists.
    let world = unique_world("other-user");
    let _root_server = server(&world, &[]);
    let dir = std::env::temp_dir().join(format!("simbus-nobody-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let client = runnable_copy(&dir, "sim-client");
    let sim_server = runnable_copy(&dir, "sim-server");

    let out = as_nobody(
        &client,
        &["--world", &world, "--timeout", "1", "status"],
        &[],
    )
    .output()
    .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cannot use iceoryx2's shared directory /tmp/iceoryx2")
            && stderr.contains("owned by uid 0, mode 0750")
            && stderr.contains("SIMBUS_IOX2_CONFIG"),
        "{stderr}"
    );

    // The fix from the error and the README: a root path of one's own.
    let root = dir.join("iox2-root/");
    let config = dir.join("nobody.toml");
    std::fs::write(
        &config,
        format!(
            "[global]\nroot-path = \"{}/\"\nprefix = \"iox2_t{}_\"\n",
            root.display(),
            std::process::id()
        ),
    )
    .unwrap();
    std::fs::create_dir_all(&root).unwrap();
    std::os::unix::fs::chown(&root, Some(NOBODY), Some(NOBODY)).unwrap();
    let env = [("SIMBUS_IOX2_CONFIG", config.to_str().unwrap())];
    let own_server = as_nobody(&sim_server, &["--world", &world], &env)
        .spawn()
        .unwrap();
    let mut own_server = ChildGuard::new(own_server, Duration::from_secs(5));
    let out = as_nobody(
        &client,
        &["--world", &world, "--timeout", "10", "status", "--json"],
        &env,
    )
    .output()
    .unwrap();
    let stopped = own_server.stop().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    // iceoryx2 keeps one small management file per prefix in /dev/shm.
    let prefix = format!("iox2_t{}_", std::process::id());
    for entry in std::fs::read_dir("/dev/shm")
        .into_iter()
        .flatten()
        .flatten()
    {
        if entry.file_name().to_string_lossy().starts_with(&prefix) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let status: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(
        status["server_pid"].as_u64(),
        Some(u64::from(own_server.id())),
        "nobody's own server answered, not root's"
    );
    assert!(
        stopped.success(),
        "nobody's server stopped cleanly: {stopped}"
    );
}
