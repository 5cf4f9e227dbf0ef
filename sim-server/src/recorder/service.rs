//! The recorder service: requests to record and replay, answered with how
//! the recorder and the replayer are doing.

use iceoryx2::port::server::Server as RequestServer;
use iceoryx2::prelude::*;
use shared_types::limits::WorldLimits;
use shared_types::{
    PathText, RecorderKind, RecorderRefusal, RecorderRequest, RecorderResponse, ReplayMode,
    ResponseStatus, PROTOCOL_VERSION,
};
use tracing::{debug, info, warn};

use crate::ports::{service_name, Transport};
use crate::replayer::ReplayRequest;
use crate::server::Domains;
use crate::ServerError;

type Port = RequestServer<ipc::Service, RecorderRequest, (), RecorderResponse, ()>;

/// The recorder service's server port.
#[derive(Debug)]
pub struct RecorderPort {
    port: Port,
}

impl RecorderPort {
    /// Opens the recorder service.
    pub fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, ServerError> {
        let port = transport
            .node
            .service_builder(&service_name(&transport.names.recorder)?)
            .request_response::<RecorderRequest, RecorderResponse>()
            .max_servers(1)
            .max_clients(limits.max_clients)
            .max_nodes(limits.nodes())
            .max_active_requests_per_client(2)
            .max_response_buffer_size(2)
            .open_or_create()
            .map_err(|e| ServerError::transport("recorder service", e))?
            .server_builder()
            .create()
            .map_err(|e| ServerError::transport("recorder server", e))?;
        Ok(Self { port })
    }

    /// Answers every pending recorder request.
    pub(crate) fn handle(&mut self, domains: &mut Domains) -> Result<(), ServerError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| ServerError::transport("recorder receive", e))?
        {
            let response = answer(domains, request.payload());
            if let Err(e) = request.send_copy(response) {
                debug!("recorder response not delivered (client gone?): {e:?}");
            }
        }
        Ok(())
    }
}

/// A refusal: the reason as a code and in words.
type Refusal = (RecorderRefusal, String);

fn answer(d: &mut Domains, request: &RecorderRequest) -> RecorderResponse {
    if request.protocol_version != PROTOCOL_VERSION {
        warn!(
            client_pid = request.client_pid,
            "refused a recorder request: protocol version {} is not the server's {PROTOCOL_VERSION}",
            request.protocol_version
        );
        return d.recorder_status(RecorderResponse::new(ResponseStatus::ProtocolMismatch));
    }
    let Some(kind) = RecorderKind::from_u32(request.kind) else {
        return d.recorder_status(RecorderResponse::new(ResponseStatus::UnknownRequest));
    };
    let done = match kind {
        RecorderKind::Status => Ok(()),
        RecorderKind::Start => start(d, request),
        RecorderKind::Stop => {
            let frame = d.clock.frame();
            match d.recorder.stop("stop", frame) {
                Some(_) => Ok(()),
                None => Err((
                    RecorderRefusal::NotRecording,
                    "no recording is running".to_string(),
                )),
            }
        }
        RecorderKind::Replay => replay(d, request),
        RecorderKind::StopReplay => {
            if d.replayer.is_running() || d.replayer.saved.is_some() {
                d.stop_replay(request.flags & RecorderRequest::KEEP_ACTORS != 0)
                    .map_err(|e| (RecorderRefusal::NotReplaying, e.to_string()))
            } else {
                Err((
                    RecorderRefusal::NotReplaying,
                    "no replay is running".to_string(),
                ))
            }
        }
        RecorderKind::TimeFactor => d.replayer.set_time_factor(request.time_factor),
    };
    match done {
        Ok(()) => d.recorder_status(RecorderResponse::new(ResponseStatus::Ok)),
        Err((refusal, message)) => {
            info!(client_pid = request.client_pid, ?kind, "refused: {message}");
            let mut response = d.recorder_status(RecorderResponse::new(ResponseStatus::Refused));
            response.refusal = refusal as u32;
            response.message = PathText::cut(&message);
            response
        }
    }
}

fn path_of(request: &RecorderRequest) -> Result<String, Refusal> {
    let path = request.path.to_string_lossy();
    if path.is_empty() || request.path.len as usize > PathText::CAPACITY {
        return Err((
            RecorderRefusal::InvalidArgument,
            "no file path given".to_string(),
        ));
    }
    Ok(path)
}

fn start(d: &mut Domains, request: &RecorderRequest) -> Result<(), Refusal> {
    if let Some((path, _)) = d.recorder.progress() {
        return Err((
            RecorderRefusal::AlreadyRecording,
            format!("already recording to {path}"),
        ));
    }
    if d.replayer.is_running() {
        return Err((
            RecorderRefusal::Replaying,
            "a replay is running; stop it first".to_string(),
        ));
    }
    let path = path_of(request)?;
    d.start_recording(&path, request.flags & RecorderRequest::SENSORS != 0)
        .map_err(|message| (RecorderRefusal::CannotWrite, message))
}

fn replay(d: &mut Domains, request: &RecorderRequest) -> Result<(), Refusal> {
    if d.replayer.is_running() {
        return Err((
            RecorderRefusal::Replaying,
            format!("already replaying {}", d.replayer.report.path),
        ));
    }
    if let Some((path, _)) = d.recorder.progress() {
        return Err((
            RecorderRefusal::Recording,
            format!("recording to {path}; stop the recorder first"),
        ));
    }
    let mode = match request.mode {
        0 => None,
        m => Some(ReplayMode::from_u32(m).ok_or((
            RecorderRefusal::InvalidArgument,
            format!("unknown replay mode {m}"),
        ))?),
    };
    let replay = ReplayRequest {
        path: path_of(request)?,
        start_seconds: request.start_seconds,
        duration_seconds: request.duration_seconds,
        follow_id: request.follow_id,
        replay_sensors: request.flags & RecorderRequest::REPLAY_SENSORS != 0,
        keep_actors: request.flags & RecorderRequest::KEEP_ACTORS != 0,
        time_factor: request.time_factor,
        mode,
    };
    d.start_replay(&replay)
}
