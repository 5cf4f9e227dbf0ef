//! The book's determinism recipe (docs/src/time-and-sync.md) passes as
//! pasted: two server processes,
//! each with the seeded autopilot and a `watch --digest --lockstep`, ticked
//! 1000 frames by an unpaced ticker, print identical digest files with every
//! frame, none missed. (It failed before: an unpaced ticker outran the
//! watcher, which silently dropped frames.)
//!
//! The README's sample of the demo's output is what the demo prints: the
//! same line formats, the same first frame and the same cadence (it had
//! drifted: a sample from frame 1 with a line at frame 175, while the demo
//! starts at frame 0 and prints every 25 frames).

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::Duration;

use simbus_tests::{bin, unique_world, ChildGuard};

/// The shell block that follows `marker` in `doc`, a path from the
/// repository's root.
fn doc_block(doc: &str, marker: &str) -> String {
    doc_fenced(doc, marker, "sh")
}

/// The ```` ```language ```` block that follows `marker` in the README.
fn readme_fenced(marker: &str, language: &str) -> String {
    doc_fenced("README.md", marker, language)
}

/// The ```` ```language ```` block that follows `marker` in `doc`.
fn doc_fenced(doc: &str, marker: &str, language: &str) -> String {
    let path = format!("{}/../{doc}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let after = &text[text
        .find(marker)
        .unwrap_or_else(|| panic!("{marker} in {doc}"))..];
    let fence = format!("```{language}\n");
    let start = after
        .find(&fence)
        .unwrap_or_else(|| panic!("a {fence} block after the marker"))
        + fence.len();
    let end = after[start..].find("```").expect("the block ends") + start;
    after[start..end].to_owned()
}

/// A line's shape: every number (sign, digits, decimals) as `N`, every run
/// of spaces as one.
fn shape(line: &str) -> String {
    let mut out = String::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        let signed = c == '-' && chars.peek().is_some_and(char::is_ascii_digit);
        if c.is_ascii_digit() || signed {
            while chars.next_if(|c| c.is_ascii_digit() || *c == '.').is_some() {}
            out.push('N');
        } else if c == ' ' {
            while chars.next_if_eq(&' ').is_some() {}
            out.push(' ');
        } else {
            out.push(c);
        }
    }
    out
}

/// A demo summary line's time and frame, as printed: `t =   0.50 s  frame    25`.
fn time_and_frame(line: &str) -> &str {
    let end = line
        .find("  moving")
        .unwrap_or_else(|| panic!("a summary line: {line}"));
    &line[..end]
}

/// A demo summary line's frame id.
fn frame_of(line: &str) -> u64 {
    let (_, frame) = time_and_frame(line)
        .split_once("frame")
        .unwrap_or_else(|| panic!("a frame in {line}"));
    frame.trim().parse().expect("a frame id")
}

#[test]
fn the_demo_prints_what_the_readme_shows() {
    let sample = readme_fenced("<!-- demo-output", "text");
    let mut sample = sample.lines();
    assert_eq!(sample.next(), Some("$ ./target/release/sim-client demo"));
    let sample: Vec<&str> = sample.collect();
    let gap = sample
        .iter()
        .position(|l| *l == "...")
        .expect("a `...` line in the sample");
    let (head, tail) = (&sample[..gap], &sample[gap + 1..]);
    assert!(head.len() >= 3, "the first line and some summary lines");
    assert_eq!(tail.len(), 1, "the last line after `...`");

    // The demo as the README runs it: its own world, 300 frames.
    let demo = simbus_tests::Proc::spawn("sim-client", &["demo"]).finish(Duration::from_secs(120));
    demo.assert_success();
    let real = &demo.stdout;
    assert!(real.len() > head.len() + 1, "{demo}");
    let summaries = &real[1..real.len() - 1];

    // The same line formats.
    assert_eq!(shape(head[0]), shape(&real[0]), "{demo}");
    for (i, (sample, real)) in head[1..].iter().zip(summaries).enumerate() {
        assert_eq!(shape(sample), shape(real), "{demo}");
        // The same cadence: time and frame as printed. The first line is the
        // first frame the demo received: frame 0, or a later one when the
        // server stepped before the demo subscribed.
        if i > 0 {
            assert_eq!(time_and_frame(sample), time_and_frame(real), "{demo}");
        }
    }
    assert_eq!(shape(tail[0]), shape(&real[real.len() - 1]), "{demo}");
    assert!(
        real[real.len() - 1].starts_with("demo finished: watched 300 frames ("),
        "{demo}"
    );
    // And the cadence holds throughout: a line every 25
    // frames (0.5 s at the default step of 0.02 s).
    let frames: Vec<u64> = summaries.iter().map(|l| frame_of(l)).collect();
    assert!(frames[0] < 25, "the first frame received: {demo}");
    // 300 frames in order from the first: a line at every 25th.
    assert_eq!(
        frames[1..],
        (25..frames[0] + 300).step_by(25).collect::<Vec<u64>>(),
        "{demo}"
    );
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

/// Runs `script` with bash in `dir`, the built binaries first on PATH, in
/// a process group of its own that is killed once it ends; its status,
/// stdout and stderr.
fn run_script(script: &str, dir: &std::path::Path) -> (std::process::ExitStatus, String, String) {
    let bin_dir = bin("sim-server").parent().unwrap().to_path_buf();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut command = Command::new("bash");
    command
        .arg("-c")
        .arg(script)
        .current_dir(dir)
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
    (status, stdout, stderr)
}

#[test]
fn the_determinism_recipe_passes_as_pasted() {
    let script = doc_block("docs/src/time-and-sync.md", "<!-- determinism-recipe -->");
    assert!(script.contains("watch --digest"), "{script}");
    // Unique world names, so parallel runs never meet.
    let (a, b) = (unique_world("recipe-a"), unique_world("recipe-b"));
    let script = script.replace("run-a", &a).replace("run-b", &b);
    let dir = std::env::temp_dir().join(format!("simbus-recipe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (status, stdout, stderr) = run_script(&script, &dir);
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

/// Issue 44, item 14: the README's Rust example gives the world back as it
/// found it before releasing the ticker, and says why; its calls, run on a
/// world, leave it running for the tour's next `watch` (the example ended
/// with a bare `ticker.release()`, which leaves the world synchronous and
/// nobody ticking it).
#[test]
fn the_readmes_rust_example_leaves_the_world_as_it_found_it() {
    let example = readme_fenced("**From Rust**", "rust,no_run");
    let restore = example
        .find("ticker.apply_settings(before)?;")
        .unwrap_or_else(|| panic!("the example puts the settings back:\n{example}"));
    let release = example.find("ticker.release()?;").expect("it releases");
    assert!(restore < release, "{example}");
    assert!(example.contains("stays synchronous"), "{example}");

    // The example's calls on a fresh world.
    let world = simbus_tests::TestWorld::start("readme-rust", &[]);
    let wait = Duration::from_secs(10);
    let client = sim_client::Client::connect(world.name(), wait).unwrap();
    let car = client
        .spawn_actor(shared_types::Command::spawn_vehicle([0.0, 1.0, 0.0]))
        .unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let before = client.get_settings().unwrap();
    ticker
        .apply_settings(shared_types::WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.05),
            ..before
        })
        .unwrap();
    client
        .apply_batch(&[shared_types::Command::vehicle_control(
            car, 0.8, 0.0, 0.0, false,
        )])
        .unwrap();
    ticker.tick(wait).unwrap();
    ticker.apply_settings(before).unwrap();
    ticker.release().unwrap();
    // The tour's next command sees frames.
    let watched = world.cli(&["watch", "--frames", "3", "--json"]);
    watched.assert_success();
    assert_eq!(watched.json().len(), 3, "{watched}");
}

/// Issue 44, item 15: the Zenoh chapter's one-host recipe (the mirror in an
/// iceoryx2 root of its own, `SIMBUS_IOX2_CONFIG`) works as pasted: the
/// ticker on the mirror's side ticks the server's world.
#[test]
fn the_zenoh_one_host_recipe_ticks_through_the_mirror_as_pasted() {
    let script = doc_block("docs/src/two-machines.md", "<!-- zenoh-one-host -->");
    assert!(script.contains("SIMBUS_IOX2_CONFIG"), "{script}");
    let world = unique_world("zenoh-one-host");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    // The recipe's root, made this test's own (its shared memory goes
    // with it).
    let root = simbus_tests::PrivateRoot::new("onehost");
    let script = script
        .replace("--world W", &format!("--world {world}"))
        .replace(":7447", &format!(":{port}"))
        .replace(
            "/tmp/simbus-mirror/",
            &format!("{}/", root.directory().display()),
        )
        .replace("iox2_mirror_", root.prefix());
    let dir = simbus_tests::Scratch::new("zenoh-one-host");
    let (status, stdout, stderr) = run_script(&script, dir.path());
    let last: serde_json::Value =
        serde_json::from_str(stdout.trim_end().lines().last().unwrap_or("null"))
            .unwrap_or_else(|e| panic!("{e}: {status}\n{stdout}\n{stderr}"));
    assert_eq!(last["frame"], 100, "{status}\n{stdout}\n{stderr}");
}
