//! What the recorder tells a user, checked as the user sees it (issue #24):
//! a path the server cannot create is refused naming the path and the real
//! cause; `recorder blocked` refuses limits out of range (exit 2, the flag
//! and its range named) and counts actors, each with its stretches; a
//! replay stopped earlier is no warning about a later recording; the first
//! recorded frame is the frame as it was published (its substeps), in the
//! file and in an exact replay; a recording still being written, an empty
//! or text file, a missing file and a file of several episodes are each
//! described as what they are; counts read `1 frame`; `replay --json
//! --detach` prints its object; the book's recorder chapter shows
//! `blocked`'s defaults.

use std::path::Path;
use std::time::Duration;

use shared_types::ReplayMode;
use sim_client::{Client, ReplayOptions, Ticker};
use simbus_tests::{replayed_frames, Finished, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);

/// A synchronous world with a fixed 0.05 s step (5 substeps of 0.01 s) on
/// the default scene, seeded; a client and its claim on the ticker.
fn sync_world(tag: &str) -> (TestWorld, Client, Ticker) {
    simbus_tests::sync_world_at(tag, "0.05", &["--seed", "3"])
}

/// Records `ticks` ticks into `path`.
fn record(client: &Client, ticker: &mut Ticker, path: &Path, ticks: u64) {
    client.start_recorder(path, false).unwrap();
    for _ in 0..ticks {
        ticker.tick(T).unwrap();
    }
    client.stop_recorder().unwrap();
}

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The one JSON value a `--json` command printed.
fn one_json(out: &Finished) -> serde_json::Value {
    out.assert_success();
    let mut values = out.json();
    assert_eq!(values.len(), 1, "{out}");
    values.pop().unwrap()
}

#[test]
fn a_path_the_server_cannot_create_is_refused_naming_the_real_cause() {
    let scratch = Scratch::new("rec-msg-create");
    let world = TestWorld::start("rec-msg-create", &[]);
    let dir = text(scratch.path());
    let plain = scratch.write("plain.txt", b"x");
    let long_name = format!("{dir}/{}.mcap", "n".repeat(300));
    let cases = [
        (
            format!("{dir}/nonexistdir/x.mcap"),
            format!("no such directory: {dir}/nonexistdir"),
        ),
        (
            dir.to_string(),
            "it is a directory; name a file in it".to_string(),
        ),
        (
            format!("{}/x.mcap", text(&plain)),
            format!("{} is a file, not a directory", text(&plain)),
        ),
        (
            "/proc/x.mcap".to_string(),
            "/proc does not take new files".to_string(),
        ),
        (
            "/sys/x.mcap".to_string(),
            "permission denied: the server may not create files in /sys".to_string(),
        ),
        (
            long_name.clone(),
            "is 305 bytes long; a file name may have at most 255".to_string(),
        ),
    ];
    for (path, cause) in cases {
        let out = world.cli(&["recorder", "start", &path]);
        out.assert_code(2);
        assert!(
            out.stderr.contains(&format!("cannot create {path}: ")),
            "{out}"
        );
        assert!(out.stderr.contains(&cause), "{out}");
        assert!(!out.stderr.contains("I/O error from writing"), "{out}");
    }
    // Nothing runs: the recorder is idle.
    let status = world.cli(&["recorder", "status", "--json"]);
    assert_eq!(one_json(&status)["recording"], false);
}

#[test]
fn blocked_checks_its_limits_and_counts_each_actor_once() {
    let scratch = Scratch::new("rec-msg-blocked");
    let path = scratch.file("run.mcap");
    let (world, client, mut ticker) = sync_world("rec-msg-blocked");
    record(&client, &mut ticker, &path, 60);
    let file = text(&path);

    for (flag, value, range) in [
        ("--min-time", "NaN", "0..=18446744073"),
        ("--min-time", "inf", "0..=18446744073"),
        ("--min-time", "-1", "0..=18446744073"),
        ("--min-distance", "NaN", "positive, finite number of metres"),
        ("--min-distance", "inf", "positive, finite number of metres"),
        ("--min-distance", "0", "positive, finite number of metres"),
        (
            "--min-distance",
            "-0.5",
            "positive, finite number of metres",
        ),
    ] {
        let out = world.cli(&["recorder", "blocked", file, &format!("{flag}={value}")]);
        out.assert_code(2);
        assert!(out.stderr.contains(flag), "{out}");
        assert!(out.stderr.contains(range), "{out}");
    }

    let info = one_json(&world.cli(&["recorder", "info", file, "--json"]));
    let most_actors = info["max_actors"].as_u64().unwrap();
    // Every movable actor stands still for some stretch of 0 s: each is
    // listed once, however many stretches it had.
    let args = [
        "recorder",
        "blocked",
        file,
        "--min-time",
        "0",
        "--min-distance",
        "0.001",
    ];
    let json = world.cli(&[&args[..], &["--json"]].concat());
    let blocked = one_json(&json);
    let actors = blocked.as_array().unwrap();
    assert!(!actors.is_empty());
    assert!(actors.len() as u64 <= most_actors, "{json}");
    let mut ids: Vec<u64> = actors
        .iter()
        .map(|a| a["actor"].as_u64().unwrap())
        .collect();
    ids.dedup();
    assert_eq!(
        ids.len(),
        actors.len(),
        "each actor once, in id order: {json}"
    );
    let mut stretches = 0;
    for actor in actors {
        assert_ne!(actor["kind"], "static");
        let list = actor["stretches"].as_array().unwrap();
        assert!(!list.is_empty(), "{actor}");
        stretches += list.len();
    }
    assert!(stretches > actors.len(), "something moved: {json}");

    let out = world.cli(&args);
    out.assert_success();
    let listed = out
        .stdout
        .iter()
        .filter(|l| l.starts_with("actor "))
        .count();
    assert_eq!(listed, actors.len(), "{out}");
    assert_eq!(
        out.stdout.last().unwrap(),
        &format!(
            "{} actors blocked for at least 0 s (moving less than 0.001 m; times are recording \
             seconds: since the recording's start, as CARLA's recorder counts)",
            actors.len()
        )
    );

    // The defaults (30 s, 0.1 m) need no flags: 3 s recorded, none.
    let out = world.cli(&["recorder", "blocked", file]);
    out.assert_success();
    assert_eq!(
        out.stdout,
        [
            "0 actors blocked for at least 30 s (moving less than 0.1 m; times are recording \
          seconds: since the recording's start, as CARLA's recorder counts)"
        ]
    );
}

#[test]
fn a_replay_stopped_earlier_is_no_warning_for_a_later_recording() {
    let scratch = Scratch::new("rec-msg-stale");
    let first = scratch.file("first.mcap");
    let second = scratch.file("second.mcap");
    let (world, client, mut ticker) = sync_world("rec-msg-stale");
    record(&client, &mut ticker, &first, 10);
    client.replay(&first, &ReplayOptions::default()).unwrap();
    ticker.tick(T).unwrap();
    world.cli(&["recorder", "stop-replay"]).assert_success();
    let status = one_json(&world.cli(&["recorder", "status", "--json"]));
    assert_eq!(status["replay"]["state"], "stopped");

    world
        .cli(&["recorder", "start", text(&second)])
        .assert_success();
    ticker.tick(T).unwrap();
    let out = world.cli(&["recorder", "stop"]);
    out.assert_success();
    assert_eq!(out.stdout.len(), 1, "no warning: {out}");
    assert!(
        out.stdout[0].starts_with("recording stopped: 2 frames, "),
        "{out}"
    );
    assert!(!out.stdout[0].contains("warning"), "{out}");
    world
        .cli(&["recorder", "start", text(&second)])
        .assert_success();
    let stopped = one_json(&world.cli(&["recorder", "stop", "--json"]));
    assert_eq!(stopped["message"], "", "{stopped}");
    // The replay's own status still says why it ended.
    let status = one_json(&world.cli(&["recorder", "status", "--json"]));
    assert_eq!(status["message"], "stopped by a client", "{status}");
}

#[test]
fn the_first_recorded_frame_is_the_frame_as_it_was_published() {
    let scratch = Scratch::new("rec-msg-substeps");
    let path = scratch.file("run.mcap");
    let (world, mut client, mut ticker) = sync_world("rec-msg-substeps");
    // Frames of 0.05 s run 5 substeps of 0.01 s; the recording starts at
    // a frame already published.
    let mut last = 0;
    for _ in 0..3 {
        last = ticker.tick(T).unwrap();
    }
    let live = loop {
        let snapshot = client.wait_for_tick(T).unwrap();
        if snapshot.frame() == last {
            break snapshot;
        }
    };
    assert_eq!(live.header.physics_substeps, 5);
    record(&client, &mut ticker, &path, 4);

    let info = one_json(&world.cli(&["recorder", "info", text(&path), "--all", "--json"]));
    let frames = info["frame_list"].as_array().unwrap();
    assert_eq!(frames.len(), 5, "{info}");
    assert_eq!(frames[0]["frame"], live.frame());
    for frame in frames {
        assert_eq!(frame["substeps"], 5, "{frame}");
    }
    let out = world.cli(&["recorder", "info", text(&path), "--all"]);
    out.assert_success();
    let first = out
        .stdout
        .iter()
        .find(|l| l.trim_start().starts_with("frame "))
        .unwrap();
    assert!(first.contains("substeps  5"), "{out}");

    // An exact replay reproduces the recorded header, substeps included.
    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        ..Default::default()
    };
    client.replay(&path, &options).unwrap();
    let replayed = replayed_frames(&mut client, &mut ticker);
    assert_eq!(replayed.len(), 5);
    for snapshot in &replayed {
        assert_eq!(snapshot.header.physics_substeps, 5);
    }
}

#[test]
fn files_are_described_as_what_they_are() {
    let scratch = Scratch::new("rec-msg-files");
    let (world, client, mut ticker) = sync_world("rec-msg-files");

    // Still being recorded: its header and every complete chunk are read.
    let live = scratch.file("live.mcap");
    client.start_recorder(&live, false).unwrap();
    ticker.tick(T).unwrap();
    let out = world.cli(&["recorder", "info", text(&live)]);
    out.assert_success();
    out.line_starting("closed       no: still being recorded");
    assert!(!out.stderr.contains("damaged"), "{out}");
    let info = one_json(&world.cli(&["recorder", "info", text(&live), "--json"]));
    assert_eq!(info["truncated"], true);
    assert_eq!(info["header"]["world"], world.name());

    // Two episodes: frame ids start again, so each has its own range.
    client.reload_world(false).unwrap();
    for _ in 0..3 {
        ticker.tick(T).unwrap();
    }
    client.stop_recorder().unwrap();
    let info = one_json(&world.cli(&["recorder", "info", text(&live), "--json"]));
    let episodes = info["episode_list"].as_array().unwrap();
    assert_eq!(episodes.len(), 2, "{info}");
    assert_eq!(episodes[1]["first_frame"], 0, "{info}");
    let sum: u64 = episodes.iter().map(|e| e["frames"].as_u64().unwrap()).sum();
    assert_eq!(sum, info["frames"].as_u64().unwrap());
    let out = world.cli(&["recorder", "info", text(&live)]);
    out.assert_success();
    let frames_line = out.line_starting("frames ");
    assert!(
        frames_line.contains(&format!("{} frames in 2 episodes", info["frames"])),
        "{out}"
    );
    for e in episodes {
        let line = format!(
            "  episode {:<4} {} frames (frame {} to {})",
            e["episode"].as_u64().unwrap(),
            e["frames"],
            e["first_frame"],
            e["last_frame"]
        );
        assert!(out.stdout.contains(&line), "{line:?} in {out}");
    }

    // Not MCAP at all, said so; a missing file's cause said once.
    let empty = scratch.write("empty.mcap", b"");
    let notes = scratch.write("notes.mcap", b"recorded on Tuesday, see run.mcap\n");
    let missing = scratch.file("missing.mcap");
    for (path, says) in [
        (&empty, "is not an MCAP file: it is empty".to_string()),
        (&notes, "is not an MCAP file: it holds text".to_string()),
        (
            &missing,
            "cannot read PATH: No such file or directory (os error 2)\n".to_string(),
        ),
    ] {
        let says = says.replace("PATH", text(path));
        let out = world.cli(&["recorder", "info", text(path)]);
        out.assert_code(2);
        assert!(out.stderr.contains(&says), "{says:?} in {out}");
        assert!(!out.stderr.contains("truncated"), "{out}");
        assert!(out.stderr.matches("os error").count() <= 1, "{out}");
    }
}

#[test]
fn counts_read_as_words_and_a_detached_json_replay_prints_its_object() {
    let scratch = Scratch::new("rec-msg-words");
    let path = scratch.file("one.mcap");
    let (world, _client, _ticker) = sync_world("rec-msg-words");
    world
        .cli(&["recorder", "start", text(&path)])
        .assert_success();
    let out = world.cli(&["recorder", "stop"]);
    out.assert_success();
    assert!(
        out.stdout[0].starts_with("recording stopped: 1 frame, "),
        "{out}"
    );
    let out = world.cli(&["recorder", "status"]);
    out.assert_success();
    assert!(
        out.stdout[0].contains(&format!("last: {} (1 frame, ", text(&path))),
        "{out}"
    );
    let out = world.cli(&["recorder", "info", text(&path)]);
    out.assert_success();
    out.line_starting("frames       1 frame (frame ");

    let out = world.cli(&["replay", text(&path), "--detach", "--json"]);
    let started = one_json(&out);
    assert_eq!(started["replay"]["state"], "running", "{out}");
    assert_eq!(started["replay"]["total"], 1, "{out}");
    world.cli(&["recorder", "stop-replay"]).assert_success();
}

#[test]
fn the_book_shows_blocked_with_its_defaults() {
    let readme = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/src/recorder.md"
    ))
    .expect("docs/src/recorder.md");
    let line = readme
        .lines()
        .find(|l| l.starts_with("| `recorder blocked "))
        .expect("the blocked line");
    assert!(
        line.starts_with("| `recorder blocked FILE [--min-time S] [--min-distance M] [--json]` |"),
        "{line}"
    );
    assert!(
        line.contains("default 30") && line.contains("default 0.1"),
        "{line}"
    );
}
