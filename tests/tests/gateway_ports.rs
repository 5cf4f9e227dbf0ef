//! `carla-gateway` says the ports it actually listens on: with `--port 0`
//! both the RPC and the streaming port are free ports the kernel picked,
//! named on its first line (`--json`: one JSON object) and answering; a
//! streaming port of `--port + 1` that would wrap past 65535 or land on a
//! privileged port is refused (exit 2) unless `--streaming-port` asks for
//! it. (It printed `127.0.0.1:0 (streams on port 1)` and bound port 1.)

use std::net::TcpStream;
use std::time::Duration;

use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(30);

/// Both ports accept a TCP connection.
fn assert_listening(port: u64, streaming_port: u64) {
    assert_ne!(port, 0, "the RPC port actually bound");
    assert_ne!(streaming_port, 0, "the streaming port actually bound");
    assert_ne!(port, streaming_port);
    for p in [port, streaming_port] {
        let p = u16::try_from(p).expect("a port");
        TcpStream::connect(("127.0.0.1", p))
            .unwrap_or_else(|e| panic!("nothing listens on port {p}: {e}"));
    }
}

#[test]
fn port_0_listens_on_two_free_ports_and_says_which() {
    let world = TestWorld::start("gw-port0", &["--scene", "empty"]);
    let (_gateway, json) = world.spawn_gateway(&[]);
    let line = json.to_string();
    assert_eq!(json["world"].as_str(), Some(world.name()), "{line}");
    assert_eq!(json["host"].as_str(), Some("127.0.0.1"), "{line}");
    assert_listening(
        json["port"].as_u64().expect("port"),
        json["streaming_port"].as_u64().expect("streaming_port"),
    );

    // The sentence names the same, real ports.
    let gateway = world.spawn_cli(&["carla-gateway", "--port", "0"]);
    let line = gateway.line(T).expect("the gateway's first line");
    let (_, rest) = line
        .split_once("on 127.0.0.1:")
        .unwrap_or_else(|| panic!("{line}"));
    let (port, rest) = rest.split_once(' ').unwrap_or_else(|| panic!("{line}"));
    let streaming = rest
        .strip_prefix("(streams on port ")
        .and_then(|r| r.strip_suffix(')'))
        .unwrap_or_else(|| panic!("{line}"));
    assert_listening(port.parse().unwrap(), streaming.parse().unwrap());
}

#[test]
fn a_streaming_port_past_65535_or_privileged_is_refused_unless_asked_for() {
    let world = TestWorld::start("gw-wrap", &["--scene", "empty"]);
    for (port, says) in [
        ("65535", "past 65535"),
        ("1000", "port 1001 (--port + 1), a privileged port"),
    ] {
        let out = world.cli(&["carla-gateway", "--port", port]);
        out.assert_code(2);
        assert!(out.stderr.contains(says), "{out}");
        assert!(out.stderr.contains("--streaming-port"), "{out}");
        assert!(out.stdout.is_empty(), "it never said it listens: {out}");
    }
    // Asked for: --port 0 with an explicit free streaming port.
    let free = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let gateway = world.spawn_cli(&[
        "carla-gateway",
        "--port",
        "0",
        "--streaming-port",
        &free.to_string(),
        "--json",
    ]);
    let line = gateway.line(T).expect("the gateway's first line");
    let json: serde_json::Value = serde_json::from_str(&line).unwrap();
    assert_eq!(
        json["streaming_port"].as_u64(),
        Some(u64::from(free)),
        "{line}"
    );
    assert_listening(json["port"].as_u64().unwrap(), u64::from(free));
}
