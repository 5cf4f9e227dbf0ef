//! `sim-client top`: what it reports of a live world — the ticker, a
//! lockstep participant, a sensor and its reader, every client's services,
//! rates and the server's shared memory — checked against the processes the
//! test started.

use std::time::Duration;

use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(20);

/// The entry of `pid` in the `clients` list.
fn client_of(screen: &serde_json::Value, pid: u32) -> &serde_json::Value {
    screen["clients"]
        .as_array()
        .expect("a client list")
        .iter()
        .find(|c| c["pid"] == pid)
        .unwrap_or_else(|| panic!("pid {pid} is not among the clients: {screen}"))
}

fn services(client: &serde_json::Value) -> Vec<&str> {
    client["services"]
        .as_array()
        .expect("services")
        .iter()
        .filter_map(|s| s.as_str())
        .collect()
}

#[test]
fn top_names_the_ticker_the_participant_the_reader_and_their_services() {
    let world = TestWorld::start("top", &["--scene", "default"]);
    let client = world.connect();
    let ticker = world.spawn_cli(&["tick", "--rate", "200"]);
    assert!(
        ticker.line(T).is_some(),
        "the ticker ticks: {}",
        ticker.stderr()
    );
    let watcher = world.spawn_cli(&["watch", "--lockstep"]);
    simbus_tests::wait_for_participants(&client, 1);
    let spawned = world.cli(&["sensor", "spawn", "imu"]);
    spawned.assert_success();
    let id = spawned
        .stdout
        .first()
        .and_then(|line| line.split_whitespace().last())
        .expect("the sensor's id")
        .to_owned();
    let reader = world.spawn_cli(&["sensor", "watch", &id]);
    assert!(
        reader.line(T).is_some(),
        "the reader reads: {}",
        reader.stderr()
    );

    let top = world.cli(&["top", "--once", "--json", "--interval", "0.3"]);
    top.assert_success();
    let screens = top.json();
    assert_eq!(screens.len(), 1, "--once prints one object: {top}");
    let screen = &screens[0];

    assert_eq!(screen["world"], world.name());
    assert_eq!(screen["server_pid"], world.server.pid());
    assert_eq!(screen["settings"]["synchronous_mode"], true);
    assert_eq!(screen["ticker"]["pid"], ticker.pid(), "{screen}");
    assert!(screen["frames_per_second"].as_f64().expect("a rate") > 0.0);
    assert!(screen["real_time_factor"].as_f64().expect("a factor") > 0.0);
    assert!(screen["shared_memory"]["files"].as_u64().expect("files") > 0);

    let participants = screen["participants"].as_array().expect("participants");
    assert_eq!(participants.len(), 1, "{screen}");
    assert_eq!(screen["participant_count"], 1);
    assert_eq!(participants[0]["pid"], watcher.pid(), "{screen}");
    assert_eq!(participants[0]["name"], "watch", "{screen}");
    assert!(participants[0]["done_frame"].as_u64().expect("a frame") > 0);
    // In synchronous mode a "done" always comes while its frame is current.
    assert!(
        participants[0]["done_after_us"].as_f64().expect("a wait") >= 0.0,
        "{screen}"
    );

    assert!(services(client_of(screen, ticker.pid())).contains(&"tick"));
    assert!(services(client_of(screen, watcher.pid())).contains(&"lockstep"));
    let sensor_service = format!("sensor/{id}");
    assert!(services(client_of(screen, reader.pid())).contains(&sensor_service.as_str()));
    assert!(
        !services(client_of(screen, watcher.pid())).contains(&"tick"),
        "only the ticker holds the tick port"
    );

    let sensors = screen["sensors"].as_array().expect("sensors");
    assert_eq!(sensors.len(), 1, "{screen}");
    assert_eq!(sensors[0]["id"].to_string(), id);
    assert_eq!(sensors[0]["kind"], "imu");
    let readers = sensors[0]["readers"].as_array().expect("readers");
    assert_eq!(readers.len(), 1, "{screen}");
    assert!(readers[0]
        .as_str()
        .expect("a label")
        .contains(&format!("(pid {})", reader.pid())));
    assert!(sensors[0]["captures_per_second"].as_f64().expect("a rate") > 0.0);
}

#[test]
fn top_refuses_a_bad_interval_and_fails_without_a_server() {
    let world = TestWorld::start("top-bad", &[]);
    let refused = world.cli(&["top", "--once", "--interval", "0"]);
    refused.assert_code(2);
    assert!(refused.stderr.contains("--interval"), "{refused}");
    simbus_tests::assert_fails_without_server(
        &simbus_tests::unique_world("top-none"),
        &["top", "--once"],
    );
}
