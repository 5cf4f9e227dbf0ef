//! Receiving frame snapshots: in order in synchronous mode, newest-first with a
//! missed count in asynchronous mode, blocking on the frame-ready event or
//! spinning.

use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use shared_types::limits::MAX_CLIENTS_FLAG;
use shared_types::{ActorState, FrameHeader, ServiceNames, PROTOCOL_VERSION};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;

use crate::open::{frame_ready_listener, open_with_retry};
use crate::snapshot::FrameView;
use crate::wait::{self, Stop, Wait};
use crate::WaitMode;
use crate::{ConnectError, WaitError};

type FrameSubscriber = Subscriber<Bus, [ActorState], FrameHeader>;
type FrameSample = Sample<Bus, [ActorState], FrameHeader>;

/// A subscription to a world's frames.
pub(crate) struct FrameStream {
    subscriber: FrameSubscriber,
    /// A frame taken off the queue by [`FrameStream::first_header`], handed
    /// out first.
    stash: Option<FrameSample>,
    ready: Listener<Bus>,
    /// (episode, frame) of the last snapshot handed out.
    last: Option<(u64, u64)>,
    pub(crate) mode: WaitMode,
    /// Hand out every queued frame in order, in asynchronous mode too.
    pub(crate) every_frame: bool,
}

impl FrameStream {
    /// Subscribes `node` to the frames of the world named by `names`.
    /// `Ok(None)` when the world's services did not appear before `deadline`.
    pub(crate) fn open(
        node: &Node<Bus>,
        names: &ServiceNames,
        world: &str,
        deadline: Instant,
    ) -> Result<Option<Self>, ConnectError> {
        use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError;
        let specs =
            WorldServices::new(names).map_err(|e| ConnectError::transport("service name", e))?;
        let frames = open_with_retry(
            deadline,
            || specs.frames.open(node),
            |e| {
                matches!(
                    e,
                    PublishSubscribeOpenError::DoesNotExist
                        | PublishSubscribeOpenError::HangsInCreation
                )
            },
        )
        .map_err(|e| match e {
            PublishSubscribeOpenError::IncompatibleTypes => ConnectError::ProtocolMismatch {
                world: world.to_owned(),
                detail: "its frame layout differs".to_owned(),
                client: PROTOCOL_VERSION,
            },
            e => ConnectError::transport("frames service", e),
        })?;
        let Some(frames) = frames else {
            return Ok(None);
        };
        let subscriber = specs.frames.subscriber(&frames).map_err(|e| match e {
            SubscriberCreateError::ExceedsMaxSupportedSubscribers => ConnectError::Full {
                world: world.to_owned(),
                what: "frame subscribers",
                max: frames.static_config().max_subscribers(),
                flag: MAX_CLIENTS_FLAG,
            },
            e => ConnectError::transport("frames subscriber", e),
        })?;
        let Some(ready) =
            frame_ready_listener(node, names, deadline).map_err(|e| e.into_connect(world))?
        else {
            return Ok(None);
        };
        Ok(Some(Self {
            subscriber,
            stash: None,
            ready,
            last: None,
            mode: WaitMode::Block,
            every_frame: false,
        }))
    }

    /// The frame-ready listener (for waits that end with a frame).
    pub(crate) fn ready(&self) -> &Listener<Bus> {
        &self.ready
    }

    /// The header of the frame kept by [`FrameStream::first_header`], not
    /// yet handed out.
    pub(crate) fn stashed_header(&self) -> Option<FrameHeader> {
        self.stash.as_ref().map(|sample| *sample.user_header())
    }

    /// The last frame handed out.
    pub(crate) fn last_frame(&self) -> Option<u64> {
        self.last.map(|(_, frame)| frame)
    }

    /// Waits until `deadline` for the first frame (a new subscriber gets the
    /// server's current one within milliseconds) and returns its header,
    /// keeping the frame for the next [`FrameStream::try_next`]. `None` when
    /// nothing came: the server is stopped or gone.
    pub(crate) fn first_header(
        &mut self,
        deadline: Instant,
    ) -> Result<Option<FrameHeader>, WaitError> {
        let (subscriber, stash) = (&self.subscriber, &mut self.stash);
        // The current frame arrives without an event: poll, backing off.
        let first = wait::until(deadline, 0, Wait::Backoff, || {
            subscriber
                .receive()
                .map_err(|e| WaitError::transport("frame receive", e))
        });
        match first {
            Ok(sample) => {
                let header = *sample.user_header();
                *stash = Some(sample);
                Ok(Some(header))
            }
            Err(Stop::Failed(e)) => Err(e),
            Err(Stop::Event(e)) => Err(WaitError::transport("frame-ready wait", e)),
            Err(Stop::TimedOut | Stop::ServerGone | Stop::Interrupted) => Ok(None),
        }
    }

    /// Hands out and drops every frame queued now, so that the next one
    /// handed out is published later (the frame of a tick sent after this).
    pub(crate) fn skip_queued(&mut self) -> Result<(), WaitError> {
        while self.try_next()?.is_some() {}
        Ok(())
    }

    /// The next snapshot already queued (in asynchronous mode the newest),
    /// without waiting.
    pub(crate) fn try_next(&mut self) -> Result<Option<FrameView>, WaitError> {
        Poller {
            subscriber: &self.subscriber,
            stash: &mut self.stash,
            last: &mut self.last,
            every_frame: self.every_frame,
        }
        .next()
    }

    /// Waits until `deadline` for the next snapshot or for `other` to give
    /// something, whichever comes first (a frame, when both have), as the
    /// stream's wait mode says: for a wait whose end the server announces
    /// on the frame-ready event either way.
    pub(crate) fn next_or<T, E: From<WaitError>>(
        &mut self,
        deadline: Instant,
        server_pid: u32,
        mut other: impl FnMut() -> Result<Option<T>, E>,
    ) -> Result<FrameOr<T>, Stop<E>> {
        let wait = Wait::for_mode(self.mode, &self.ready);
        let mut poll = Poller {
            subscriber: &self.subscriber,
            stash: &mut self.stash,
            last: &mut self.last,
            every_frame: self.every_frame,
        };
        wait::until(deadline, server_pid, wait, || {
            if let Some(frame) = poll.next()? {
                return Ok(Some(FrameOr::Frame(frame)));
            }
            Ok(other()?.map(FrameOr::Other))
        })
    }

    /// Waits up to `timeout` for the next snapshot. With a `server_pid`,
    /// a dead server ends the wait with [`WaitError::ServerGone`].
    pub(crate) fn next(
        &mut self,
        timeout: Duration,
        world: &str,
        server_pid: Option<u32>,
    ) -> Result<FrameView, WaitError> {
        let pid = server_pid.unwrap_or(0);
        let ready = &self.ready;
        let wait = Wait::for_mode(self.mode, ready);
        let mut poll = Poller {
            subscriber: &self.subscriber,
            stash: &mut self.stash,
            last: &mut self.last,
            every_frame: self.every_frame,
        };
        wait::until(Instant::now() + timeout, pid, wait, || poll.next()).map_err(
            |stop| match stop {
                Stop::Failed(e) => e,
                Stop::TimedOut => WaitError::Timeout {
                    world: world.to_owned(),
                    timeout,
                    last_frame: self.last.map(|(_, frame)| frame),
                },
                Stop::ServerGone => WaitError::ServerGone {
                    world: world.to_owned(),
                    pid,
                },
                Stop::Interrupted => WaitError::Interrupted {
                    world: world.to_owned(),
                },
                Stop::Event(e) => WaitError::transport("frame-ready wait", e),
            },
        )
    }
}

/// What ended a [`FrameStream::next_or`] wait.
pub(crate) enum FrameOr<T> {
    /// The next frame.
    Frame(FrameView),
    /// What the other source gave.
    Other(T),
}

/// The parts of a [`FrameStream`] that taking the next frame changes, apart
/// from its listener (which the wait borrows meanwhile).
struct Poller<'a> {
    subscriber: &'a FrameSubscriber,
    stash: &'a mut Option<FrameSample>,
    last: &'a mut Option<(u64, u64)>,
    every_frame: bool,
}

impl Poller<'_> {
    /// The next snapshot already queued, without waiting.
    ///
    /// Synchronous-mode frames (and every frame with `every_frame`) come one
    /// at a time, in order, so a reader that drains its queue between ticks
    /// sees every frame once. Otherwise, in asynchronous mode, the queue is
    /// drained and only the newest frame is returned, with the number of
    /// frames skipped in [`WorldSnapshot::missed`].
    ///
    /// The last frame handed out is the only reference for that count: a
    /// frame taken off the queue but not handed out (the receive after it
    /// failed) waits in the stash for the next call, so no frame between
    /// two handed-out ones goes uncounted.
    fn next(&mut self) -> Result<Option<FrameView>, WaitError> {
        let mut newest: Option<(FrameSample, (u64, u64))> = None;
        loop {
            let sample = match self.stash.take() {
                Some(sample) => sample,
                None => match self.subscriber.receive() {
                    Ok(Some(sample)) => sample,
                    Ok(None) => break,
                    Err(e) => {
                        *self.stash = newest.map(|(sample, _)| sample);
                        return Err(WaitError::transport("frame receive", e));
                    }
                },
            };
            let header = *sample.user_header();
            if header.protocol_version != PROTOCOL_VERSION {
                *self.stash = newest.map(|(sample, _)| sample);
                return Err(WaitError::ProtocolMismatch {
                    got: header.protocol_version,
                    client: PROTOCOL_VERSION,
                });
            }
            let key = (header.episode, header.timestamp.frame);
            let seen = newest.as_ref().map(|(_, key)| *key).or(*self.last);
            if seen.is_some_and(|seen| key <= seen) {
                continue; // already seen (history replay on connect)
            }
            let in_order = self.every_frame || header.settings.synchronous_mode != 0;
            // A skipped sample is released here; the newest is handed out in place.
            newest = Some((sample, key));
            if in_order {
                break; // one at a time
            }
        }
        Ok(newest.map(|(sample, key)| {
            let missed = missed_between(*self.last, key);
            *self.last = Some(key);
            FrameView::new(sample, missed)
        }))
    }
}

/// Frames never handed out between the last one handed out (`previous`,
/// as (episode, frame)) and `next`: 0 before a client's first frame and
/// at the first frame of a new episode, whose ids start again.
fn missed_between(previous: Option<(u64, u64)>, next: (u64, u64)) -> u64 {
    match previous {
        Some((episode, frame)) if episode == next.0 => {
            next.1.saturating_sub(frame.saturating_add(1))
        }
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use iceoryx2::port::update_connections::UpdateConnections;
    use shared_types::limits::WorldLimits;
    use shared_types::WorldName;
    use simbus_transport::frame_sample::{send_frame, FramePublisher};

    const T: Duration = Duration::from_secs(5);

    #[test]
    fn a_gap_after_the_first_frame_is_counted() {
        // The first frame (0, from history), then frame 2: frame 1 missed.
        assert_eq!(missed_between(None, (1, 0)), 0);
        assert_eq!(missed_between(Some((1, 0)), (1, 2)), 1);
        assert_eq!(missed_between(Some((1, 0)), (1, 1)), 0);
        // A new episode starts its ids again.
        assert_eq!(missed_between(Some((1, 40)), (2, 0)), 0);
        // A hostile frame id does not overflow.
        assert_eq!(missed_between(Some((1, u64::MAX)), (1, u64::MAX)), 0);
    }

    fn node(name: &str) -> Node<Bus> {
        simbus_transport::environment::prepare().expect("iceoryx2 environment");
        simbus_transport::node(name).expect("node")
    }

    /// Publishes asynchronous-mode frame `frame` of episode 1, no actors.
    fn publish(publisher: &FramePublisher, frame: u64) {
        let header = FrameHeader {
            protocol_version: PROTOCOL_VERSION,
            episode: 1,
            timestamp: shared_types::Timestamp {
                frame,
                ..Default::default()
            },
            ..Default::default()
        };
        send_frame(publisher, header, 0, |_| ActorState::default()).unwrap();
    }

    /// A receive that fails after a frame was taken off the queue (here:
    /// the reader holds every sample it may borrow) loses that frame no
    /// more: the next frame handed out counts it as missed.
    #[test]
    fn a_frame_taken_before_a_failed_receive_is_not_lost_from_the_count() {
        let world = WorldName::new(&format!("frames-gap-{}", std::process::id())).unwrap();
        let names = ServiceNames::new(&world);
        let specs = WorldServices::new(&names).unwrap();
        let server = node("frames-server");
        let limits = WorldLimits::default();
        let frames = specs.frames.create(&server, &limits).unwrap();
        let publisher = specs.frames.publisher(&frames, 1).unwrap();
        let _ready = specs.frame_ready.create(&server, &limits).unwrap();
        publish(&publisher, 0);

        let client = node("frames-client");
        let deadline = Instant::now() + T;
        let mut stream = FrameStream::open(&client, &names, world.as_str(), deadline)
            .unwrap()
            .expect("the world's services exist");
        publisher.update_connections().unwrap(); // delivers frame 0 (history)
        assert_eq!(
            stream
                .first_header(deadline)
                .unwrap()
                .unwrap()
                .timestamp
                .frame,
            0
        );

        // Frames 0, 1 and 2 handed out and held: one sample left to borrow.
        let mut held = vec![stream.next(T, world.as_str(), None).unwrap()];
        for frame in 1..=2 {
            publish(&publisher, frame);
            held.push(stream.next(T, world.as_str(), None).unwrap());
        }
        assert_eq!(
            held.iter()
                .map(|v| (v.frame(), v.missed()))
                .collect::<Vec<_>>(),
            [(0, 0), (1, 0), (2, 0)]
        );
        // Frame 3 takes the last borrow; receiving frame 4 then fails.
        publish(&publisher, 3);
        publish(&publisher, 4);
        assert!(stream.next(T, world.as_str(), None).is_err());
        drop(held);
        let next = stream.next(T, world.as_str(), None).unwrap();
        assert_eq!((next.frame(), next.missed()), (4, 1), "frame 3 counted");
    }
}
