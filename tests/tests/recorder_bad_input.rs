//! Bad recordings and bad recorder requests: a missing file, a directory,
//! a file that is not MCAP, another program's MCAP, a truncated file, a
//! flipped byte, a schema from the future, a replay or recording that
//! collides with another, a path the server cannot write, bad arguments —
//! each is a clear error naming the problem, and the world is unchanged.
//! Thousands of mutated recordings are each read without a panic, and a
//! server replaying a sample of them stays up.

use std::path::Path;
use std::time::Duration;

use shared_types::RecorderRefusal;
use sim_client::{Client, RecorderError, ReplayOptions, Ticker};
use simbus_recording::inspect;
use simbus_recording::FRAME_SCHEMA;
use simbus_tests::{rewrite, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);

/// Records `frames` ticks into `path`.
fn record(client: &Client, ticker: &mut Ticker, path: &Path, frames: u64) {
    client.start_recorder(path, false).unwrap();
    for _ in 0..frames {
        ticker.tick(T).unwrap();
    }
    client.stop_recorder().unwrap();
}

/// (frame, episode) of the world: what a refused request must not change.
fn where_is(client: &Client) -> (u64, u64) {
    let status = client.status().unwrap();
    (status.frame, status.episode)
}

fn refused<T: std::fmt::Debug>(result: Result<T, RecorderError>) -> (RecorderRefusal, String) {
    match result {
        Err(RecorderError::Refused { refusal, message }) => (refusal, message),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn bad_recordings_are_refused_by_name_and_change_nothing() {
    let scratch = Scratch::new("rec-bad");
    let (world, client, mut ticker) = sync_world("rec-bad", &[]);
    let good = scratch.file("good.mcap");
    record(&client, &mut ticker, &good, 40);
    let good_bytes = std::fs::read(&good).unwrap();

    let not_mcap = scratch.write(
        "notes.mcap",
        b"these are not the bytes you are looking for\n",
    );
    let foreign = scratch.file("foreign.mcap");
    {
        let mut writer = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&foreign).unwrap(),
        ))
        .unwrap();
        let channel = std::sync::Arc::new(mcap::Channel {
            id: 0,
            topic: "/imu".into(),
            schema: None,
            message_encoding: "json".into(),
            metadata: Default::default(),
        });
        writer
            .write(&mcap::Message {
                channel,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
                data: b"{}".as_slice().into(),
            })
            .unwrap();
        writer.finish().unwrap();
    }
    // Cut inside MCAP's header record: nothing complete.
    let truncated = scratch.write("truncated.mcap", &good_bytes[..30]);
    // Cut half way: the recording's header (a chunk of its own) is
    // complete, its frames are not.
    let half = scratch.write("half.mcap", &good_bytes[..good_bytes.len() / 2]);
    let mut flipped_bytes = good_bytes.clone();
    flipped_bytes[good_bytes.len() / 3] ^= 0x10;
    let flipped = scratch.write("flipped.mcap", &flipped_bytes);
    let future = scratch.file("future.mcap");
    rewrite(&good, &future, (FRAME_SCHEMA, "simbus::FrameHeader/4"));
    let missing = scratch.file("missing.mcap");

    let cases: [(&Path, &str); 7] = [
        (&missing, "No such file"),
        (scratch.path(), "is a directory"),
        (&not_mcap, "is not an MCAP file: it holds text"),
        (&foreign, "not a simbus recording"),
        (
            &truncated,
            "is still being recorded, or was not closed (its server was killed or the copy is cut short): it ends before its first complete chunk",
        ),
        (&flipped, "damaged"),
        (
            &future,
            "simbus::FrameHeader/4; this simbus reads simbus::FrameHeader/3",
        ),
    ];
    let before = where_is(&client);
    for (path, says) in cases {
        let (refusal, message) = refused(client.replay(path, &ReplayOptions::default()));
        assert_eq!(
            refusal,
            RecorderRefusal::BadFile,
            "{}: {message}",
            path.display()
        );
        assert!(message.contains(says), "{}: {message}", path.display());
        let finished = world.cli(&["recorder", "info", path.to_str().unwrap()]);
        finished.assert_code(2);
        assert!(finished.stderr.contains(says), "{finished}");
    }
    let (refusal, message) = refused(client.replay(&half, &ReplayOptions::default()));
    assert_eq!(refusal, RecorderRefusal::BadFile, "{message}");
    assert!(message.contains("holds no frame"), "{message}");
    let finished = world.cli(&["recorder", "info", half.to_str().unwrap()]);
    finished.assert_success();
    assert!(
        finished
            .stdout
            .iter()
            .any(|l| l
                .starts_with("closed       no: still being recorded, or cut short (its server was killed or its disk filled); readable up to frame")),
        "{finished}"
    );
    assert_eq!(where_is(&client), before, "nothing changed");

    // Requests that collide or make no sense.
    let (refusal, message) = refused(client.stop_recorder());
    assert_eq!(refusal, RecorderRefusal::NotRecording, "{message}");
    let (refusal, message) =
        refused(client.start_recorder("/nonexistent-simbus-dir/x.mcap", false));
    assert_eq!(refusal, RecorderRefusal::CannotWrite, "{message}");
    assert!(
        message.contains("cannot create /nonexistent-simbus-dir/x.mcap"),
        "{message}"
    );
    for factor in [0.0, -1.0, f64::NAN] {
        let options = ReplayOptions {
            time_factor: factor,
            ..Default::default()
        };
        let (refusal, _) = refused(client.replay(&good, &options));
        assert_eq!(refusal, RecorderRefusal::InvalidArgument, "factor {factor}");
    }
    let options = ReplayOptions {
        follow_id: 999_999,
        ..Default::default()
    };
    let (refusal, message) = refused(client.replay(&good, &options));
    assert_eq!(refusal, RecorderRefusal::UnknownActor, "{message}");
    let (refusal, _) = refused(client.stop_replayer(false));
    assert_eq!(refusal, RecorderRefusal::NotReplaying);
    assert_eq!(where_is(&client), before, "nothing changed");

    // A replay and a recording exclude each other; a second replay waits its turn.
    client
        .start_recorder(scratch.file("busy.mcap"), false)
        .unwrap();
    let (refusal, message) = refused(client.replay(&good, &ReplayOptions::default()));
    assert_eq!(refusal, RecorderRefusal::Recording, "{message}");
    let (refusal, _) = refused(client.start_recorder(scratch.file("again.mcap"), false));
    assert_eq!(refusal, RecorderRefusal::AlreadyRecording);
    client.stop_recorder().unwrap();
    client.replay(&good, &ReplayOptions::default()).unwrap();
    let (refusal, message) = refused(client.replay(&good, &ReplayOptions::default()));
    assert_eq!(refusal, RecorderRefusal::Replaying, "{message}");
    let (refusal, _) = refused(client.start_recorder(scratch.file("during.mcap"), false));
    assert_eq!(refusal, RecorderRefusal::Replaying);
    // The replayed actors follow the recording: commands wait for its end.
    let spawn = shared_types::Command::spawn_box([0.0, 2.0, 0.0], [0.5; 3]);
    assert!(matches!(
        client.apply_batch_sync(&[spawn], false),
        Err(sim_client::BatchError::Replaying)
    ));
    client.stop_replayer(false).unwrap();
}

/// xorshift64*: a fixed sequence of mutations, the same on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[test]
fn thousands_of_mutated_recordings_end_in_ok_or_a_typed_error() {
    const MUTATIONS: usize = 3000;
    const REPLAYED_EVERY: usize = 100;
    let scratch = Scratch::new("rec-mut");
    let (_world, client, mut ticker) = sync_world("rec-mut", &[]);
    let good = scratch.file("good.mcap");
    // Spawns and pushes, so every channel has messages.
    client.start_recorder(&good, false).unwrap();
    client
        .apply_batch_sync(
            &[shared_types::Command::spawn_box([0.0, 3.0, 0.0], [0.3; 3])],
            false,
        )
        .unwrap();
    for _ in 0..30 {
        ticker.tick(T).unwrap();
    }
    client.stop_recorder().unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let mut rng = Rng(0x5eed_2026);
    let (mut ok, mut errors) = (0, 0);
    let path = scratch.file("mutant.mcap");
    for i in 0..MUTATIONS {
        let mut mutant = bytes.clone();
        match i % 3 {
            0 => {
                for _ in 0..=rng.below(8) {
                    let at = rng.below(mutant.len());
                    mutant[at] ^= 1 << rng.below(8);
                }
            }
            1 => mutant.truncate(rng.below(bytes.len())),
            _ => {
                let from = rng.below(bytes.len());
                let len = rng.below(bytes.len() - from);
                let to = rng.below(bytes.len());
                let piece = bytes[from..from + len].to_vec();
                mutant.splice(to..(to + len).min(mutant.len()), piece);
            }
        }
        std::fs::write(&path, &mutant).unwrap();
        let file = path.to_str().unwrap();
        match inspect::file_info(file, true) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(!e.to_string().is_empty());
                errors += 1;
            }
        }
        let _ = inspect::collisions(file, 'a', 'a');
        let _ = inspect::actors_blocked(file, 0.1, 0.01);
        if i % REPLAYED_EVERY == 0 {
            match client.replay(
                &path,
                &ReplayOptions {
                    time_factor: 1000.0,
                    ..Default::default()
                },
            ) {
                Ok(_) => {
                    ticker.tick(T).unwrap();
                    let _ = client.stop_replayer(false);
                }
                Err(RecorderError::Refused { .. }) => {}
                Err(e) => panic!("mutation {i}: the server did not answer: {e}"),
            }
        }
    }
    assert_eq!(ok + errors, MUTATIONS);
    assert!(
        errors > MUTATIONS / 2,
        "most mutations are caught: {ok} read, {errors} refused"
    );
    // The server is still up and stepping.
    ticker.tick(T).unwrap();
}

/// A synchronous world with a fixed 0.05 s step on the default scene (and
/// `args`), seeded; a client and its claim on the ticker.
fn sync_world(tag: &str, args: &[&str]) -> (TestWorld, Client, Ticker) {
    let mut all = vec!["--seed", "1"];
    all.extend_from_slice(args);
    simbus_tests::sync_world_at(tag, "0.05", &all)
}
