//! `carla-gateway` stops on Ctrl-C (SIGINT) and SIGTERM with a CARLA
//! client connected and idle: exit status 0 and "carla-gateway stopped".
//! Until then it waits for connections and for its stop on events alone:
//! the thread that accepts CARLA clients does not wake while nobody
//! connects. (It woke every 100 ms to read a stop flag.)

use std::net::TcpStream;
use std::time::Duration;

use simbus_tests::{send_signal, Proc, TestWorld};

const T: Duration = Duration::from_secs(30);

/// A gateway of `world` on free ports, and its RPC and streaming ports.
fn gateway(world: &TestWorld) -> (Proc, u16, u16) {
    let (gateway, json) = world.spawn_gateway(&[]);
    let port = |key: &str| {
        json[key]
            .as_u64()
            .and_then(|p| u16::try_from(p).ok())
            .unwrap_or_else(|| panic!("no {key}: {json}"))
    };
    let (rpc, streams) = (port("port"), port("streaming_port"));
    (gateway, rpc, streams)
}

/// Connects an idle CARLA client to both ports (it sends nothing) and
/// waits until the gateway serves it.
fn idle_clients(gateway: &Proc, rpc: u16, streams: u16) -> (TcpStream, TcpStream) {
    let client = TcpStream::connect(("127.0.0.1", rpc)).expect("the RPC port");
    gateway.wait_stderr("CARLA client connected", T);
    let stream = TcpStream::connect(("127.0.0.1", streams)).expect("the streaming port");
    (client, stream)
}

/// The voluntary context switches of process `pid`'s main thread: how
/// often it blocked, that is went to sleep to wait.
fn main_thread_sleeps(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/status"))
        .expect("the main thread's status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("voluntary_ctxt_switches:"))
        .and_then(|n| n.trim().parse().ok())
        .expect("voluntary_ctxt_switches")
}

#[test]
fn sigterm_and_sigint_stop_a_gateway_with_an_idle_client_connected() {
    let world = TestWorld::start("gw-stop", &["--scene", "empty"]);
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let (gateway, rpc, streams) = gateway(&world);
        let _clients = idle_clients(&gateway, rpc, streams);
        send_signal(gateway.pid(), signal).expect("signalling the gateway");
        let out = gateway.finish(T);
        out.assert_code(0);
        assert!(out.stderr.contains("carla-gateway stopped"), "{out}");
        assert!(!out.stderr.contains("panicked"), "{out}");
    }
}

#[test]
fn the_accepting_thread_sleeps_until_a_client_connects_or_the_stop() {
    // Frames paced at wall-clock speed: 50 of them span a second.
    let world = TestWorld::start(
        "gw-idle",
        &["--scene", "empty", "--delta-seconds", "0.02", "--realtime"],
    );
    let (gateway, rpc, streams) = gateway(&world);
    let _clients = idle_clients(&gateway, rpc, streams);
    let mut watcher = world.connect();
    watcher.set_every_frame(true);
    let first = watcher.wait_for_frame(T).expect("a frame").frame();
    let before = main_thread_sleeps(gateway.pid());
    // While the world runs 50 frames, nobody connects and nothing stops
    // the gateway: its main thread (it accepts the clients) stays asleep.
    // It may still have been on its way to sleep at `before`: one more.
    while watcher.wait_for_frame(T).expect("a frame").frame() < first + 50 {}
    let woke = main_thread_sleeps(gateway.pid()) - before;
    assert!(
        woke <= 1,
        "the gateway's accepting thread woke {woke} times in 50 frames with nothing to do"
    );
    // It still wakes for the stop.
    send_signal(gateway.pid(), libc::SIGTERM).expect("signalling the gateway");
    let out = gateway.finish(T);
    out.assert_code(0);
    assert!(out.stderr.contains("carla-gateway stopped"), "{out}");
}
