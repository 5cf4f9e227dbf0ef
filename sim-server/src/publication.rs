//! Publishing frames: each frame's snapshot (the actors, then their packed
//! poses) is written straight into loaned shared memory, then every client
//! blocked on the frame-ready event wakes.

use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::update_connections::UpdateConnections;
use shared_types::limits::{WorldLimits, INITIAL_MAX_ACTORS};
use shared_types::{frame_slice_len, ActorState, FrameHeader};
use simbus_transport::frame_sample::{send_frame, FramePublisher};
use simbus_transport::Bus;
use tracing::debug;

use crate::error::PortError;
use crate::ports::Transport;
use crate::world::World;

/// The frame publisher and the frame-ready notifier.
#[derive(Debug)]
pub(crate) struct Publication {
    publisher: FramePublisher,
    ready: Notifier<Bus>,
}

impl Publication {
    /// Opens the world's frame service (every new subscriber gets the
    /// current frame) and its frame-ready event.
    pub(crate) fn open(
        transport: &Transport,
        initial_actors: usize,
        limits: &WorldLimits,
    ) -> Result<Self, PortError> {
        let (node, services) = (&transport.node, &transport.services);
        let frames = services
            .frames
            .open_or_create(node, limits)
            .map_err(|e| PortError::transport("frames service", e))?;
        let publisher = services
            .frames
            .publisher(
                &frames,
                frame_slice_len(initial_actors.max(INITIAL_MAX_ACTORS)),
            )
            .map_err(|e| PortError::transport("frames publisher", e))?;
        let ready = services
            .frame_ready
            .open_or_create(node, limits)
            .map_err(|e| PortError::transport("frame-ready service", e))?
            .notifier_builder()
            .create()
            .map_err(|e| PortError::transport("frame-ready notifier", e))?;
        Ok(Self { publisher, ready })
    }

    /// Writes `header`, every actor of `world` and their poses straight
    /// into a loaned sample and sends it. No copy, no allocation.
    pub(crate) fn publish(&self, header: FrameHeader, world: &World) -> Result<(), PortError> {
        send_frame(&self.publisher, header, world.actor_count(), |i| {
            world.actor_state(i)
        })
        .map_err(|e| PortError::transport("frame send", e))
    }

    /// Sends `header` with `actors` (a replayed frame).
    pub(crate) fn publish_states(
        &self,
        header: FrameHeader,
        actors: &[ActorState],
    ) -> Result<(), PortError> {
        send_frame(&self.publisher, header, actors.len(), |i| actors[i])
            .map_err(|e| PortError::transport("frame send", e))
    }

    /// Wakes every client blocked on the frame-ready event.
    pub(crate) fn notify(&self) -> Result<(), PortError> {
        self.ready
            .notify()
            .map_err(|e| PortError::transport("frame-ready notify", e))?;
        Ok(())
    }

    /// Connects subscribers that joined since the last frame, so they get
    /// the current frame now, not only when the next one is sent (in
    /// synchronous mode that may be a long wait).
    pub(crate) fn connect_new_subscribers(&self) {
        if let Err(e) = self.publisher.update_connections() {
            debug!("connecting new subscribers: {e}");
        }
    }
}
