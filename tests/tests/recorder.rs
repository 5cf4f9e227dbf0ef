//! The recorder and replayer: a recorded run replays frame for frame with
//! the original digests in a fresh server, re-simulates bit-identically
//! (and says where a changed command makes it differ), variable-step
//! recordings replay with their deltas or interpolated, start and duration
//! select the right frames, inspection answers as data, and an MCAP reader
//! simbus did not write reads the file.

use std::path::Path;
use std::time::Duration;

use shared_types::{Command, ReplayMode};
use sim_client::{Client, ReplayOptions, Ticker, WorldSnapshot};
use simbus_recording::{Entry, RecordingReader};
use simbus_tests::{replayed_frames, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);
const FRAMES: u64 = 300;
const RELOAD_AT: u64 = 150;

/// The scenario's commands before `frame` of an episode whose first actor
/// is `first`: spawns, pushes, a vehicle driving.
fn commands_at(frame: u64, first: u64) -> Vec<Command> {
    let id = |nth: u64| first + nth - 1;
    match frame {
        5 => vec![
            Command::spawn_box([3.0, 4.0, 2.0], [0.4, 0.4, 0.4]),
            Command::spawn_sphere([6.0, 8.0, -2.0], 0.3),
            Command::spawn_vehicle([-10.0, 1.0, 14.0]),
        ],
        20 => vec![Command::apply_impulse(id(3), [2.0, 3.0, 0.0])],
        40 => vec![Command::vehicle_control(id(20), 0.8, 0.3, 0.0, false)],
        90 => vec![Command::apply_force(id(4), [0.0, 30.0, 5.0])],
        120 => vec![Command::destroy(id(18))],
        _ => Vec::new(),
    }
}

/// Records the scenario (with a reload half way) into `path`; returns
/// every frame's (frame, digest) as the live run saw it.
fn record_scenario(client: &mut Client, ticker: &mut Ticker, path: &Path) -> Vec<(u64, u64)> {
    let first = client.wait_for_tick(T).expect("frame 0");
    client.start_recorder(path, false).expect("start recorder");
    let mut seen = vec![(first.frame(), first.digest())];
    let mut first_id = first.header.first_actor_id;
    let mut frame = first.frame();
    for _ in 0..FRAMES {
        if frame == RELOAD_AT {
            client.reload_world(false).expect("reload");
            let fresh = client.wait_for_tick(T).expect("the reloaded frame 0");
            assert_eq!(fresh.frame(), 0);
            first_id = fresh.header.first_actor_id;
            frame = 0;
            seen.push((0, fresh.digest()));
        }
        let commands = commands_at(frame + 1, first_id);
        if !commands.is_empty() {
            let response = client.apply_batch_sync(&commands, false).expect("batch");
            assert!(response.errors().is_empty(), "{:?}", response.errors());
        }
        frame = ticker.tick(T).expect("tick");
        let snapshot = client.wait_for_tick(T).expect("snapshot");
        assert_eq!(snapshot.frame(), frame);
        seen.push((frame, snapshot.digest()));
    }
    let status = client.stop_recorder().expect("stop recorder");
    assert_eq!(status.frames, seen.len() as u64, "every frame was recorded");
    assert!(status.bytes > 0);
    seen
}

fn cli_stdout(world: &TestWorld, args: &[&str]) -> String {
    let finished = world.cli(args);
    finished.assert_success();
    finished.stdout.join("\n")
}

#[test]
fn a_recorded_run_replays_exactly_and_resimulates_bit_identically() {
    let scratch = Scratch::new("rec-exact");
    let path = scratch.file("run.mcap");
    let (_world, mut client, mut ticker) = sync_world("rec-a", &[]);
    let original = record_scenario(&mut client, &mut ticker, &path);
    assert_eq!(
        original.len() as u64,
        FRAMES + 2,
        "frame 0, the ticks and the reloaded frame 0"
    );

    // Exact replay in a fresh server, one recorded frame per tick.
    let (_fresh, mut replay_client, mut replay_ticker) = sync_world("rec-b", &[]);
    let status = replay_client
        .replay(
            &path,
            &ReplayOptions {
                mode: Some(ReplayMode::Exact),
                ..Default::default()
            },
        )
        .expect("replay");
    assert_eq!(status.replay.total, original.len() as u64);
    let replayed = replayed_frames(&mut replay_client, &mut replay_ticker);
    // Replayed frames are the server's next ids; the recorded id is in the header.
    let replayed: Vec<(u64, u64)> = replayed
        .iter()
        .map(|s| (s.recorded_frame().expect("a replayed frame"), s.digest()))
        .collect();
    assert_eq!(replayed.len(), original.len());
    for (i, (a, b)) in original.iter().zip(&replayed).enumerate() {
        assert_eq!(a, b, "replayed frame #{i} differs from the original");
    }

    // Re-simulation from the recorded scene, seed, settings and commands.
    let checker = TestWorld::start("rec-c", &[]);
    let out = cli_stdout(
        &checker,
        &[
            "replay",
            path.to_str().unwrap(),
            "--mode",
            "resimulate",
            "--verify",
            "--time-factor",
            "1000",
        ],
    );
    assert!(
        out.contains(&format!("identical: {} frames", original.len())),
        "{out}"
    );

    // The same recording with one command changed differs at that frame.
    let changed = scratch.file("changed.mcap");
    let changed_frame = rewrite_one_command(&path, &changed);
    let finished = checker.cli(&[
        "replay",
        changed.to_str().unwrap(),
        "--mode",
        "resimulate",
        "--verify",
        "--time-factor",
        "1000",
    ]);
    finished.assert_code(1);
    assert!(
        finished
            .stdout
            .join("\n")
            .contains(&format!("differs: frame {changed_frame} ")),
        "{finished}"
    );
}

/// Copies `from` to `to` with the first impulse command made stronger;
/// returns the frame it applies before.
fn rewrite_one_command(from: &Path, to: &Path) -> u64 {
    use simbus_recording::{RecordedCommand, COMMANDS_TOPIC};
    let bytes = std::fs::read(from).unwrap();
    let out = std::io::BufWriter::new(std::fs::File::create(to).unwrap());
    let mut writer = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .create(out)
        .unwrap();
    let mut changed = None;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let mut message = message.unwrap();
        if message.channel.topic == COMMANDS_TOPIC && changed.is_none() {
            let mut command: RecordedCommand = bytemuck::pod_read_unaligned(&message.data);
            if command.command.kind == shared_types::CommandKind::ApplyImpulse as u32 {
                command.command.vector[1] += 0.5;
                changed = Some(command.frame);
                message.data = std::borrow::Cow::Owned(bytemuck::bytes_of(&command).to_vec());
            }
        }
        writer.write(&message).unwrap();
    }
    writer.finish().unwrap();
    changed.expect("the recording holds an impulse")
}

#[test]
fn start_and_duration_select_frames_and_a_sync_replay_waits_for_the_tick() {
    let scratch = Scratch::new("rec-select");
    let path = scratch.file("run.mcap");
    let (_world, mut client, mut ticker) = sync_world("rec-sel", &[]);
    client.wait_for_tick(T).unwrap();
    client.start_recorder(&path, false).unwrap();
    for _ in 0..100 {
        ticker.tick(T).unwrap();
    }
    // 101 frames, 0.05 s apart: 5 s.
    client.stop_recorder().unwrap();
    let start_elapsed = {
        let reader = RecordingReader::open(path.to_str().unwrap()).unwrap();
        reader.header().start_elapsed_ns
    };

    let cases: [(f64, f64, u64, u64); 4] = [
        // (start, duration, frames, first frame's recording time in ms)
        (0.0, 0.0, 101, 0),
        (2.0, 1.0, 21, 2000),
        (-1.0, 0.0, 21, 4000),
        (-100.0, 0.5, 11, 0),
    ];
    for (start, duration, frames, first_ms) in cases {
        let options = ReplayOptions {
            start,
            duration,
            time_factor: 1.0,
            ..Default::default()
        };
        let status = client.replay(&path, &options).expect("replay");
        assert_eq!(
            status.replay.total, frames,
            "start {start} duration {duration}"
        );
        // Nothing happens before the next tick, however long the server runs.
        for _ in 0..3 {
            assert_eq!(client.recorder_status().unwrap().replay.frames, 0);
        }
        let replayed = replayed_frames(&mut client, &mut ticker);
        assert_eq!(
            replayed.len() as u64,
            frames,
            "start {start} duration {duration}"
        );
        let first = replayed[0].header.recorded_elapsed_ns - start_elapsed;
        assert_eq!(first, first_ms * 1_000_000, "start {start}");
    }
    let past_end = client
        .replay(
            &path,
            &ReplayOptions {
                start: 6.0,
                ..Default::default()
            },
        )
        .unwrap_err();
    assert!(past_end.to_string().contains("past the end"), "{past_end}");
}

#[test]
fn a_variable_step_recording_replays_its_deltas_exactly_or_interpolated() {
    let scratch = Scratch::new("rec-var");
    let path = scratch.file("var.mcap");
    let recorded = TestWorld::start("rec-var", &["--seed", "2", "--max-fps", "200"]);
    let mut client = recorded.connect();
    client.start_recorder(&path, false).unwrap();
    // Let it run at its own variable pace for 200 frames.
    let begin = client.wait_for_frame(T).unwrap().frame();
    while client.wait_for_frame(T).unwrap().frame() < begin + 200 {}
    client.stop_recorder().unwrap();
    drop(recorded);

    let mut reader = RecordingReader::open(path.to_str().unwrap()).unwrap();
    let mut frames = Vec::new();
    while let Some(entry) = reader.next() {
        if let Entry::Frame {
            log_ns,
            header,
            actors,
        } = entry.unwrap()
        {
            frames.push((log_ns, header, actors));
        }
    }
    let deltas: Vec<u64> = frames.iter().map(|f| f.1.timestamp.delta_ns).collect();
    assert!(
        deltas[1..].windows(2).any(|w| w[0] != w[1]),
        "a variable step: {deltas:?}"
    );
    let recorded_seconds = frames.last().unwrap().0;

    // Exact: the recorded deltas, frame by frame.
    let (_w, mut replay_client, mut ticker) = sync_world("rec-var-b", &[]);
    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        ..Default::default()
    };
    replay_client.replay(&path, &options).unwrap();
    let exact = replayed_frames(&mut replay_client, &mut ticker);
    let exact_deltas: Vec<u64> = exact.iter().map(|s| s.timestamp().delta_ns).collect();
    assert_eq!(exact_deltas, deltas);
    let span = |s: &[WorldSnapshot]| {
        s.last().unwrap().header.recorded_elapsed_ns - s[0].header.recorded_elapsed_ns
    };
    assert_eq!(span(&exact), recorded_seconds);

    // Interpolate (the default for a variable step): the server's own
    // 0.05 s step; poses match the recording interpolated at each time.
    let status = replay_client
        .replay(&path, &ReplayOptions::default())
        .unwrap();
    assert_eq!(status.replay.mode, "interpolate");
    let interpolated = replayed_frames(&mut replay_client, &mut ticker);
    assert_eq!(
        span(&interpolated),
        recorded_seconds,
        "the recorded number of seconds"
    );
    assert!(interpolated.len() as u64 >= recorded_seconds / 50_000_000);
    const TOLERANCE: f32 = 1e-3;
    for snapshot in &interpolated {
        let t = snapshot.header.recorded_elapsed_ns;
        let after = frames
            .partition_point(|f| f.1.timestamp.elapsed_ns < t)
            .min(frames.len() - 1);
        let before = after.saturating_sub(1);
        let (b, a) = (&frames[before], &frames[after]);
        let (tb, ta) = (b.1.timestamp.elapsed_ns, a.1.timestamp.elapsed_ns);
        let alpha = if ta > tb {
            (t - tb) as f32 / (ta - tb) as f32
        } else {
            0.0
        };
        for actor in &snapshot.actors {
            let (Some(x), Some(y)) = (
                b.2.iter().find(|s| s.id == actor.id),
                a.2.iter().find(|s| s.id == actor.id),
            ) else {
                continue;
            };
            for i in 0..3 {
                let expected = x.position[i] + (y.position[i] - x.position[i]) * alpha;
                assert!(
                    (actor.position[i] - expected).abs() <= TOLERANCE,
                    "actor {} at t={t} ns: {} vs {expected}",
                    actor.id,
                    actor.position[i]
                );
            }
        }
    }
}

#[test]
fn inspection_answers_as_data_and_a_foreign_mcap_reader_reads_the_file() {
    let scratch = Scratch::new("rec-info");
    let path = scratch.file("info.mcap");
    let (world, mut client, mut ticker) = sync_world("rec-info", &[]);
    let original = record_scenario(&mut client, &mut ticker, &path);
    let file = path.to_str().unwrap();

    let info: serde_json::Value =
        serde_json::from_str(&cli_stdout(&world, &["recorder", "info", file, "--json"])).unwrap();
    assert_eq!(info["frames"], original.len() as u64);
    assert_eq!(info["episodes"], 1, "one reload");
    assert_eq!(info["actors_spawned"], 6, "three spawns in each episode");
    assert_eq!(info["actors_destroyed"], 2, "one destroy in each episode");
    assert_eq!(info["duration_seconds"], 0.05 * FRAMES as f64);
    assert_eq!(info["header"]["scene"], "default");
    assert_eq!(info["header"]["seed"], 5);
    assert_eq!(info["stopped"], "stop");
    assert_eq!(info["truncated"], false);

    // The default scene's sphere falls onto the boxes.
    let collisions: Vec<serde_json::Value> = serde_json::from_str(&cli_stdout(
        &world,
        &["recorder", "collisions", file, "--json"],
    ))
    .unwrap();
    assert!(
        collisions
            .iter()
            .any(|c| (c["kind_a"] == "sphere" && c["kind_b"] == "box")
                || (c["kind_a"] == "box" && c["kind_b"] == "sphere")),
        "{collisions:?}"
    );
    let spheres: Vec<serde_json::Value> = serde_json::from_str(&cli_stdout(
        &world,
        &[
            "recorder",
            "collisions",
            file,
            "--kind1",
            "s",
            "--kind2",
            "b",
            "--json",
        ],
    ))
    .unwrap();
    assert!(!spheres.is_empty() && spheres.len() < collisions.len());

    let blocked: Vec<serde_json::Value> = serde_json::from_str(&cli_stdout(
        &world,
        &[
            "recorder",
            "blocked",
            file,
            "--min-time",
            "5",
            "--min-distance",
            "0.05",
            "--json",
        ],
    ))
    .unwrap();
    // One entry per actor, each with its stretches.
    assert!(blocked
        .iter()
        .all(|b| b["stretches"]
            .as_array()
            .unwrap()
            .iter()
            .all(|s| s["duration_seconds"].as_f64().unwrap() >= 5.0)));
    assert!(blocked.iter().all(|b| b["kind"] != "static"));

    // An MCAP reader simbus did not write: the `mcap` package from PyPI.
    let script = r#"
import sys, json
from mcap.reader import make_reader
reader = make_reader(open(sys.argv[1], "rb"))
summary = reader.get_summary()
topics = {c.topic: summary.statistics.channel_message_counts.get(i, 0) for i, c in summary.channels.items()}
frames = sum(1 for _ in reader.iter_messages(topics=["/simbus/frames"]))
schemas = sorted(s.name for s in summary.schemas.values())
print(json.dumps({"topics": topics, "frames": frames, "schemas": schemas, "profile": reader.get_header().profile}))
"#;
    let output = std::process::Command::new(simbus_tests::python())
        .arg("-c")
        .arg(script)
        .arg(file)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let read: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(read["frames"], original.len() as u64);
    assert_eq!(read["profile"], "simbus");
    assert_eq!(read["topics"]["/foxglove/scene"], original.len() as u64);
    assert_eq!(read["topics"]["/simbus/header"], 1);
    assert!(
        read["topics"]["/simbus/keyframes"].as_u64().unwrap() >= 2,
        "start and every 10 s"
    );
    assert!(read["schemas"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s == "simbus::FrameHeader/3"));
}

/// A synchronous world with a fixed 0.05 s step on the default scene (and
/// `args`), seeded; a client and its claim on the ticker.
fn sync_world(tag: &str, args: &[&str]) -> (TestWorld, Client, Ticker) {
    let mut all = vec!["--seed", "5"];
    all.extend_from_slice(args);
    simbus_tests::sync_world_at(tag, "0.05", &all)
}
