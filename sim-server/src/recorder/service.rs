//! The recorder service: requests to record and replay, decoded into the
//! calls they make and answered with how the recorder and the replayer
//! are doing.
//!
//! A replay request is answered once its recording has been read through
//! and its world built (off the frame loop, by the replayer); meanwhile
//! the world goes on, and the request waits here for its answer.

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::server::Server as RequestServer;
use iceoryx2::service::port_factory::PortFactory as _;
use shared_types::limits::WorldLimits;
use shared_types::{
    PathText, RecorderKind, RecorderRequest, RecorderResponse, ReplayMode, ResponseStatus,
    PROTOCOL_VERSION,
};
use simbus_transport::Bus;
use tracing::{debug, warn};

use super::Refused;
use crate::error::PortError;
use crate::ports::{sender_pid, Transport};
use crate::replayer::ReplayRequest;

type Port = RequestServer<Bus, RecorderRequest, (), RecorderResponse, ()>;
type Request = ActiveRequest<Bus, RecorderRequest, (), RecorderResponse, ()>;

/// The recorder service's server port, and the replay request waiting for
/// its answer.
#[derive(Debug)]
pub(crate) struct RecorderPort {
    port: Port,
    /// The previous server's clients (their requests are dropped).
    earlier: simbus_transport::EarlierClients,
    waiting: Option<Request>,
}

/// A recorder request, decoded: what a client asks of the recorder or the
/// replayer. What only the request itself can tell (a path, a mode) is
/// checked here; what depends on what runs, where it is carried out.
#[derive(Debug)]
pub(crate) enum RecorderCall {
    /// Refused before it reaches the recorder (protocol version, unknown
    /// request), with this status.
    Refuse(ResponseStatus),
    /// How the recorder and the replayer are doing.
    Status,
    /// Record to `path`.
    Start {
        /// The file, or why the request names none.
        path: Result<String, Refused>,
        /// Sensor captures too.
        sensors: bool,
    },
    /// Stop recording.
    Stop,
    /// Replay a recording (answered once it is prepared).
    Replay(Result<ReplayRequest, Refused>),
    /// Stop the replay.
    StopReplay {
        /// Keep the replayed world live.
        keep_actors: bool,
    },
    /// Replay at this speed.
    TimeFactor(f64),
}

impl RecorderPort {
    /// Opens the recorder service.
    pub(crate) fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, PortError> {
        let service = transport
            .services
            .recorder
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("recorder service", e))?;
        let earlier = simbus_transport::EarlierClients::of(service.dynamic_config());
        let port = service
            .server_builder()
            .create()
            .map_err(|e| PortError::transport("recorder server", e))?;
        Ok(Self {
            port,
            earlier,
            waiting: None,
        })
    }

    /// Answers every pending recorder request with what `answer` makes of
    /// its call; `None` means later (a replay being prepared: see
    /// [`RecorderPort::answer_replay`]).
    pub(crate) fn handle(
        &mut self,
        mut answer: impl FnMut(RecorderCall, u32) -> Option<RecorderResponse>,
    ) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("recorder receive", e))?
        {
            if self.earlier.sent(request.header()) {
                tracing::debug!("dropped a request from a client of the previous server");
                continue;
            }
            let payload = *request.payload();
            // Logged by the sending port's process, not the pid it claims.
            match answer(decode(&payload), sender_pid(request.header())) {
                Some(response) => respond(&request, response),
                None => self.waiting = Some(request),
            }
        }
        Ok(())
    }

    /// Answers the replay request that waited for its preparation.
    pub(crate) fn answer_replay(&mut self, response: RecorderResponse) {
        if let Some(request) = self.waiting.take() {
            respond(&request, response);
        }
    }
}

fn respond(request: &Request, response: RecorderResponse) {
    if let Err(e) = request.send_copy(response) {
        debug!("recorder response not delivered (client gone?): {e:?}");
    }
}

fn decode(request: &RecorderRequest) -> RecorderCall {
    if request.protocol_version != PROTOCOL_VERSION {
        warn!(
            client_pid = request.client_pid,
            "refused a recorder request: protocol version {} is not the server's {PROTOCOL_VERSION}",
            request.protocol_version
        );
        return RecorderCall::Refuse(ResponseStatus::ProtocolMismatch);
    }
    let Some(kind) = RecorderKind::from_u32(request.kind) else {
        return RecorderCall::Refuse(ResponseStatus::UnknownRequest);
    };
    match kind {
        RecorderKind::Status => RecorderCall::Status,
        RecorderKind::Start => RecorderCall::Start {
            path: path_of(request),
            sensors: request.flags & RecorderRequest::SENSORS != 0,
        },
        RecorderKind::Stop => RecorderCall::Stop,
        RecorderKind::Replay => RecorderCall::Replay(replay_request(request)),
        RecorderKind::StopReplay => RecorderCall::StopReplay {
            keep_actors: request.flags & RecorderRequest::KEEP_ACTORS != 0,
        },
        RecorderKind::TimeFactor => RecorderCall::TimeFactor(request.time_factor),
    }
}

fn path_of(request: &RecorderRequest) -> Result<String, Refused> {
    let path = request.path.to_string_lossy();
    if path.is_empty() || request.path.len as usize > PathText::CAPACITY {
        return Err(Refused::NoPath);
    }
    Ok(path)
}

/// A replay request as far as the request alone can tell.
fn replay_request(request: &RecorderRequest) -> Result<ReplayRequest, Refused> {
    let mode = match request.mode {
        0 => None,
        m => Some(ReplayMode::from_u32(m).ok_or(Refused::UnknownMode(m))?),
    };
    Ok(ReplayRequest {
        path: path_of(request)?,
        start_seconds: request.start_seconds,
        duration_seconds: request.duration_seconds,
        follow_id: request.follow_id,
        replay_sensors: request.flags & RecorderRequest::REPLAY_SENSORS != 0,
        keep_actors: request.flags & RecorderRequest::KEEP_ACTORS != 0,
        time_factor: request.time_factor,
        mode,
    })
}
