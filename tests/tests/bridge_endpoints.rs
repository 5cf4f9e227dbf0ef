//! `bridge zenoh` on one machine, at its edges: a malformed endpoint is
//! refused (exit 2) saying the form it needs (it dumped Zenoh's JSON5
//! parser error, with paths into the build machine's cargo registry); a
//! mirror waits the whole `--timeout` for its exporter, so one started
//! first mirrors the world once the exporter is up (it gave up after
//! Zenoh's first failed connection, half a second, whatever `--timeout`
//! said); Zenoh's own warnings stay off the user's stderr unless
//! asked for (RUST_LOG, -v); and an exporter still waiting for its
//! world's server stops on Ctrl-C (it waited out its whole `--timeout`).

use std::process::{Command, Stdio};
use std::time::Duration;

use simbus_tests::{bin, client, unique_world, ChildGuard, PrivateRoot, TestWorld};

const LONG: Duration = Duration::from_secs(30);

/// A TCP port nothing listens on (bound by the kernel, then let go).
fn idle_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

#[test]
fn a_malformed_endpoint_is_refused_saying_the_form_it_needs() {
    let world = unique_world("zenoh-endpoint");
    for flag in ["--listen", "--connect"] {
        for bad in [
            "garbage",
            "tcp/127.0.0.1",
            "127.0.0.1:7447",
            "tcp/host:port",
        ] {
            let out = client(&world, &["--timeout", "1", "bridge", "zenoh", flag, bad]);
            out.assert_code(2);
            assert!(
                out.stderr.contains(&format!(
                    "{flag} '{bad}' is not a Zenoh endpoint: give PROTOCOL/HOST:PORT, e.g. tcp/"
                )),
                "{out}"
            );
            for leak in [".cargo", "Json5", "json5"] {
                assert!(!out.stderr.contains(leak), "{out}");
            }
        }
    }
}

#[test]
fn a_mirror_with_nothing_to_connect_to_fails_quietly_after_its_timeout() {
    // Run as a user would: RUST_LOG unset (the fixture sets it).
    let endpoint = format!("tcp/127.0.0.1:{}", idle_port());
    let world = unique_world("zenoh-idle");
    let root = PrivateRoot::new("zenoh-idle");
    let child = Command::new(bin("sim-client"))
        .args([
            "--world",
            &world,
            "--timeout",
            "2",
            "bridge",
            "zenoh",
            "--connect",
            &endpoint,
        ])
        .env_remove("RUST_LOG")
        .envs(root.env())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sim-client");
    let mut guard = ChildGuard::new(child, Duration::from_secs(1));
    let status = guard
        .wait_timeout(LONG)
        .expect("waiting")
        .expect("the mirror gave up by itself");
    let mut stderr = String::new();
    std::io::Read::read_to_string(
        guard.child_mut().stderr.as_mut().expect("stderr"),
        &mut stderr,
    )
    .expect("reading stderr");
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "no bridge exports world '{world}' at {endpoint} (nothing answered within 2s)"
        )),
        "{stderr}"
    );
    assert!(
        !stderr.contains("WARN"),
        "Zenoh's warnings are not shown: {stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "one line, the reason: {stderr}");
}

#[test]
fn a_mirror_started_before_its_exporter_mirrors_the_world_once_it_is_up() {
    let world = TestWorld::start("zenoh-late", &["--scene", "empty"]);
    let endpoint = format!("tcp/127.0.0.1:{}", idle_port());
    // The mirror in a root of its own: another host's shared memory.
    let root = PrivateRoot::new("zenoh-late");
    let mirror = root.client(
        world.name(),
        "30",
        &["bridge", "zenoh", "--connect", &endpoint],
    );
    // It asks for the world (it says so at the fixture's RUST_LOG=info)
    // before the exporter starts: nothing answers that first question.
    mirror.wait_stderr("asking for the world's status", LONG);
    let exporter = world.spawn_cli(&["bridge", "zenoh", "--listen", &endpoint]);
    exporter.wait_line("exporting world", LONG);
    let line = mirror.wait_line("mirroring world", LONG);
    assert!(
        line.contains(&format!(
            "mirroring world '{}' from {endpoint}",
            world.name()
        )),
        "{line}"
    );
}

#[test]
fn an_exporter_waiting_for_its_server_stops_on_ctrl_c() {
    let world = unique_world("zenoh-export-wait");
    let port = idle_port().to_string();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    // Nothing serves the world: the exporter would wait ten minutes.
    let exporter = simbus_tests::Proc::spawn_env(
        "sim-client",
        &[
            "--world",
            &world,
            "--timeout",
            "600",
            "bridge",
            "zenoh",
            "--listen",
            &endpoint,
        ],
        &[("RUST_LOG", std::ffi::OsStr::new("simbus_zenoh=info"))],
    );
    exporter.wait_stderr("waiting for the world's server", LONG);
    simbus_tests::send_signal(exporter.pid(), libc::SIGINT).expect("signalling the exporter");
    let out = exporter.finish(LONG);
    out.assert_code(0);
    assert!(!out.stderr.contains("panicked"), "{out}");
}
