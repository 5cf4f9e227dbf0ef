//! A replay is frames like any other: in synchronous mode its frames get
//! the server's next frame ids (the recorded id travels in the header, and
//! `watch --json` shows both), it starts a new episode, and lockstep
//! participants follow it tick by tick. Waits that have nothing to wait
//! for say so: a replay into a synchronous world nobody ticks is refused at
//! once, and `autopilot` gives up after `--timeout` on a world that stopped
//! (SIGSTOP) or that nobody ticks. A recording made before frame headers
//! carried their recorded id replays as this protocol's frames.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use shared_types::ReplayMode;
use sim_client::ReplayOptions;
use simbus_recording::inspect;
use simbus_recording::{FRAME_SCHEMA, LEGACY_FRAME_HEADER_BYTES, LEGACY_FRAME_SCHEMA};
use simbus_tests::{
    replayed_frames, send_signal, sync_world, wait_for_participants, Scratch, TestWorld,
};

const T: Duration = Duration::from_secs(30);

/// Records `ticks` frames of `world` (synchronous) to `path`; returns the
/// recorded frame ids.
fn record(world: &TestWorld, path: &std::path::Path, ticks: u32) -> Vec<u64> {
    let client = world.connect();
    let mut ticker = client.claim_ticker().expect("claim");
    client.start_recorder(path, false).expect("start recorder");
    for _ in 0..ticks {
        ticker.tick(T).expect("tick");
    }
    client.stop_recorder().expect("stop recorder");
    let info = inspect::file_info(path.to_str().unwrap(), false).expect("recording info");
    (info.first_frame..info.first_frame + info.frames).collect()
}

#[test]
fn a_synchronous_replay_numbers_its_frames_on_and_a_lockstep_watcher_sees_every_one() {
    let world = TestWorld::start("replay-ls", &["--sync", "--delta-seconds", "0.02"]);
    let scratch = Scratch::new("replay-ls");
    let path = scratch.file("ss.mcap");
    let recorded = record(&world, &path, 17);
    assert_eq!(
        recorded.len(),
        18,
        "the frame current at the start and 17 ticked"
    );

    let client = world.connect();
    let watcher = world.spawn_cli(&["watch", "--json", "--lockstep"]);
    wait_for_participants(&client, 1);
    // Unbounded: it ticks until told to stop, however slow the machine.
    let ticker = world.spawn_cli(&["tick", "--rate", "50", "--participants", "1"]);
    let next = || -> serde_json::Value {
        let line = watcher.line(T).unwrap_or_else(|| {
            panic!(
                "the lockstep watcher stopped; stderr:\n{}",
                watcher.stderr()
            )
        });
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("not JSON ({e}): {line}"))
    };
    // The ticker runs: live frames come.
    let mut seen = vec![next()];
    while seen.last().unwrap()["frame"].as_u64() < Some(recorded[recorded.len() - 1] + 3) {
        seen.push(next());
    }
    let replay = world.cli(&["replay", path.to_str().unwrap(), "--mode", "exact"]);
    replay.assert_success();
    assert!(
        replay.stdout.iter().any(|l| l.contains("18 of 18 frames")),
        "{replay}"
    );
    // Every replayed frame, then the live world again.
    loop {
        let frame = next();
        let replayed = frame["replay"] == true;
        let past_replay = seen.iter().any(|f| f["replay"] == true) && !replayed;
        seen.push(frame);
        if past_replay {
            break;
        }
    }
    let ids: Vec<u64> = seen.iter().map(|f| f["frame"].as_u64().unwrap()).collect();
    for pair in ids.windows(2) {
        assert_eq!(pair[1], pair[0] + 1, "frame ids go on one by one: {ids:?}");
    }
    let replayed: Vec<&serde_json::Value> = seen.iter().filter(|f| f["replay"] == true).collect();
    let recorded_ids: Vec<u64> = replayed
        .iter()
        .map(|f| {
            f["recorded_frame"]
                .as_u64()
                .expect("a replayed frame names its recorded id")
        })
        .collect();
    assert_eq!(
        recorded_ids, recorded,
        "every recorded frame, once, in order"
    );
    let live = seen.iter().find(|f| f["replay"] == false).unwrap();
    assert!(live["recorded_frame"].is_null(), "{live}");
    // The replay is an episode of its own, and so is the live world after it.
    let first = seen.iter().position(|f| f["replay"] == true).unwrap();
    let last = seen.iter().rposition(|f| f["replay"] == true).unwrap();
    assert_ne!(seen[first - 1]["episode"], seen[first]["episode"]);
    assert_eq!(seen[first]["episode"], seen[last]["episode"]);
    assert_ne!(seen[last]["episode"], seen[last + 1]["episode"]);
    // Simulation time never goes back either.
    let times: Vec<u64> = seen
        .iter()
        .map(|f| f["elapsed_ns"].as_u64().unwrap())
        .collect();
    assert!(times.windows(2).all(|t| t[1] >= t[0]), "{times:?}");
    send_signal(ticker.pid(), libc::SIGINT).unwrap();
    ticker.finish(T).assert_success();
}

#[test]
fn a_replay_into_a_synchronous_world_nobody_ticks_is_refused_at_once() {
    let world = TestWorld::start("replay-noticker", &["--sync", "--delta-seconds", "0.02"]);
    let scratch = Scratch::new("replay-noticker");
    let path = scratch.file("r.mcap");
    record(&world, &path, 5);
    // Said at once: a --timeout this long would outlast the test's own.
    let out = world.cli(&["--timeout", "1000", "replay", path.to_str().unwrap()]);
    out.assert_code(1);
    assert!(out.stderr.contains("nobody ticks it"), "{out}");
    assert!(out.stderr.contains("--detach"), "{out}");
    // Nothing changed: no replay runs.
    let status = world.connect().recorder_status().unwrap();
    assert_eq!(status.replay.state, "idle", "{status:?}");
}

#[test]
fn autopilot_gives_up_after_its_timeout_and_says_why() {
    // A synchronous world nobody ticks.
    let world = TestWorld::start("autopilot-noticker", &["--sync", "--delta-seconds", "0.02"]);
    let out = world.cli(&["--timeout", "1", "autopilot"]);
    out.assert_code(1);
    assert!(out.stderr.contains("nobody ticks it"), "{out}");

    // A stopped server.
    let world = TestWorld::start("autopilot-stopped", &["--delta-seconds", "0.02"]);
    let client = world.connect();
    let autopilot = world.spawn_cli(&["--timeout", "1", "autopilot"]);
    wait_for_participants(&client, 1);
    send_signal(world.server.pid(), libc::SIGSTOP).unwrap();
    let out = autopilot.finish(T);
    send_signal(world.server.pid(), libc::SIGCONT).unwrap();
    out.assert_code(1);
    // Waiting for a frame ("does not answer") or for its controls' answer
    // (a batch sent just before the stop): either way after --timeout.
    assert!(
        out.stderr.contains("does not answer") || out.stderr.contains("did not answer within 1s"),
        "{out}"
    );
}

/// `from` rewritten as a recording of the older frame layout
/// (`FrameHeader/2`: the header without its last 16 bytes).
fn as_legacy(from: &Path, to: &Path) {
    let bytes = std::fs::read(from).unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(to).unwrap());
    let mut writer = mcap::Writer::new(file).unwrap();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let mut channel = (*message.channel).clone();
        let mut data = message.data.to_vec();
        if let Some(schema) = channel.schema.clone().filter(|s| s.name == FRAME_SCHEMA) {
            let mut schema = (*schema).clone();
            schema.name = LEGACY_FRAME_SCHEMA.to_string();
            channel.schema = Some(Arc::new(schema));
            let header = std::mem::size_of::<shared_types::FrameHeader>();
            data.drain(LEGACY_FRAME_HEADER_BYTES..header);
        }
        writer
            .write(&mcap::Message {
                channel: Arc::new(channel),
                data: data.into(),
                ..message
            })
            .unwrap();
    }
    writer.finish().unwrap();
}

#[test]
fn a_recording_of_the_older_frame_layout_replays_as_this_protocols_frames() {
    let scratch = Scratch::new("replay-legacy");
    let (path, legacy) = (scratch.file("new.mcap"), scratch.file("old.mcap"));
    let (_world, mut client, mut ticker) = sync_world("replay-legacy", &["--seed", "3"]);
    client.wait_for_tick(T).unwrap();
    client.start_recorder(&path, false).unwrap();
    let mut original = std::collections::BTreeMap::new();
    for _ in 0..10 {
        let frame = ticker.tick(T).unwrap();
        let snapshot = client.wait_for_tick(T).unwrap();
        assert_eq!(snapshot.frame(), frame);
        original.insert(frame, snapshot.digest());
    }
    client.stop_recorder().unwrap();
    as_legacy(&path, &legacy);

    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        ..Default::default()
    };
    let status = client
        .replay(&legacy, &options)
        .expect("an older recording replays");
    assert_eq!(status.replay.total, 11);
    // Every replayed frame arrives (a frame of another protocol version
    // would be refused by the client), digest for digest.
    let replayed = replayed_frames(&mut client, &mut ticker);
    assert_eq!(replayed.len(), 11);
    for snapshot in &replayed {
        assert_eq!(
            snapshot.header.protocol_version,
            shared_types::PROTOCOL_VERSION
        );
        let recorded = snapshot.recorded_frame().expect("a replayed frame");
        if let Some(digest) = original.get(&recorded) {
            assert_eq!(snapshot.digest(), *digest, "recorded frame {recorded}");
        }
    }
}

#[test]
fn autopilot_drives_through_a_replay_without_sending_it_commands() {
    let world = TestWorld::start("replay-autopilot", &["--sync", "--delta-seconds", "0.02"]);
    let scratch = Scratch::new("replay-autopilot");
    let path = scratch.file("a.mcap");
    record(&world, &path, 9);
    let client = world.connect();
    // New controls every frame: a replayed frame must not get any.
    let autopilot = world.spawn_cli(&["autopilot", "--every", "1"]);
    wait_for_participants(&client, 1);
    let ticker = world.spawn_cli(&["tick", "--rate", "100", "--participants", "1"]);
    // The ticker ticks once a frame past the current one arrives.
    let mut watching = world.connect();
    let now = watching.wait_for_tick(T).unwrap().frame();
    while watching.wait_for_tick(T).unwrap().frame() <= now {}
    let replay = world.cli(&["replay", path.to_str().unwrap(), "--mode", "exact"]);
    replay.assert_success();
    assert!(
        replay.stdout.iter().any(|l| l.contains("10 of 10 frames")),
        "{replay}"
    );
    // Still a participant, driving the live world again.
    assert_eq!(
        client.status().unwrap().participants,
        1,
        "{}",
        autopilot.stderr()
    );
    send_signal(ticker.pid(), libc::SIGINT).unwrap();
    ticker.finish(T).assert_success();
    send_signal(autopilot.pid(), libc::SIGINT).unwrap();
    autopilot.finish(T).assert_success();
}
