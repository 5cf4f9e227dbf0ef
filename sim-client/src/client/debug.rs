//! A client's debug drawing: points, lines, arrows, boxes and texts the
//! world keeps for a while and its viewers show (CARLA's
//! `world.debug.draw_*`).

use shared_types::debug_shapes::MAX_DEBUG_SHAPES;
use shared_types::{
    DebugRequest, DebugRequestKind, DebugResponseHeader, DebugShape, DebugShapeError,
    ResponseStatus,
};
use simbus_transport::spec::WorldServices;

use crate::rpc::{PortNames, RequestPort};
use crate::wait::Wait;
use crate::{Client, RequestError};

/// The request port of the world's debug-drawing service.
pub(crate) type DebugClient = RequestPort<DebugRequest, [DebugShape], (), DebugResponseHeader>;

/// Why a shape was not drawn.
#[derive(Debug, thiserror::Error)]
pub enum DrawError {
    /// The shape is wrong (checked before it is sent).
    #[error(transparent)]
    Shape(#[from] DebugShapeError),
    /// The world keeps [`MAX_DEBUG_SHAPES`] shapes at most.
    #[error("the world keeps {MAX_DEBUG_SHAPES} debug shapes at most: clear some, or draw shorter-lived ones")]
    TooMany,
    /// The request failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

impl Client {
    /// The debug port, opened on first use and kept.
    fn debug_port(&self) -> Result<&DebugClient, RequestError> {
        if let Some(port) = self.debug_port.get() {
            return Ok(port);
        }
        let specs = WorldServices::new(&self.names)
            .map_err(|e| RequestError::transport("service name", e))?;
        let names = PortNames {
            service: "debug service",
            client: "debug client",
            send: "debug send",
            clients: "clients drawing debug shapes",
        };
        let port = self.slice_answer_port(&specs.debug, names)?;
        Ok(self.debug_port.get_or_init(|| port))
    }

    fn debug_request(
        &self,
        kind: DebugRequestKind,
        shape: DebugShape,
    ) -> Result<Vec<DebugShape>, RequestError> {
        let answer = self.debug_port()?.request_waking(
            DebugRequest::new(kind, shape),
            self,
            self.request_timeout,
            Wait::Backoff,
        )?;
        match ResponseStatus::from_u32(answer.header.status) {
            Some(ResponseStatus::Ok) => Ok(answer.items),
            _ => Err(RequestError::UnknownAnswer {
                status: answer.header.status,
            }),
        }
    }

    /// Draws `shape` from the next frame on, for as long as it lasts in
    /// simulation time ([`DebugShape::lasting`]): the Foxglove live view
    /// and a recording's scene show it; nothing else sees it.
    ///
    /// # Errors
    ///
    /// Returns [`DrawError::Shape`] for a shape that is wrong (nothing
    /// sent), [`DrawError::TooMany`] if the world keeps
    /// [`MAX_DEBUG_SHAPES`] already, and [`DrawError::Request`] if the
    /// request fails ([`RequestError::Timeout`], ...).
    pub fn draw_debug(&self, shape: DebugShape) -> Result<(), DrawError> {
        shape.check()?;
        match self.debug_request(DebugRequestKind::Draw, shape) {
            Ok(_) => Ok(()),
            Err(RequestError::UnknownAnswer { status })
                if status == ResponseStatus::Refused as u32 =>
            {
                Err(DrawError::TooMany)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// The debug shapes the current frame shows.
    ///
    /// # Errors
    ///
    /// Returns the [`RequestError`] of the request
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`], ...).
    pub fn debug_shapes(&self) -> Result<Vec<DebugShape>, RequestError> {
        self.debug_request(DebugRequestKind::List, DebugShape::default())
    }

    /// Forgets every debug shape, from the next frame on.
    ///
    /// # Errors
    ///
    /// Returns the [`RequestError`] of the request.
    pub fn clear_debug_shapes(&self) -> Result<(), RequestError> {
        self.debug_request(DebugRequestKind::Clear, DebugShape::default())
            .map(drop)
    }
}
