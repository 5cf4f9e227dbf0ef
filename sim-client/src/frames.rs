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
            Err(Stop::TimedOut | Stop::ServerGone) => Ok(None),
        }
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
                Stop::Event(e) => WaitError::transport("frame-ready wait", e),
            },
        )
    }
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
    fn next(&mut self) -> Result<Option<FrameView>, WaitError> {
        let previous = *self.last;
        let mut newest = None;
        while let Some(sample) = match self.stash.take() {
            Some(sample) => Some(sample),
            None => self
                .subscriber
                .receive()
                .map_err(|e| WaitError::transport("frame receive", e))?,
        } {
            let header = *sample.user_header();
            if header.protocol_version != PROTOCOL_VERSION {
                return Err(WaitError::ProtocolMismatch {
                    got: header.protocol_version,
                    client: PROTOCOL_VERSION,
                });
            }
            let key = (header.episode, header.timestamp.frame);
            if self.last.is_some_and(|last| key <= last) {
                continue; // already seen (history replay on connect)
            }
            *self.last = Some(key);
            let in_order = self.every_frame || header.settings.synchronous_mode != 0;
            newest = Some(sample);
            if in_order {
                break; // one at a time
            }
        }
        // The newest sample is handed out in place; skipped ones were just released.
        Ok(newest.map(|sample| {
            let header = *sample.user_header();
            let missed = match previous {
                Some((episode, frame)) if episode == header.episode => {
                    header.timestamp.frame.saturating_sub(frame + 1)
                }
                _ => 0,
            };
            FrameView::new(sample, missed)
        }))
    }
}
