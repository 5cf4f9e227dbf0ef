//! `sim-client foxglove` refuses what it cannot serve (the protocol itself is
//! checked by a Python Foxglove client in `tests/python/test_foxglove.py`).

use simbus_tests::TestWorld;

#[test]
fn foxglove_refuses_a_bad_rate_and_a_taken_port_and_needs_a_server() {
    let world = TestWorld::start("foxglove-bad", &[]);
    let refused = world.cli(&["foxglove", "--port", "0", "--max-hz=-1"]);
    refused.assert_code(2);
    assert!(refused.stderr.contains("--max-hz"), "{refused}");

    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("a port");
    let port = taken.local_addr().expect("its address").port().to_string();
    let busy = world.cli(&["foxglove", "--port", &port]);
    busy.assert_code(1);
    assert!(
        busy.stderr
            .contains(&format!("listening on 127.0.0.1:{port}")),
        "{busy}"
    );

    simbus_tests::assert_fails_without_server(
        &simbus_tests::unique_world("foxglove-none"),
        &["foxglove", "--port", "0"],
    );
}
