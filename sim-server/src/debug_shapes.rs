//! The debug-drawing domain: the shapes clients draw (CARLA's
//! `world.debug.draw_*`), kept until they expire in simulation time, listed
//! for the viewers and drawn into a recording's scene. They have no body.

use iceoryx2::port::server::Server as RequestServer;
use iceoryx2::service::port_factory::PortFactory as _;
use shared_types::debug_shapes::MAX_DEBUG_SHAPES;
use shared_types::limits::WorldLimits;
use shared_types::{
    DebugRequest, DebugRequestKind, DebugResponseHeader, DebugShape, ResponseStatus,
    PROTOCOL_VERSION,
};
use simbus_transport::{Bus, EarlierClients};
use tracing::debug;

use crate::clock::Clock;
use crate::error::PortError;
use crate::ports::{sender_pid, Transport};

type DebugServer = RequestServer<Bus, DebugRequest, (), [DebugShape], DebugResponseHeader>;

/// One shape kept, and when it goes.
#[derive(Debug, Clone, Copy)]
struct Kept {
    shape: DebugShape,
    /// The frame current when it was drawn.
    drawn_frame: u64,
    /// The simulation time it was drawn at, nanoseconds.
    drawn_ns: u64,
}

impl Kept {
    /// Whether it is gone once frame `frame` at `elapsed_ns` is stepped:
    /// a one-frame shape shows in the frame after its drawing only.
    fn expired(&self, frame: u64, elapsed_ns: u64) -> bool {
        if self.shape.is_permanent() {
            return false;
        }
        if self.shape.life_ns == 0 {
            return frame > self.drawn_frame + 1;
        }
        elapsed_ns > self.drawn_ns.saturating_add(self.shape.life_ns)
    }
}

/// The debug-drawing service and the shapes kept.
#[derive(Debug)]
pub(crate) struct DebugShapes {
    port: DebugServer,
    /// The previous server's clients (their requests are dropped).
    earlier: EarlierClients,
    kept: Vec<Kept>,
    /// The live shapes, as the last frame left them (the recorder's).
    live: Vec<DebugShape>,
}

impl DebugShapes {
    /// Opens the debug-drawing service.
    pub(crate) fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, PortError> {
        let spec = &transport.services.debug;
        let service = spec
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("debug service", e))?;
        let earlier = EarlierClients::of(service.dynamic_config());
        let port = spec
            .server(&service)
            .map_err(|e| PortError::transport("debug server", e))?;
        Ok(Self {
            port,
            earlier,
            kept: Vec::new(),
            live: Vec::new(),
        })
    }

    /// Answers every pending request: a draw kept (or refused), the list,
    /// a clear.
    pub(crate) fn handle(&mut self, clock: &Clock) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("debug receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            let payload = *request.payload();
            let status = if payload.protocol_version != PROTOCOL_VERSION {
                ResponseStatus::ProtocolMismatch
            } else {
                match DebugRequestKind::from_u32(payload.kind) {
                    Some(DebugRequestKind::Draw) => self.draw(payload.shape, clock),
                    Some(DebugRequestKind::Clear) => {
                        self.kept.clear();
                        ResponseStatus::Ok
                    }
                    Some(DebugRequestKind::List) => ResponseStatus::Ok,
                    None => ResponseStatus::UnknownRequest,
                }
            };
            let list =
                payload.kind == DebugRequestKind::List as u32 && status == ResponseStatus::Ok;
            let shapes: &[DebugShape] = if list { &self.live } else { &[] };
            let response = request.loan_slice_uninit(shapes.len()).map(|mut response| {
                *response.user_header_mut() = DebugResponseHeader {
                    protocol_version: PROTOCOL_VERSION,
                    status: status as u32,
                    frame: clock.frame() + 1,
                };
                response.write_from_slice(shapes)
            });
            match response.map(|r| r.send()) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => debug!("debug response not delivered: {e:?}"),
                Err(e) => debug!("debug response not loaned: {e:?}"),
            }
            if status != ResponseStatus::Ok {
                debug!(
                    pid = sender_pid(request.header()),
                    ?status,
                    "debug request refused"
                );
            }
        }
        Ok(())
    }

    /// Keeps `shape` from the next frame on, if it is right and there is
    /// room.
    fn draw(&mut self, shape: DebugShape, clock: &Clock) -> ResponseStatus {
        if shape.check().is_err() || self.kept.len() >= MAX_DEBUG_SHAPES {
            return ResponseStatus::Refused;
        }
        self.kept.push(Kept {
            shape,
            drawn_frame: clock.frame(),
            drawn_ns: clock.elapsed_ns(),
        });
        ResponseStatus::Ok
    }

    /// Frame `frame` at `elapsed_ns` is stepped: the shapes it no longer
    /// shows go, and the live list is what it shows.
    pub(crate) fn stepped(&mut self, frame: u64, elapsed_ns: u64) {
        self.kept.retain(|k| !k.expired(frame, elapsed_ns));
        self.live.clear();
        self.live.extend(self.kept.iter().map(|k| k.shape));
    }

    /// The shapes the current frame shows.
    pub(crate) fn live(&self) -> &[DebugShape] {
        &self.live
    }

    /// A new episode (a load, a reload, a restore): nothing drawn stays.
    pub(crate) fn new_episode(&mut self) {
        self.kept.clear();
        self.live.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kept(shape: DebugShape) -> Kept {
        Kept {
            shape,
            drawn_frame: 10,
            drawn_ns: 1_000_000_000,
        }
    }

    #[test]
    fn shapes_last_one_frame_their_time_or_for_good() {
        let one_frame = kept(DebugShape::default().lasting(-1.0));
        assert!(
            !one_frame.expired(11, 1_050_000_000),
            "shown in the next frame"
        );
        assert!(one_frame.expired(12, 1_100_000_000), "gone after it");
        let timed = kept(DebugShape::default().lasting(0.5));
        assert!(!timed.expired(20, 1_500_000_000));
        assert!(timed.expired(21, 1_500_000_001));
        let permanent = kept(DebugShape::default().lasting(0.0));
        assert!(!permanent.expired(u64::MAX, u64::MAX));
    }
}
