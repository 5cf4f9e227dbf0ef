//! Chaos: a synchronous world keeps its promises while its clients are
//! killed, stopped and restarted at random.
//!
//! One server; a ticker; 16 watchers; 2 lockstep participants; 4 readers of
//! an IMU. For the run's length a seeded schedule picks a client and
//! SIGKILLs it (and starts a new one in its place) or SIGSTOPs it for a
//! moment and SIGCONTs it, the ticker included. Asserted:
//!
//! - the server never stalls: a status request made every quarter second
//!   is answered within its timeout, however the clients behave;
//! - every watcher saw consecutive frames, none missed, and all agree on
//!   every frame's digest;
//! - each new ticker continued from the frame after the last one published
//!   (no frame skipped, none stepped twice), as a witness that is never
//!   touched sees;
//! - afterwards the world's shared memory and iceoryx2's node directory hold
//!   nothing of the dead (the processes run in an iceoryx2 root of the
//!   test's own, so everything in it is counted).
//!
//! The short variant runs in CI; `cargo test --test chaos -- --ignored` runs
//! the 30-second one.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simbus_tests::{send_signal, unique_world, PrivateRoot, Proc};

/// What a client is, so a killed one can be replaced by the same.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    Ticker,
    Watcher,
    Participant,
    SensorReader,
}

struct Member {
    role: Role,
    proc: Proc,
    /// Every stdout line, in order.
    lines: Vec<String>,
}

struct Chaos<'a> {
    root: &'a PrivateRoot,
    world: String,
    sensor: String,
    members: Vec<Member>,
    /// Lines of members that were killed and replaced.
    retired: Vec<(Role, Vec<String>)>,
}

impl Chaos<'_> {
    fn spawn(&self, role: Role) -> Proc {
        let args: &[&str] = match role {
            Role::Ticker => &[
                "tick",
                "--json",
                "--rate",
                "50",
                "--delta-seconds",
                "0.02",
                "--leave-sync",
            ],
            Role::Watcher => &["watch", "--digest"],
            Role::Participant => &["watch", "--digest", "--lockstep"],
            Role::SensorReader => &["sensor", "watch", self.sensor.as_str(), "--json"],
        };
        self.root.client(&self.world, "10", args)
    }

    /// Collects what every member printed so far.
    fn drain(&mut self) {
        for m in &mut self.members {
            while let Some(line) = m.proc.line(Duration::ZERO) {
                m.lines.push(line);
            }
        }
    }

    /// Starts a ticker and waits for its first tick; a claim refused while
    /// the server has not yet noticed the previous ticker's death is retried.
    fn start_ticker(&mut self) -> Member {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let proc = self.spawn(Role::Ticker);
            if let Some(first) = proc.line(Duration::from_secs(10)) {
                return Member {
                    role: Role::Ticker,
                    proc,
                    lines: vec![first],
                };
            }
            let finished = proc.finish(Duration::from_secs(5));
            assert!(
                Instant::now() < deadline,
                "no new ticker could take over within 10 s: {finished}"
            );
        }
    }
}

fn frames_of(lines: &[String]) -> Vec<(u64, Option<String>)> {
    lines
        .iter()
        .filter_map(|line| {
            if let Some(rest) = line.strip_prefix("frame ") {
                let mut it = rest.split(" digest ");
                let frame = it.next()?.parse().ok()?;
                Some((frame, it.next().map(str::to_owned)))
            } else {
                let json: serde_json::Value = serde_json::from_str(line).ok()?;
                Some((json["frame"].as_u64()?, None))
            }
        })
        .collect()
}

fn assert_consecutive(what: &str, frames: &[u64]) {
    for pair in frames.windows(2) {
        assert_eq!(
            pair[1],
            pair[0] + 1,
            "{what}: frame {} followed frame {} (frames {:?}..)",
            pair[1],
            pair[0],
            &frames[..frames.len().min(5)]
        );
    }
}

fn run_chaos(seed: u64, length: Duration) {
    let root = PrivateRoot::new("chaos");
    let world = unique_world("chaos");
    let mut server = root.server(
        &world,
        &[
            "--scene",
            "default",
            "--fixed-delta-seconds",
            "0.02",
            "--on-ticker-loss",
            "wait",
            "--lockstep-timeout",
            "1",
        ],
    );
    let cli = |args: &[&str]| {
        root.client(&world, "20", args)
            .finish(Duration::from_secs(30))
    };
    // Up and answering (the first request waits for the server's services).
    cli(&["status", "--json"]).assert_success();
    let spawned = cli(&["sensor", "spawn", "imu", "--json"]);
    spawned.assert_success();
    let sensor = spawned.json()[0]["id"]
        .as_u64()
        .expect("sensor id")
        .to_string();

    let mut chaos = Chaos {
        root: &root,
        world: world.clone(),
        sensor,
        members: Vec::new(),
        retired: Vec::new(),
    };
    // The world is synchronous from the first tick on: start watching then.
    let ticker = chaos.start_ticker();
    chaos.members.push(ticker);
    let witness = chaos.spawn(Role::Watcher);
    let mut witness = Member {
        role: Role::Watcher,
        proc: witness,
        lines: Vec::new(),
    };
    for (role, count) in [
        (Role::Watcher, 16),
        (Role::Participant, 2),
        (Role::SensorReader, 4),
    ] {
        for _ in 0..count {
            let proc = chaos.spawn(role);
            chaos.members.push(Member {
                role,
                proc,
                lines: Vec::new(),
            });
        }
    }

    // The liveness probe: a status request every quarter second, each
    // answered within its 2 s timeout (the lockstep timeout is 1 s).
    let (stop_probe, stopped) = mpsc::channel::<()>();
    let (root_ref, world_ref) = (&root, world.as_str());
    let probe = move || {
        let mut answered = 0u32;
        while let Err(mpsc::RecvTimeoutError::Timeout) =
            stopped.recv_timeout(Duration::from_millis(250))
        {
            let status = root_ref
                .client(world_ref, "2", &["status", "--json"])
                .finish(Duration::from_secs(30));
            assert!(
                status.status.success(),
                "the server did not answer a status request within 2 s: {status}"
            );
            answered += 1;
        }
        answered
    };
    let (answered, kills, stops, ticker_kills) = std::thread::scope(|scope| {
        let probe = scope.spawn(probe);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut kills, mut stops, mut ticker_kills) = (0, 0, 0);
        let end = Instant::now() + length;
        let pace = mpsc::channel::<()>();
        while Instant::now() < end {
            // The schedule's own pace: a random pause between two blows.
            let _ = pace
                .1
                .recv_timeout(Duration::from_millis(rng.random_range(30..150)));
            chaos.drain();
            while let Some(line) = witness.proc.line(Duration::ZERO) {
                witness.lines.push(line);
            }
            let victim = rng.random_range(0..chaos.members.len());
            let pid = chaos.members[victim].proc.pid();
            if rng.random_range(0..3) == 0 {
                // SIGKILL, and a new client of the same kind in its place.
                send_signal(pid, libc::SIGKILL).expect("SIGKILL");
                let role = chaos.members[victim].role;
                let mut dead = chaos.members.remove(victim);
                dead.proc.guard.wait_timeout(Duration::from_secs(5)).ok();
                while let Some(line) = dead.proc.line(Duration::from_millis(50)) {
                    dead.lines.push(line);
                }
                chaos.retired.push((role, dead.lines));
                let fresh = if role == Role::Ticker {
                    ticker_kills += 1;
                    chaos.start_ticker()
                } else {
                    Member {
                        role,
                        proc: chaos.spawn(role),
                        lines: Vec::new(),
                    }
                };
                chaos.members.push(fresh);
                kills += 1;
            } else {
                // SIGSTOP for a moment shorter than the watchers' 16 frames of
                // slack at 50 ticks a second, then SIGCONT.
                send_signal(pid, libc::SIGSTOP).expect("SIGSTOP");
                let _ = pace
                    .1
                    .recv_timeout(Duration::from_millis(rng.random_range(10..120)));
                send_signal(pid, libc::SIGCONT).expect("SIGCONT");
                stops += 1;
            }
        }
        // Make sure the last ticker is not left stopped (a SIGCONT to a running
        // process is harmless), then let every watcher see the last frames.
        for m in &chaos.members {
            let _ = send_signal(m.proc.pid(), libc::SIGCONT);
        }
        stop_probe.send(()).expect("stopping the probe");
        let answered = probe.join().expect("the liveness probe failed");
        (answered, kills, stops, ticker_kills)
    });
    assert!(answered > 0, "the liveness probe never ran");

    // Stop the ticker first and wait until the witness has its last frame.
    let ticker_at = chaos
        .members
        .iter()
        .position(|m| m.role == Role::Ticker)
        .expect("a ticker");
    let mut ticker = chaos.members.remove(ticker_at);
    send_signal(ticker.proc.pid(), libc::SIGKILL).expect("SIGKILL");
    ticker.proc.guard.wait_timeout(Duration::from_secs(5)).ok();
    while let Some(line) = ticker.proc.line(Duration::from_millis(50)) {
        ticker.lines.push(line);
    }
    chaos.retired.push((Role::Ticker, ticker.lines));
    let ticked: Vec<u64> = chaos
        .retired
        .iter()
        .filter(|(role, _)| *role == Role::Ticker)
        .flat_map(|(_, lines)| frames_of(lines).into_iter().map(|(f, _)| f))
        .collect();
    let last_ticked = *ticked.iter().max().expect("the tickers ticked");
    while witness
        .lines
        .last()
        .and_then(|l| frames_of(std::slice::from_ref(l)).first().map(|f| f.0))
        .is_none_or(|f| f < last_ticked)
    {
        let line = witness
            .proc
            .line(Duration::from_secs(10))
            .unwrap_or_else(|| panic!("the witness never saw frame {last_ticked}"));
        witness.lines.push(line);
    }
    for m in &mut chaos.members {
        send_signal(m.proc.pid(), libc::SIGKILL).expect("SIGKILL");
        m.proc.guard.wait_timeout(Duration::from_secs(5)).ok();
        while let Some(line) = m.proc.line(Duration::from_millis(50)) {
            m.lines.push(line);
        }
    }
    send_signal(witness.proc.pid(), libc::SIGKILL).expect("SIGKILL");
    let members = std::mem::take(&mut chaos.members);
    let mut everyone: Vec<(Role, Vec<String>)> = std::mem::take(&mut chaos.retired);
    everyone.extend(members.into_iter().map(|m| (m.role, m.lines)));

    // The witness saw every frame, consecutively; every frame a ticker
    // stepped was stepped once and published.
    let seen: Vec<(u64, Option<String>)> = frames_of(&witness.lines);
    let seen_frames: Vec<u64> = seen.iter().map(|f| f.0).collect();
    assert!(
        witness.lines.iter().all(|l| !l.starts_with("missed")),
        "the witness missed frames: {:?}",
        witness
            .lines
            .iter()
            .filter(|l| l.starts_with("missed"))
            .collect::<Vec<_>>()
    );
    assert_consecutive("the witness", &seen_frames);
    let mut once = BTreeSet::new();
    for frame in &ticked {
        assert!(once.insert(*frame), "frame {frame} was ticked twice");
    }
    let published: BTreeSet<u64> = seen_frames.iter().copied().collect();
    for frame in ticked.iter().filter(|&&f| f > seen_frames[0]) {
        assert!(
            published.contains(frame),
            "frame {frame} was ticked but never published"
        );
    }

    // Every watcher (killed or not) saw consecutive frames, and every
    // frame has one digest.
    let mut digests: BTreeMap<u64, String> = seen
        .iter()
        .filter_map(|(f, d)| d.clone().map(|d| (*f, d)))
        .collect();
    let mut watchers = 0;
    for (role, lines) in &everyone {
        if !matches!(role, Role::Watcher | Role::Participant) {
            continue;
        }
        watchers += 1;
        assert!(
            lines.iter().all(|l| !l.starts_with("missed")),
            "a {role:?} missed frames: {lines:?}"
        );
        let frames = frames_of(lines);
        let numbers: Vec<u64> = frames.iter().map(|f| f.0).collect();
        assert_consecutive(&format!("a {role:?}"), &numbers);
        for (frame, digest) in frames {
            if let Some(digest) = digest {
                let known = digests.entry(frame).or_insert_with(|| digest.clone());
                assert_eq!(*known, digest, "two digests for frame {frame}");
            }
        }
    }
    // Sensor readers: captures in frame order, none twice.
    for (_, lines) in everyone.iter().filter(|(r, _)| *r == Role::SensorReader) {
        let frames: Vec<u64> = frames_of(lines).into_iter().map(|f| f.0).collect();
        assert!(
            frames.windows(2).all(|w| w[1] > w[0]),
            "a sensor reader got captures out of order: {frames:?}"
        );
    }
    assert!(watchers >= 18, "only {watchers} watchers ran");
    eprintln!(
        "chaos seed {seed}: {} frames, {kills} kills ({ticker_kills} of the ticker), {stops} stops, {answered} status probes",
        seen_frames.len()
    );

    // Nothing of the dead is left once the server has swept and stopped.
    send_signal(server.pid(), libc::SIGTERM).expect("SIGTERM");
    let status = server.guard.wait_timeout(Duration::from_secs(10));
    assert!(
        matches!(status, Ok(Some(_))),
        "the server did not stop on SIGTERM: {}",
        server.stderr()
    );
    let left_shm = root.shared_memory();
    assert!(
        left_shm.is_empty(),
        "shared memory left behind: {left_shm:?}"
    );
    let left_files: Vec<String> = root
        .files()
        .into_iter()
        .filter(|f| f.contains("/nodes/") || f.contains("node"))
        .collect();
    assert!(
        left_files.is_empty(),
        "node files left behind: {left_files:?}"
    );
    drop(server);
}

#[test]
fn a_sync_world_survives_kills_and_stops_of_any_client() {
    run_chaos(0x5eed, Duration::from_secs(8));
}

#[test]
#[ignore = "30 s of chaos: run by bench/run-fault-suite or with --ignored"]
fn chaos_for_thirty_seconds() {
    run_chaos(0xc4a05, Duration::from_secs(30));
}
