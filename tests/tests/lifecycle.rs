//! Process lifecycle: no server is a clear error within the timeout, and
//! Ctrl-C ends the wait for one; a server killed with SIGKILL is replaced
//! cleanly on the same world; a second live server on a world is refused;
//! two worlds run side by side unaware of each other.

use std::time::Duration;

use simbus_tests::{assert_fails_without_server, client, server, status, unique_world, Proc};

#[test]
fn a_client_without_a_server_fails_clearly_within_its_timeout() {
    let world = unique_world("nobody");
    assert_fails_without_server(&world, &["status"]);
    assert_fails_without_server(&world, &["watch", "--frames", "1"]);
}

#[test]
fn a_command_waiting_for_its_worlds_server_stops_on_ctrl_c() {
    let world = unique_world("ctrl-c-wait");
    let commands: [&[&str]; 3] = [&["status"], &["tick", "--count", "1"], &["watch"]];
    for command in commands {
        // Nothing serves the world: each would wait ten minutes.
        let mut args = vec!["--world", world.as_str(), "--timeout", "600"];
        args.extend(command);
        let waiting = Proc::spawn_env(
            "sim-client",
            &args,
            &[("RUST_LOG", std::ffi::OsStr::new("sim_client::open=debug"))],
        );
        waiting.wait_stderr("waiting for the world's server", Duration::from_secs(30));
        simbus_tests::send_signal(waiting.pid(), libc::SIGINT).expect("signalling");
        let out = waiting.finish(Duration::from_secs(30));
        out.assert_code(130);
        assert!(
            out.stderr.contains(&format!(
                "sim-client: interrupted: before the server of world '{world}' answered"
            )),
            "{command:?}: {out}"
        );
    }
}

#[test]
fn a_server_killed_with_sigkill_is_replaced_cleanly_on_the_same_world() {
    let world = unique_world("restart");
    let mut first = server(&world, &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let frame_before = status(&world)["frame"].as_u64().unwrap();
    assert!(frame_before < 1000);
    first.guard.kill().unwrap();

    // A client of the dead server learns it is gone instead of hanging.
    let out = client(&world, &["--timeout", "2", "status"]);
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);

    let second = server(
        &world,
        &["--fixed-delta-seconds", "0.02", "--scene", "empty"],
    );
    let now = status(&world);
    assert_eq!(now["server_pid"].as_u64(), Some(u64::from(second.pid())));
    assert_eq!(now["scene"], "empty");
    assert_eq!(now["fixed_delta_seconds"].as_f64(), Some(0.02));
    let out = client(&world, &["watch", "--frames", "3", "--json"]);
    out.assert_success();
    assert_eq!(out.json().len(), 3);
}

#[test]
fn a_second_server_on_a_live_world_is_refused() {
    let world = unique_world("two-servers");
    let first = server(&world, &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let second = Proc::spawn("sim-server", &["--world", &world]).finish(Duration::from_secs(30));
    assert!(!second.status.success());
    assert!(
        second
            .stderr
            .contains(&format!("world '{world}' already has a running server")),
        "{}",
        second.stderr
    );
    assert_eq!(
        status(&world)["server_pid"].as_u64(),
        Some(u64::from(first.pid())),
        "the first server still owns the world"
    );
}

#[test]
fn two_worlds_run_side_by_side_without_seeing_each_other() {
    let (a, b) = (unique_world("side-a"), unique_world("side-b"));
    let server_a = server(
        &a,
        &[
            "--scene",
            "empty",
            "--fixed-delta-seconds",
            "0.01",
            "--realtime",
        ],
    );
    let server_b = server(
        &b,
        &[
            "--scene",
            "boxes:20",
            "--fixed-delta-seconds",
            "0.02",
            "--realtime",
        ],
    );

    let (status_a, status_b) = (status(&a), status(&b));
    assert_eq!(
        status_a["server_pid"].as_u64(),
        Some(u64::from(server_a.pid()))
    );
    assert_eq!(
        status_b["server_pid"].as_u64(),
        Some(u64::from(server_b.pid()))
    );
    assert_eq!(status_a["actors"], 0);
    assert_eq!(status_b["actors"], 21);

    client(&a, &["config", "--delta-seconds", "0.03"]).assert_success();
    assert_eq!(status(&a)["fixed_delta_seconds"].as_f64(), Some(0.03));
    assert_eq!(status(&b)["fixed_delta_seconds"].as_f64(), Some(0.02));

    for (world, actors) in [(&a, 0), (&b, 21)] {
        let out = client(world, &["watch", "--frames", "5", "--json"]);
        out.assert_success();
        assert!(out.json().iter().all(|f| f["actors"] == actors));
    }
}

#[test]
fn the_demo_runs_a_server_watches_it_and_reaps_it() {
    let demo = Proc::spawn(
        "sim-client",
        &["demo", "--frames", "40", "--delta-seconds", "0.01"],
    );
    let out = demo.finish(Duration::from_secs(60));
    out.assert_success();
    let started = &out.stdout[0];
    assert!(
        started.starts_with("demo: started sim-server (pid "),
        "{started}"
    );
    let pid: u32 = started["demo: started sim-server (pid ".len()..]
        .split(')')
        .next()
        .and_then(|p| p.parse().ok())
        .expect("the server's pid");
    assert!(out
        .stdout
        .iter()
        .any(|l| l.contains("frame") && l.contains("cars")));
    let last = out.stdout.last().unwrap();
    assert!(
        last.starts_with("demo finished: watched 40 frames") && last.contains("exit status: 0"),
        "{last}"
    );
    assert!(
        !simbus_tests::process_alive(pid),
        "the demo's server is gone"
    );
}

/// The pid in the demo's first line, `demo: started sim-server (pid P) ...`.
fn demo_server_pid(line: &str) -> u32 {
    line.strip_prefix("demo: started sim-server (pid ")
        .and_then(|rest| rest.split(')').next())
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("not the demo's first line: {line}"))
}

#[test]
fn a_demo_killed_with_sigkill_takes_its_server_with_it() {
    let world = unique_world("demo-kill");
    let mut demo = Proc::spawn(
        "sim-client",
        &["--world", &world, "demo", "--frames", "100000"],
    );
    let first = demo
        .line(Duration::from_secs(30))
        .unwrap_or_else(|| panic!("the demo started: {}", demo.stderr()));
    assert!(
        first.contains(&format!("on world '{world}'")),
        "--world is used: {first}"
    );
    let server = demo_server_pid(&first);
    assert!(simbus_tests::process_alive(server));
    demo.guard.kill().unwrap();
    // The kernel sends the orphaned server SIGTERM; it finishes its frame
    // and exits (a server never reaped by us stays a zombie of init, which
    // process_alive counts as gone).
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while simbus_tests::process_alive(server) {
        assert!(
            std::time::Instant::now() < deadline,
            "the demo's server {server} outlived the demo"
        );
        std::thread::yield_now();
    }
}

#[test]
fn a_demo_with_a_scene_no_server_can_load_is_refused_before_starting_one() {
    // The scene grammar is shared: the demo refuses before it starts a
    // server (a server that exits at once is covered by `cli_words`).
    let out =
        Proc::spawn("sim-client", &["demo", "--scene", "boxes:0"]).finish(Duration::from_secs(30));
    assert_eq!(out.status.code(), Some(2), "{}", out.stderr);
    assert!(
        out.stderr.contains("boxes:N needs N in 1..=100000"),
        "{}",
        out.stderr
    );
    assert!(!out.stderr.contains("started sim-server"), "{}", out.stderr);
}

#[test]
fn a_stopped_server_is_reported_as_not_answering_not_as_missing() {
    let world = unique_world("sigstop");
    let server = server(&world, &[]);
    simbus_tests::send_signal(server.pid(), libc::SIGSTOP).unwrap();
    let out = Proc::spawn(
        "sim-client",
        &["--world", &world, "--timeout", "1", "status"],
    )
    .finish(Duration::from_secs(30));
    simbus_tests::send_signal(server.pid(), libc::SIGCONT).unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains(&format!(
            "the server of world '{world}' exists but did not answer within 1s"
        )),
        "{}",
        out.stderr
    );
}
