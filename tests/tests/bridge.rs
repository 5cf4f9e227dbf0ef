//! The Zenoh bridge across two hosts: a world exported from one network
//! namespace and mirrored into another (each with its own iceoryx2 root,
//! joined only by a veth pair) ticks in step on both — the same frames,
//! the same digests, none lost — keeps one ticker across hosts, and
//! survives its link going down and up: the remote ticker fails with a
//! clear error, the server releases the ownership, a new ticker continues
//! from the next frame.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use simbus_tests::{unique_world, Proc, TwoHosts};

const LONG: Duration = Duration::from_secs(30);

/// `frame F digest D` lines as a map.
fn digests(lines: &[String]) -> BTreeMap<u64, String> {
    lines
        .iter()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            match (words.next(), words.next(), words.next(), words.next()) {
                (Some("frame"), Some(frame), Some("digest"), Some(digest)) => {
                    Some((frame.parse().ok()?, digest.to_owned()))
                }
                _ => None,
            }
        })
        .collect()
}

/// A `tick --json` run that succeeded within `timeout`, and the frames of
/// the lines it printed (those not read yet).
fn ticked_frames(ticker: Proc, timeout: Duration) -> (simbus_tests::Finished, Vec<u64>) {
    let ticked = ticker.finish(timeout);
    ticked.assert_success();
    let frames = ticked
        .json()
        .iter()
        .map(|t| t["frame"].as_u64().expect("frame"))
        .collect();
    (ticked, frames)
}

/// The ticker the world's status names, as `(node, pid)`.
fn status_ticker(hosts: &TwoHosts, world: &str) -> Option<(String, u64)> {
    let status = hosts
        .a
        .client(world, "10", &["status", "--json"])
        .finish(LONG);
    status.assert_success();
    let json = status.json();
    let ticker = &json.first().expect("status json")["ticker"];
    ticker.as_object().map(|t| {
        (
            t["node"].as_str().unwrap_or_default().to_owned(),
            t["pid"].as_u64().unwrap_or_default(),
        )
    })
}

#[test]
fn a_mirrored_world_ticks_in_step_keeps_one_ticker_and_survives_its_link() {
    let hosts = TwoHosts::new("zb");
    let world = unique_world("zb");
    // This mirror sleeps at once between events (`--poll-us 0`); the other
    // tests' mirrors look for a tick's next event first (the default).
    let bridge = hosts.mirrored(
        &world,
        &["--sync", "--delta-seconds", "0.05"],
        &["--poll-us", "0"],
    );

    // A watcher on each host, then 500 ticks from the second host.
    let watch = ["watch", "--digest", "--frames", "501"];
    let watch_a = hosts.a.client(&world, "20", &watch);
    let watch_b = hosts.b.client(&world, "20", &watch);
    watch_a.wait_line("frame 0 digest", LONG);
    watch_b.wait_line("frame 0 digest", LONG);
    // A depth camera spawned from the second host, read on both: each
    // reader joins the lockstep, so the ticks wait until both read.
    let spawned = hosts
        .b
        .client(
            &world,
            "20",
            &["sensor", "spawn", "depth", "--size", "16,12", "--json"],
        )
        .finish(LONG);
    spawned.assert_success();
    let id = spawned.json()[0]["id"]
        .as_u64()
        .expect("sensor id")
        .to_string();
    let read = [
        "sensor",
        "watch",
        &id,
        "--captures",
        "10",
        "--lockstep",
        "--json",
    ];
    let camera_a = hosts.a.client(&world, "20", &read);
    let camera_b = hosts.b.client(&world, "20", &read);
    let ticker = hosts.b.client(
        &world,
        "20",
        &[
            "tick",
            "--count",
            "500",
            "--participants",
            "2",
            "--leave-sync",
            "--json",
        ],
    );
    let (ticked, frames) = ticked_frames(ticker, LONG * 2);
    assert_eq!(frames, (1..=500).collect::<Vec<_>>(), "{ticked}");
    let (seen_a, seen_b) = (watch_a.finish(LONG), watch_b.finish(LONG));
    seen_a.assert_success();
    seen_b.assert_success();
    let (a, b) = (digests(&seen_a.stdout), digests(&seen_b.stdout));
    assert_eq!(
        a.len(),
        500,
        "host a saw frames 1..=500 once each:\n{seen_a}"
    );
    assert_eq!(a, b, "both hosts saw the same frames with the same digests");
    let captures = |proc: Proc| {
        let done = proc.finish(LONG);
        done.assert_success();
        done.json()
            .iter()
            .map(|c| {
                (
                    c["frame"].as_u64(),
                    c["sequence"].as_u64(),
                    c["bytes"].as_u64(),
                )
            })
            .collect::<Vec<_>>()
    };
    let (captured_a, captured_b) = (captures(camera_a), captures(camera_b));
    assert_eq!(
        captured_a.iter().map(|c| c.0).collect::<Vec<_>>(),
        (1..=10).map(Some).collect::<Vec<_>>(),
        "every frame's capture, in order"
    );
    assert_eq!(captured_a, captured_b, "the same captures on both hosts");

    // A remote ticker holds the world: a second one, on either host, is
    // refused naming it (its node on its host, its pid there).
    let holder = hosts.b.client(
        &world,
        "10",
        &["tick", "--rate", "20", "--leave-sync", "--json"],
    );
    holder.wait_line("\"frame\"", LONG);
    let (node, pid) = status_ticker(&hosts, &world).expect("the remote ticker holds the world");
    assert_eq!(
        u64::from(holder.pid()),
        pid,
        "the remote ticker's pid is reported"
    );
    assert!(
        node.ends_with("/sim-client-tick"),
        "reported as host/node: {node}"
    );
    for host in [&hosts.a, &hosts.b] {
        let second = host
            .client(&world, "10", &["tick", "--count", "1"])
            .finish(LONG);
        assert!(!second.status.success(), "{second}");
        assert!(
            second.stderr.contains(&node) && second.stderr.contains(&pid.to_string()),
            "the refusal names the remote owner {node} (pid {pid}):\n{second}"
        );
    }

    // The link drops: the remote ticker fails with a clear error, the
    // server releases the ownership held for it.
    let down = Instant::now();
    hosts.b.set_link(false);
    let failed = holder.finish(LONG);
    assert!(!failed.status.success(), "{failed}");
    assert!(
        failed.stderr.contains("cannot reach") || failed.stderr.contains("did not answer"),
        "the remote ticker says why it stopped:\n{failed}"
    );
    let failed_after = down.elapsed();
    while status_ticker(&hosts, &world).is_some() {
        assert!(
            down.elapsed() < LONG,
            "the server kept the lost remote ticker's ownership"
        );
    }
    let released_after = down.elapsed();
    eprintln!(
        "remote ticker failed after {failed_after:?}, ownership released after {released_after:?}"
    );
    let before: u64 = {
        let status = hosts
            .a
            .client(&world, "10", &["status", "--json"])
            .finish(LONG);
        status.json()[0]["frame"].as_u64().expect("frame")
    };

    // The link comes back: a new ticker there continues from the next frame.
    hosts.b.set_link(true);
    bridge.mirror.wait_line("link up", LONG);
    let next = hosts
        .b
        .client(&world, "20", &["tick", "--count", "1", "--json"])
        .finish(LONG);
    next.assert_success();
    assert_eq!(next.json()[0]["frame"].as_u64(), Some(before + 1), "{next}");
}

#[test]
fn a_mirror_of_a_world_nobody_exports_says_so() {
    let hosts = TwoHosts::new("zn");
    let world = unique_world("zn");
    let endpoint = format!("tcp/{}:7447", hosts.a.address());
    // Something listens there, but it exports another world.
    let _server = hosts.a.spawn("sim-server", &["--world", &world]);
    let exporter = hosts
        .a
        .client(&world, "20", &["bridge", "zenoh", "--listen", &endpoint]);
    exporter.wait_line("exporting world", LONG);
    let other = unique_world("zn-other");
    let mirror = hosts
        .b
        .client(&other, "2", &["bridge", "zenoh", "--connect", &endpoint])
        .finish(LONG);
    mirror.assert_code(1);
    assert!(
        mirror
            .stderr
            .contains(&format!("no bridge exports world '{other}'")),
        "{mirror}"
    );
    // Refused before anything starts: bad endpoint, bad lease.
    let bad = hosts
        .b
        .client(&world, "2", &["bridge", "zenoh", "--connect", "nonsense"])
        .finish(LONG);
    assert!(!bad.status.success(), "{bad}");
    assert!(bad.stderr.contains("nonsense"), "{bad}");
    let config = simbus_tests::Scratch::new("zn");
    let broken = config.write("broken.json5", b"{ mode: ");
    let refused = hosts
        .b
        .client(
            &world,
            "2",
            &["bridge", "zenoh", "--connect", &endpoint, "--zenoh-config"],
        )
        .finish(LONG);
    assert!(!refused.status.success(), "{refused}");
    let refused = hosts
        .b
        .client(
            &world,
            "2",
            &[
                "bridge",
                "zenoh",
                "--connect",
                &endpoint,
                "--zenoh-config",
                broken.to_str().expect("path"),
            ],
        )
        .finish(LONG);
    refused.assert_code(2);
    assert!(refused.stderr.contains("broken.json5"), "{refused}");
    // A good file is used: a mirror in client mode, no scouting, reaches the exporter.
    let client_mode = config.write(
        "client.json5",
        b"{ mode: \"client\", scouting: { multicast: { enabled: false } } }",
    );
    let mirror = hosts.b.client(
        &world,
        "10",
        &[
            "bridge",
            "zenoh",
            "--connect",
            &endpoint,
            "--zenoh-config",
            client_mode.to_str().expect("path"),
        ],
    );
    mirror.wait_line("mirroring world", LONG);
    let lease = hosts
        .b
        .client(
            &world,
            "2",
            &["bridge", "zenoh", "--connect", &endpoint, "--lease-ms", "5"],
        )
        .finish(LONG);
    lease.assert_code(2);
}

#[test]
fn the_export_goes_on_with_a_server_resumed_from_its_journal_and_the_remote_ticker_keeps_the_world()
{
    let hosts = TwoHosts::new("zr");
    let world = unique_world("zr");
    let scratch = simbus_tests::Scratch::new("zr");
    let journal = scratch.file("journal");
    let journal = journal.to_str().expect("a UTF-8 path");
    let mut bridge = hosts.mirrored(
        &world,
        &["--sync", "--delta-seconds", "0.05", "--journal", journal],
        &[],
    );
    // A remote ticker holds the world and ticks every 4 s: the restart
    // comes and goes between two of its ticks.
    let holder = hosts.b.client(
        &world,
        "20",
        &["tick", "--rate", "0.25", "--count", "3", "--json"],
    );
    let first: serde_json::Value =
        serde_json::from_str(&holder.wait_line("\"frame\"", LONG)).expect("a tick line");
    let first = first["frame"].as_u64().expect("frame");
    let watch = hosts.b.client(&world, "20", &["watch", "--json"]);
    watch.wait_line(&format!("\"frame\":{first}"), LONG);

    bridge.server.guard.kill().expect("killing the server");
    let _resumed = hosts.a.spawn("sim-server", &["--resume", journal]);
    bridge.exporter.wait_line(
        &format!("resumed at frame {first}; exporting goes on"),
        LONG,
    );
    bridge.mirror.wait_line("link up", LONG);

    // The same ticker ticks on: the exporter claimed the resumed world
    // again for it, and the mirror's clients read on.
    let (ticked, frames) = ticked_frames(holder, LONG);
    // (Its first tick's line was read above.)
    assert_eq!(frames, vec![first + 1, first + 2], "{ticked}");
    watch.wait_line(&format!("\"frame\":{}", first + 2), LONG);
}
