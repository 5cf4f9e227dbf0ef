//! The floors of the tick's message shapes: raw iceoryx2 carrying a tick
//! and its frame between two spinning processes, with an empty world's
//! step in between, and no simbus server or client.
//!
//! - [`Shape::Request`]: simbus's shape. The tick is a request on the
//!   world's tick service (its description, `WorldServices::tick`), its
//!   doorbell rung; the answer is the frame, published on the frames
//!   service (history 1, as every new subscriber gets the current frame)
//!   with the frame-ready event rung; the request is dropped unanswered,
//!   as a tick sent [`TickRequest::BY_FRAME`] is.
//! - [`Shape::RequestNoHistory`]: the same, the frames without history.
//! - [`Shape::Publish`]: the tick as a sample on a publish-subscribe
//!   service with one publisher, the frame on a frames service without
//!   history, no events rung.
//! - [`Shape::RequestBlock`]: simbus's shape as [`Shape::Request`], both
//!   ends asleep between messages: the peer on the doorbell's event, the
//!   ticking end on the frame-ready event (`simbus_transport::Bus`'s futex
//!   under both), as a blocking server and ticker are.
//! - [`Shape::RequestFutex`]: the tick a request as in [`Shape::Request`],
//!   but no event rung either way: both ends asleep between messages, the
//!   wake-ups handed over as the futex floor hands its counter
//!   (`crate::futex`: a word on a shared page each way, `FUTEX_WAKE` and
//!   `FUTEX_WAIT`); the frame published with history.
//! - [`Shape::FutexBlock`]: the same wake-ups with no request: the tick is
//!   the futex word itself. The least a blocking tick with a stepped,
//!   published frame costs when the handoff is not an iceoryx2 port.
//!
//! Against the raw ping-pong of a `u64` with a step (the tick table's
//! `raw iox2 spin + step`), the rows say what each part of the message
//! shape costs and what simbus's own code adds on top (`simbus, spin, by
//! frame`).

use std::time::{Duration, Instant};

use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client as RequestClient;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use shared_types::limits::WorldLimits;
use shared_types::{
    frame_slice_len, ActorState, Doorbell, FrameHeader, ServiceNames, TickRequest, TickRequestKind,
    TickResponse, WorldName,
};
use simbus_transport::frame_sample::send_frame;
use simbus_transport::spec::{EventSpec, WorldServices};
use simbus_transport::Bus;

use crate::futex::SharedWords;

/// Which shape a row and its peer use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Shape {
    /// A request on the tick service, the frame published with history.
    Request,
    /// A request on the tick service, the frame published without history.
    RequestNoHistory,
    /// A tick sample on its own publish-subscribe service, the frame
    /// published without history.
    Publish,
    /// [`Shape::Request`] with both ends asleep on their events between
    /// messages.
    RequestBlock,
    /// A tick request, both ends asleep on futex words (no events); the
    /// frame published with history.
    RequestFutex,
    /// The tick and the frame's arrival as futex words, both ends asleep
    /// between them; the frame published with history.
    FutexBlock,
}

impl Shape {
    /// Whether both ends hand their wake-ups over as futex words.
    fn futex(self) -> bool {
        matches!(self, Self::RequestFutex | Self::FutexBlock)
    }

    /// The peer kind (`peer --kind`) that answers this shape.
    pub(crate) fn peer_kind(self) -> &'static str {
        match self {
            Self::Request => "shape-request",
            Self::RequestNoHistory => "shape-request-no-history",
            Self::Publish => "shape-publish",
            Self::RequestBlock => "shape-request-block",
            Self::RequestFutex => "shape-request-futex",
            Self::FutexBlock => "shape-futex-block",
        }
    }

    /// The shape a peer kind answers.
    pub(crate) fn of_peer(kind: &str) -> Option<Self> {
        [
            Self::Request,
            Self::RequestNoHistory,
            Self::Publish,
            Self::RequestBlock,
            Self::RequestFutex,
            Self::FutexBlock,
        ]
        .into_iter()
        .find(|s| s.peer_kind() == kind)
    }
}

fn err(e: impl std::fmt::Debug) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// The world's service descriptions, the frames without history in every
/// shape but [`Shape::Request`].
fn services(world: &str, shape: Shape) -> anyhow::Result<WorldServices> {
    let names = ServiceNames::new(&WorldName::new(world)?);
    let mut services = WorldServices::new(&names)?;
    if matches!(shape, Shape::RequestNoHistory | Shape::Publish) {
        services.frames.history = 0;
    }
    Ok(services)
}

/// The publish-subscribe service of the `publish` shape's ticks.
fn tick_topic(
    node: &Node<Bus>,
    world: &str,
) -> anyhow::Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Bus, TickRequest, ()>,
> {
    node.service_builder(&ServiceName::new(&format!("{world}/tick-topic")).map_err(err)?)
        .publish_subscribe::<TickRequest>()
        .max_publishers(1)
        .history_size(0)
        .subscriber_max_buffer_size(4)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(err)
}

/// How a tick goes out in each shape (the request's ports boxed: they are
/// large beside a publisher).
enum TickPort {
    /// A request, its doorbell rung unless the wake-up is a futex word.
    Request {
        client: Box<RequestClient<Bus, TickRequest, (), TickResponse, ()>>,
        wake: Option<Box<Notifier<Bus>>>,
    },
    Publish(Publisher<Bus, TickRequest, ()>),
    /// No message: the futex word is the tick.
    Word,
}

/// The futex words of a shape whose wake-ups are words: `ping` carries the
/// tick's number, `pong` the answered one.
struct Handoff {
    words: SharedWords,
    sent: u32,
}

/// A listener of the event `spec` describes.
fn listener(spec: &EventSpec, node: &Node<Bus>) -> anyhow::Result<Listener<Bus>> {
    spec.open_or_create(node, &WorldLimits::default())
        .map_err(err)?
        .listener_builder()
        .create()
        .map_err(err)
}

/// The file of the futex words of `world`'s row.
fn futex_words_path(world: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("simbus-bench-{world}-words"))
}

/// The ticking end of a shape row: one round trip per call.
pub(crate) struct Ticking {
    tick: TickPort,
    frames: Subscriber<Bus, [ActorState], FrameHeader>,
    /// The frame-ready event's listener where the ticking end sleeps
    /// ([`Shape::RequestBlock`]).
    ready: Option<Listener<Bus>>,
    /// The futex words ([`Shape::futex`]).
    handoff: Option<Handoff>,
    request: TickRequest,
    frame: u64,
    _node: Node<Bus>,
}

impl Ticking {
    /// Opens the ticking end of `shape` on `world` (the peer must be up).
    pub(crate) fn open(world: &str, shape: Shape) -> anyhow::Result<Self> {
        let services = services(world, shape)?;
        let node = simbus_transport::node("simbus-bench-shape").map_err(err)?;
        let limits = WorldLimits::default();
        let tick = match shape {
            Shape::Request
            | Shape::RequestNoHistory
            | Shape::RequestBlock
            | Shape::RequestFutex => TickPort::Request {
                client: Box::new(
                    services
                        .tick
                        .open_or_create(&node, &limits)
                        .map_err(err)?
                        .client_builder()
                        .create()
                        .map_err(err)?,
                ),
                wake: match shape {
                    Shape::RequestFutex => None,
                    _ => Some(Box::new(
                        services
                            .control_wake
                            .open_or_create(&node, &limits)
                            .map_err(err)?
                            .notifier_builder()
                            .create()
                            .map_err(err)?,
                    )),
                },
            },
            Shape::Publish => TickPort::Publish(
                tick_topic(&node, world)?
                    .publisher_builder()
                    .create()
                    .map_err(err)?,
            ),
            Shape::FutexBlock => TickPort::Word,
        };
        let handoff = if shape.futex() {
            let path = futex_words_path(world);
            let words = SharedWords::map(&path)?;
            // The peer mapped the page before it said it was ready.
            let _ = std::fs::remove_file(path);
            Some(Handoff { words, sent: 0 })
        } else {
            None
        };
        let frames = services
            .frames
            .open_or_create(&node, &limits)
            .map_err(err)?;
        let frames = services.frames.subscriber(&frames).map_err(err)?;
        let ready = (shape == Shape::RequestBlock)
            .then(|| listener(&services.frame_ready, &node))
            .transpose()?;
        Ok(Self {
            tick,
            frames,
            ready,
            handoff,
            request: TickRequest::new(TickRequestKind::Tick, "simbus-bench-shape"),
            frame: 0,
            _node: node,
        })
    }

    /// Sends a tick and waits until its frame is held: asleep on the
    /// answer's futex word ([`Shape::futex`]) or on the frame-ready event
    /// ([`Shape::RequestBlock`]), spinning on the frames in the others.
    pub(crate) fn round_trip(&mut self) -> anyhow::Result<()> {
        let request = TickRequest {
            flags: TickRequest::BY_FRAME,
            ..self.request
        };
        let _pending: Option<PendingResponse<Bus, TickRequest, (), TickResponse, ()>> =
            match &self.tick {
                TickPort::Request { client, wake } => {
                    let pending = client.send_copy(request).map_err(err)?;
                    if let Some(wake) = wake {
                        wake.notify_with_custom_event_id(EventId::new(Doorbell::Tick.event_id()))
                            .map_err(err)?;
                    }
                    Some(pending)
                }
                TickPort::Publish(publisher) => {
                    publisher.send_copy(request).map_err(err)?;
                    None
                }
                TickPort::Word => None,
            };
        if let Some(Handoff { words, sent }) = &mut self.handoff {
            *sent = sent.wrapping_add(1);
            words.ping_pong(*sent);
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(sample) = self.frames.receive().map_err(err)? {
                let frame = sample.user_header().timestamp.frame;
                if frame > self.frame {
                    self.frame = frame;
                    return Ok(());
                }
                continue;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            anyhow::ensure!(!left.is_zero(), "the shape peer stopped answering");
            match &self.ready {
                Some(ready) => {
                    ready.timed_wait(|_| {}, left).map_err(err)?;
                }
                None => std::hint::spin_loop(),
            }
        }
    }
}

/// The answering end (`peer --kind` [`Shape::peer_kind`]): steps an empty
/// world for every tick and publishes its frame, until stopped.
pub(crate) fn peer(world: &str, shape: Shape) -> anyhow::Result<()> {
    use sim_server::world::World;
    let services = services(world, shape)?;
    let node = simbus_transport::node("simbus-bench-shape-peer").map_err(err)?;
    let limits = WorldLimits::default();
    let (mut world_state, plan) = crate::support::empty_world();
    let frames = services
        .frames
        .open_or_create(&node, &limits)
        .map_err(err)?;
    let publisher = services
        .frames
        .publisher(&frames, frame_slice_len(world_state.actor_count()))
        .map_err(err)?;
    let ready = services
        .frame_ready
        .open_or_create(&node, &limits)
        .map_err(err)?
        .notifier_builder()
        .create()
        .map_err(err)?;
    let mut frame = 0u64;
    let publish = |frame: u64, world_state: &mut World| -> anyhow::Result<()> {
        world_state.step(&plan);
        let mut header = FrameHeader::default();
        header.timestamp.frame = frame;
        let state = &*world_state;
        send_frame(&publisher, header, state.actor_count(), |i| {
            state.actor_state(i)
        })?;
        Ok(())
    };
    match shape {
        Shape::Request | Shape::RequestNoHistory | Shape::RequestBlock | Shape::RequestFutex => {
            // Asleep on the doorbell between ticks in the blocking shape,
            // on the futex word in the futex one.
            let doorbell = (shape == Shape::RequestBlock)
                .then(|| listener(&services.control_wake, &node))
                .transpose()?;
            let server = services
                .tick
                .open_or_create(&node, &limits)
                .map_err(err)?
                .server_builder()
                .create()
                .map_err(err)?;
            let words = if shape.futex() {
                Some(SharedWords::map(&futex_words_path(world))?)
            } else {
                None
            };
            println!("ready");
            let (mut last, mut woken) = (0, false);
            loop {
                if let (Some(words), false) = (&words, woken) {
                    last = words.next_ping(last);
                    woken = true;
                }
                let Some(request) = server.receive().map_err(err)? else {
                    match (&words, &doorbell) {
                        // Sent before its word was posted: there once woken,
                        // so the word is not waited on again until it is.
                        (Some(_), _) => {}
                        (None, Some(doorbell)) => {
                            doorbell.blocking_wait(|_| {}).map_err(err)?;
                        }
                        (None, None) => std::hint::spin_loop(),
                    }
                    continue;
                };
                frame += 1;
                publish(frame, &mut world_state)?;
                woken = false;
                match &words {
                    Some(words) => words.answer(last),
                    None => {
                        ready.notify().map_err(err)?;
                    }
                }
                drop(request);
            }
        }
        Shape::FutexBlock => {
            let words = SharedWords::map(&futex_words_path(world))?;
            println!("ready");
            let mut last = 0;
            loop {
                last = words.next_ping(last);
                frame += 1;
                publish(frame, &mut world_state)?;
                words.answer(last);
            }
        }
        Shape::Publish => {
            let ticks = tick_topic(&node, world)?
                .subscriber_builder()
                .create()
                .map_err(err)?;
            println!("ready");
            loop {
                if ticks.receive().map_err(err)?.is_none() {
                    std::hint::spin_loop();
                    continue;
                }
                frame += 1;
                publish(frame, &mut world_state)?;
            }
        }
    }
}
