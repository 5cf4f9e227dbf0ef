//! A closed stdout (`sim-client watch | head -1`) ends every printing
//! command quietly with exit status 0 — no panic, no message — and a
//! ticker whose stdout closes still gives the world back: asynchronous,
//! its own step, nobody ticking.

use std::io::{BufRead, BufReader, Read};
use std::process::{Command, ExitStatus, Stdio};
use std::time::Duration;

use simbus_tests::{bin, unique_world, ChildGuard, Scratch, TestWorld};

/// How a command whose stdout reader went away ended.
struct Ended {
    args: Vec<String>,
    status: ExitStatus,
    /// The lines read before the reader went away.
    read: Vec<String>,
    stderr: String,
}

impl Ended {
    /// A failure message unless it exited 0 without a panic.
    fn problem(&self) -> Option<String> {
        let quiet = self.status.code() == Some(0) && !self.stderr.contains("panicked");
        (!quiet).then(|| {
            format!(
                "sim-client {}: {} after reading {:?}; stderr:\n{}",
                self.args.join(" "),
                self.status,
                self.read,
                self.stderr
            )
        })
    }
}

/// Runs `sim-client --world <world> <args>` with stdout a pipe whose
/// reader reads `lines` lines and then closes it (0: closed before the
/// command starts), and waits (at most 60 s) for it to exit.
fn closed_after(world: &str, args: &[&str], lines: usize) -> Ended {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    let mut command = Command::new(bin("sim-client"));
    command
        .args(["--world", world])
        .args(args)
        .stdin(Stdio::null())
        .stdout(writer)
        .stderr(Stdio::piped())
        .env("RUST_LOG", "warn");
    let mut reader = (lines > 0).then(|| BufReader::new(reader));
    let mut child = command
        .spawn()
        .unwrap_or_else(|e| panic!("starting sim-client {args:?}: {e}"));
    // Our copy of the write end goes with the command.
    drop(command);
    let mut stderr_pipe = child.stderr.take().expect("piped stderr");
    let stderr = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stderr_pipe.read_to_string(&mut text);
        text
    });
    let mut child = ChildGuard::new(child, Duration::from_secs(5));
    let mut read = Vec::new();
    if let Some(reader) = reader.as_mut() {
        for _ in 0..lines {
            let mut line = String::new();
            if reader.read_line(&mut line).unwrap_or(0) == 0 {
                break;
            }
            read.push(line.trim_end().to_owned());
        }
    }
    // Nobody reads any more.
    drop(reader);
    let status = child
        .wait_timeout(Duration::from_secs(60))
        .expect("waiting for sim-client")
        .unwrap_or_else(|| {
            let _ = child.kill();
            panic!("sim-client {args:?} did not end after its stdout closed")
        });
    Ended {
        args: args.iter().map(|a| (*a).to_owned()).collect(),
        status,
        read,
        stderr: stderr.join().expect("stderr reader"),
    }
}

/// Runs every case and fails naming each one that did not end quietly.
fn assert_all_quiet(world: &str, cases: &[(&[&str], usize)]) {
    let problems: Vec<String> = cases
        .iter()
        .filter_map(|(args, lines)| closed_after(world, args, *lines).problem())
        .collect();
    assert!(problems.is_empty(), "{}", problems.join("\n\n"));
}

#[test]
fn every_printing_command_ends_quietly_when_its_stdout_is_closed() {
    let world = TestWorld::start("pipe-all", &["--delta-seconds", "0.02"]);
    let scratch = Scratch::new("pipe-all");
    let recording = scratch.file("run.mcap");
    let recording = recording.to_str().expect("a UTF-8 path");
    let second_recording = scratch.file("second.mcap");
    let second_recording = second_recording.to_str().expect("a UTF-8 path");
    let pictures = scratch.file("pictures");
    let pictures = pictures.to_str().expect("a UTF-8 path");

    // What the commands below need: an actor, sensors, a recording.
    let actor = world.cli(&["spawn", "box", "--at", "0,5,0", "--json"]);
    actor.assert_success();
    let actor_id = actor.json()[0]["id"]
        .as_u64()
        .expect("actor id")
        .to_string();
    let sensor = |kind: &[&str]| {
        let mut args = vec!["sensor", "spawn"];
        args.extend_from_slice(kind);
        args.push("--json");
        let out = world.cli(&args);
        out.assert_success();
        out.json()[0]["id"].as_u64().expect("sensor id").to_string()
    };
    let imu = sensor(&["imu"]);
    let depth = sensor(&["depth", "--size", "8,8"]);
    world
        .cli(&["recorder", "start", recording])
        .assert_success();
    world.cli(&["watch", "--frames", "20"]).assert_success();
    world.cli(&["recorder", "stop"]).assert_success();

    // Closed before the command starts: its first write fails.
    let cases: &[(&[&str], usize)] = &[
        (&["status"], 0),
        (&["status", "--json"], 0),
        (&["top", "--once"], 0),
        (&["top", "--once", "--json"], 0),
        (&["top", "--interval", "0.1"], 0),
        (&["watch"], 0),
        (&["watch", "--json"], 0),
        (&["watch", "--digest"], 0),
        (&["watch", "--every-frame", "--frames", "3"], 0),
        (&["config", "--inspect"], 0),
        (&["config", "--inspect", "--json"], 0),
        (&["config", "--delta-seconds", "0.02"], 0),
        (&["spawn", "sphere", "--at", "2,5,0"], 0),
        (&["spawn", "capsule", "--at", "4,5,0", "--json"], 0),
        (&["sensor", "list"], 0),
        (&["sensor", "list", "--json"], 0),
        (&["sensor", "spawn", "imu"], 0),
        (&["sensor", "watch", &imu], 0),
        (&["sensor", "watch", &imu, "--json"], 0),
        (&["sensor", "save", &depth, "--out", pictures], 0),
        (&["recorder", "status"], 0),
        (&["recorder", "status", "--json"], 0),
        (&["recorder", "info", recording], 0),
        (&["recorder", "info", "--all", recording], 0),
        (&["recorder", "info", "--all", "--json", recording], 0),
        (&["recorder", "info", "--all", "--carla-text", recording], 0),
        (&["recorder", "collisions", recording], 0),
        (&["recorder", "collisions", "--json", recording], 0),
        (&["recorder", "blocked", recording], 0),
        (&["recorder", "blocked", "--json", recording], 0),
        (&["tick", "--count", "100"], 0),
        (&["tick", "--json"], 0),
        (&["foxglove", "--port", "0"], 0),
        (&["carla-gateway", "--port", "0"], 0),
        (&["carla-gateway", "--port", "0", "--json"], 0),
        (&["destroy", &actor_id], 0),
        (&["sensor", "destroy", &imu], 0),
        (&["replay", recording], 0),
        (
            &["replay", recording, "--detach", "--time-factor", "0.01"],
            0,
        ),
        (&["recorder", "time-factor", "0.02"], 0),
        (&["recorder", "stop-replay"], 0),
        (&["recorder", "start", second_recording], 0),
        (&["recorder", "stop"], 0),
        (&["config", "--no-sync"], 0),
        (&["bridge", "zenoh", "--listen", "tcp/127.0.0.1:0"], 0),
        (&["reload"], 0),
        (&["load", "boxes:3", "--json"], 0),
    ];
    assert_all_quiet(&world, cases);
    // The demo starts a server of its own, on a world of its own.
    let demo = closed_after(&unique_world("pipe-demo"), &["demo", "--frames", "5"], 0);
    assert_eq!(demo.problem(), None);
    // Nothing was left ticking the world, nor in synchronous mode.
    world.assert_time_settings(false, Some(0.02), "");
}

#[test]
fn streams_end_quietly_when_their_reader_goes_away_after_a_line() {
    // Paced (50 frames a second): an unpaced world outruns a `--digest`
    // watcher on a loaded machine, which then rightly exits 1 for the gap.
    let world = TestWorld::start("pipe-line", &["--delta-seconds", "0.02", "--realtime"]);
    let imu = world.cli(&["sensor", "spawn", "imu", "--json"]);
    imu.assert_success();
    let imu = imu.json()[0]["id"].as_u64().expect("sensor id").to_string();
    let cases: &[(&[&str], usize)] = &[
        (&["watch"], 1),
        (&["watch", "--json"], 1),
        (&["watch", "--digest"], 1),
        (&["top", "--interval", "0.1"], 1),
        (&["top", "--interval", "0.1", "--json"], 1),
        (&["sensor", "watch", &imu], 1),
        (&["sensor", "watch", &imu, "--json"], 1),
        (&["tick"], 2),
        (&["tick", "--json", "--count", "100000"], 2),
    ];
    assert_all_quiet(&world, cases);
}

#[test]
fn a_ticker_whose_stdout_closes_gives_the_world_back() {
    let world = TestWorld::start("pipe-tick", &["--delta-seconds", "0.02"]);
    for (args, lines) in [
        (&["tick", "--delta-seconds", "0.05"][..], 2),
        (
            &["tick", "--count", "100", "--delta-seconds", "0.05"][..],
            2,
        ),
        (&["tick", "--json", "--delta-seconds", "0.05"][..], 0),
        (&["tick", "--rate", "50", "--fps", "25"][..], 1),
    ] {
        let ended = closed_after(&world, args, lines);
        assert_eq!(ended.problem(), None);
        if lines > 0 {
            assert!(
                ended.read.iter().all(|l| l.starts_with("tick  frame")),
                "{:?}",
                ended.read
            );
        }
        // Asynchronous again, the world's own step, nobody ticking.
        world.assert_time_settings(false, Some(0.02), &format!("after {args:?}: "));
    }
    // A plain ticker then takes the world's own step, as on a fresh world.
    let ticked = world.cli(&["tick", "--count", "2", "--json"]);
    ticked.assert_success();
    assert!(ticked.stderr.contains("fixed step 0.02 s"), "{ticked}");
}

#[test]
fn a_replay_whose_stdout_closes_is_stopped_and_the_world_given_back() {
    let world = TestWorld::start("pipe-replay", &["--delta-seconds", "0.02"]);
    let scratch = Scratch::new("pipe-replay");
    let recording = scratch.file("run.mcap");
    let recording = recording.to_str().expect("a UTF-8 path");
    world
        .cli(&["recorder", "start", recording])
        .assert_success();
    world.cli(&["watch", "--frames", "20"]).assert_success();
    world.cli(&["recorder", "stop"]).assert_success();
    // At a hundredth of its pace the replay would run for a minute.
    let ended = closed_after(&world, &["replay", recording, "--time-factor", "0.01"], 0);
    assert!(ended.problem().is_none(), "{:?}", ended.problem());
    let status = world.connect().recorder_status().unwrap();
    assert_eq!(status.replay.state, "stopped", "{status:?}");
}
