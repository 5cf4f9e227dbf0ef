//! The other ends of the tick table's baselines and their exchanges: raw
//! iceoryx2 ping-pong (a `u64` there and back, on iceoryx2's own event or
//! simbus's futex `Bus`, optionally stepping an empty world before each
//! answer) and CARLA's tick over TCP loopback (an 8-byte tick, a frame
//! header back).

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::Service;
use shared_types::FrameHeader;
use simbus_process::ChildGuard;
use simbus_transport::Bus;

use crate::support::spawn_peer;

pub(crate) struct RawPorts<S: Service> {
    _node: Node<S>,
    tx: Publisher<S, u64, ()>,
    rx: Subscriber<S, u64, ()>,
    notifier: Notifier<S>,
    listener: Listener<S>,
}

/// Opens `name/{a,b}` pub-sub and `name/{a,b}/event`; `side` sends on one and
/// receives on the other.
pub(crate) fn raw_ports<S: Service>(
    name: &str,
    send_on: &str,
    receive_on: &str,
) -> anyhow::Result<RawPorts<S>> {
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<S>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let pubsub = |n: String| -> anyhow::Result<_> {
        node.service_builder(&ServiceName::new(&n).map_err(|e| anyhow::anyhow!("{e:?}"))?)
            .publish_subscribe::<u64>()
            .open_or_create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))
    };
    let event = |n: String| -> anyhow::Result<_> {
        node.service_builder(&ServiceName::new(&n).map_err(|e| anyhow::anyhow!("{e:?}"))?)
            .event()
            .open_or_create()
            .map_err(|e| anyhow::anyhow!("{e:?}"))
    };
    let tx = pubsub(format!("{name}/{send_on}"))?
        .publisher_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let rx = pubsub(format!("{name}/{receive_on}"))?
        .subscriber_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let notifier = event(format!("{name}/{send_on}/event"))?
        .notifier_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let listener = event(format!("{name}/{receive_on}/event"))?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok(RawPorts {
        _node: node,
        tx,
        rx,
        notifier,
        listener,
    })
}

impl<S: Service> RawPorts<S> {
    pub(crate) fn send(&self, value: u64, notify: bool) -> anyhow::Result<()> {
        self.tx
            .send_copy(value)
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        if notify {
            self.notifier
                .notify()
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        }
        Ok(())
    }

    pub(crate) fn receive(&self, block: bool) -> anyhow::Result<u64> {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(sample) = self.rx.receive().map_err(|e| anyhow::anyhow!("{e:?}"))? {
                return Ok(*sample.payload());
            }
            anyhow::ensure!(
                Instant::now() < deadline,
                "ping-pong peer stopped answering"
            );
            if block {
                // A SIGCONT (the bench stops peers between their slices)
                // interrupts iceoryx2's socket wait: look again.
                match self.listener.timed_wait(|_| {}, Duration::from_millis(100)) {
                    Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => {}
                    Err(e) => anyhow::bail!("{e:?}"),
                }
            } else {
                std::hint::spin_loop();
            }
        }
    }
}

/// The TCP baseline's other end: a frame header back for every 8-byte tick.
pub(crate) fn tcp_echo() -> anyhow::Result<()> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    println!("{}", listener.local_addr()?.port());
    let (mut stream, _) = listener.accept()?;
    stream.set_nodelay(true)?;
    let frame = vec![0u8; std::mem::size_of::<FrameHeader>()];
    let mut tick = [0u8; 8];
    while stream.read_exact(&mut tick).is_ok() {
        stream.write_all(&frame)?;
    }
    Ok(())
}

/// The raw iceoryx2 baselines' other end (`iceoryx-spin`, `iceoryx-block`,
/// `iceoryx-bus-block`, and `iceoryx-spin-step`, which steps an empty
/// rapier world before each answer): echoes every value until stopped.
pub(crate) fn raw_peer(kind: &str, name: &str) -> anyhow::Result<()> {
    match kind {
        "iceoryx-bus-block" => raw_echo(raw_ports::<Bus>(name, "pong", "ping")?, true, false),
        kind => raw_echo(
            raw_ports::<ipc::Service>(name, "pong", "ping")?,
            kind == "iceoryx-block",
            kind == "iceoryx-spin-step",
        ),
    }
}

/// Echoes every value back until the other end stops; with `step`, after
/// a physics step of an empty world (what the server's frame costs rapier
/// in the simbus rows: one 0.01 s substep).
fn raw_echo<S: Service>(ports: RawPorts<S>, block: bool, step: bool) -> anyhow::Result<()> {
    let (mut world, plan) = crate::support::empty_world();
    println!("ready");
    loop {
        let value = ports.receive(block)?;
        if step {
            world.step(&plan);
        }
        ports.send(value, block)?;
    }
}

/// CARLA's per-tick exchange over TCP loopback (a tick request, a frame
/// header back) with a peer process: the peer, and one exchange.
pub(crate) fn tcp_exchange() -> anyhow::Result<(ChildGuard, impl FnMut() -> anyhow::Result<()>)> {
    let (peer, port) = spawn_peer("tcp", "tcp")?;
    let mut stream = TcpStream::connect(("127.0.0.1", port.parse::<u16>()?))?;
    stream.set_nodelay(true)?;
    let mut frame = vec![0u8; std::mem::size_of::<FrameHeader>()];
    let mut tick = 0u64;
    Ok((peer, move || {
        tick += 1;
        stream.write_all(&tick.to_le_bytes())?;
        stream.read_exact(&mut frame)?;
        Ok(())
    }))
}
