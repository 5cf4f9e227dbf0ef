//! `simbus-forger WORLD PID participant|ticker`: a hostile client for the
//! tests. It opens the world's lockstep or tick service with the wire
//! types, as any process of the same user can, joins the lockstep or claims
//! the ticker writing `PID` (another, living process) as its own in every
//! field that holds one, prints `joined` or `claimed` with the server's
//! answer, and then waits until it is killed.
//!
//! What it proves (`tests/tests/hostile.rs`): the server keys membership,
//! ownership and liveness by the sending port's process, so the forger's
//! death ends both, however long the process it named lives.

use std::time::{Duration, Instant};

use shared_types::{
    LockstepKind, LockstepRequest, ServiceNames, TickRequest, TickRequestKind, WorldName,
};
use simbus_transport::spec::WorldServices;

const ANSWER: Duration = Duration::from_secs(10);

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, world, pid, mode] = args.as_slice() else {
        eprintln!("usage: simbus-forger WORLD PID participant|ticker");
        std::process::exit(2);
    };
    let world = WorldName::new(world).expect("a world name");
    let pid: u32 = pid.parse().expect("a pid");
    let names = ServiceNames::new(&world);
    let specs = WorldServices::new(&names).expect("service names");
    let node = simbus_transport::node("forger").expect("a node");
    let wake = specs
        .control_wake
        .open(&node)
        .expect("the wake event")
        .notifier_builder()
        .create()
        .expect("a notifier");
    let status = match mode.as_str() {
        "participant" => {
            let port = specs
                .lockstep
                .open(&node)
                .expect("the lockstep service")
                .client_builder()
                .create()
                .expect("a lockstep port");
            let request = LockstepRequest {
                pid,
                ..LockstepRequest::new(LockstepKind::Join, "forger", 0, 0)
            };
            let pending = port.send_copy(request).expect("send");
            wake.notify().expect("wake");
            let answer = answer(|| pending.receive().expect("receive").map(|r| r.status));
            println!("joined {answer}");
            park(port)
        }
        "ticker" => {
            let port = specs
                .tick
                .open(&node)
                .expect("the tick service")
                .client_builder()
                .create()
                .expect("a tick port");
            let request = TickRequest {
                pid,
                ..TickRequest::new(TickRequestKind::Claim, "forger")
            };
            let pending = port.send_copy(request).expect("send");
            wake.notify().expect("wake");
            let answer = answer(|| pending.receive().expect("receive").map(|r| r.status));
            println!("claimed {answer}");
            park(port)
        }
        other => {
            eprintln!("unknown mode {other}: participant or ticker");
            2
        }
    };
    std::process::exit(status);
}

/// The first answer `receive` gives within [`ANSWER`].
fn answer(mut receive: impl FnMut() -> Option<u32>) -> u32 {
    let deadline = Instant::now() + ANSWER;
    loop {
        if let Some(status) = receive() {
            return status;
        }
        assert!(Instant::now() < deadline, "no answer within {ANSWER:?}");
        std::thread::yield_now();
    }
}

/// Holds `port` open until the process is killed.
fn park<T>(_port: T) -> i32 {
    loop {
        std::thread::park();
    }
}
