//! Limits: a watcher holds no command port, so twenty watchers leave
//! `status`, `spawn` and `tick` working; a client past the number of batch
//! senders a world admits gets an error naming that limit, never a bare
//! transport error.

use std::time::Duration;

use shared_types::limits::MAX_BATCH_CLIENTS;
use sim_client::{BatchError, Client, RequestError};
use simbus_tests::{client, server, unique_world, Proc};

const T: Duration = Duration::from_secs(30);

#[test]
fn twenty_watchers_leave_status_spawn_and_tick_working() {
    let world = unique_world("watchers");
    let _server = server(&world, &["--delta-seconds", "0.01", "--realtime"]);
    let watchers: Vec<Proc> = (0..20)
        .map(|_| Proc::spawn("sim-client", &["--world", &world, "watch"]))
        .collect();
    for watcher in &watchers {
        assert!(watcher.line(T).is_some(), "watching: {}", watcher.stderr());
    }
    client(&world, &["status"]).assert_success();
    client(&world, &["spawn", "box"]).assert_success();
    client(&world, &["tick", "--count", "2"]).assert_success();
    for watcher in &watchers {
        assert!(
            watcher.line(T).is_some(),
            "still watching: {}",
            watcher.stderr()
        );
    }
}

#[test]
fn a_batch_sender_past_the_limit_is_told_which_limit() {
    let world = unique_world("batch-limit");
    let _server = server(&world, &["--delta-seconds", "0.01", "--realtime"]);
    let senders: Vec<Client> = (0..MAX_BATCH_CLIENTS)
        .map(|_| {
            let c = Client::connect(&world, T).unwrap();
            c.apply_batch_sync(&[], false).unwrap();
            c
        })
        .collect();
    let one_more = Client::connect(&world, T).unwrap();
    one_more
        .status()
        .expect("a client past the batch limit still asks status");
    match one_more.apply_batch_sync(&[], false) {
        Err(BatchError::Request(e @ RequestError::Full { .. })) => {
            let message = e.to_string();
            assert!(
                message.contains("clients sending command batches")
                    && message.contains(&MAX_BATCH_CLIENTS.to_string()),
                "{message}"
            );
        }
        other => panic!("expected the limit to be named, got {other:?}"),
    }
    drop(senders);
}
