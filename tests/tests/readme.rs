//! The README's determinism recipe passes as pasted: two server processes,
//! each with the seeded autopilot and a `watch --digest --lockstep`, ticked
//! 1000 frames by an unpaced ticker, print identical digest files with every
//! frame, none missed. (It failed before: an unpaced ticker outran the
//! watcher, which silently dropped frames.)

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::Duration;

use simbus_tests::{bin, unique_world, ChildGuard};

/// The shell block that follows `marker` in the README.
fn readme_block(marker: &str) -> String {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md"))
        .expect("README.md");
    let after = &readme[readme.find(marker).expect("marker in README")..];
    let start = after
        .find("```sh\n")
        .expect("a ```sh block after the marker")
        + 6;
    let end = after[start..].find("```").expect("the block ends") + start;
    after[start..end].to_owned()
}

/// Kills the whole process group of the script (the servers and clients it
/// started in the background) and reaps the shell, whatever happened.
struct Group(ChildGuard);

impl Drop for Group {
    fn drop(&mut self) {
        let pgid = self.0.id();
        let _ = simbus_tests::send_signal_to_group(pgid, libc::SIGKILL);
        let _ = self.0.kill();
    }
}

#[test]
fn the_determinism_recipe_passes_as_pasted() {
    let script = readme_block("<!-- determinism-recipe -->");
    assert!(script.contains("watch --digest"), "{script}");
    // Unique world names, so parallel runs never meet.
    let (a, b) = (unique_world("recipe-a"), unique_world("recipe-b"));
    let script = script.replace("run-a", &a).replace("run-b", &b);
    let dir = std::env::temp_dir().join(format!("simbus-recipe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bin_dir = bin("sim-server").parent().unwrap().to_path_buf();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut command = Command::new("bash");
    command
        .arg("-c")
        .arg(&script)
        .current_dir(&dir)
        .env("PATH", path)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // SAFETY: setpgid(2) is async-signal-safe; the closure allocates nothing.
    unsafe {
        command.pre_exec(|| {
            if libc::setpgid(0, 0) == 0 {
                Ok(())
            } else {
                Err(std::io::Error::last_os_error())
            }
        });
    }
    let mut child = command.spawn().expect("bash");
    // Read both pipes while the script runs, so a full pipe never stalls it.
    let read = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_string(&mut text);
            }
            text
        })
    };
    let out = read(child.stdout.take().map(|p| Box::new(p) as _));
    let err = read(child.stderr.take().map(|p| Box::new(p) as _));
    let mut group = Group(ChildGuard::new(child, Duration::from_secs(1)));
    let status = group
        .0
        .wait_timeout(Duration::from_secs(600))
        .unwrap()
        .expect("the recipe finished within 10 minutes");
    // The whole group is gone once the script ended (the recipe waits for
    // its own background jobs), so the pipes close.
    drop(group);
    let stdout = out.join().expect("stdout reader");
    let stderr = err.join().expect("stderr reader");
    assert!(status.success(), "{status}\n{stdout}\n{stderr}");
    assert_eq!(
        stdout.trim_end().lines().last(),
        Some("identical"),
        "{stdout}\n{stderr}"
    );
    for world in [&a, &b] {
        let digests = std::fs::read_to_string(dir.join(format!("{world}.digest"))).unwrap();
        let frames: Vec<u64> = digests
            .lines()
            .map(|line| {
                assert!(line.starts_with("frame "), "every line a frame: {line}");
                line.split(' ').nth(1).unwrap().parse().unwrap()
            })
            .collect();
        assert_eq!(
            frames,
            (0..=1000).collect::<Vec<_>>(),
            "every frame, once, in order"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
