//! The recorder service: requests to record and replay, answered with how
//! the recorder and the replayer are doing.
//!
//! A replay request is answered once its recording has been read through
//! and its world built — on a thread of its own, so a large file never
//! stalls the frame loop; meanwhile the world goes on, and a second replay
//! or a recording is refused.

use shared_types::Bus;
use std::thread::JoinHandle;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::server::Server as RequestServer;
use shared_types::limits::WorldLimits;
use shared_types::{
    PathText, RecorderKind, RecorderRefusal, RecorderRequest, RecorderResponse, ReplayMode,
    ResponseStatus, PROTOCOL_VERSION,
};
use tracing::{debug, info, warn};

use crate::ports::{service_name, Transport};
use crate::replayer::{prepare, Prepared, Refused, ReplayRequest};
use crate::server::Domains;
use crate::ServerError;

type Port = RequestServer<Bus, RecorderRequest, (), RecorderResponse, ()>;
type Request = ActiveRequest<Bus, RecorderRequest, (), RecorderResponse, ()>;

/// A replay being prepared: the request waiting for its answer, and the job.
#[derive(Debug)]
struct Preparing {
    request: Request,
    path: String,
    job: JoinHandle<Result<Prepared, Refused>>,
}

/// The recorder service's server port.
#[derive(Debug)]
pub struct RecorderPort {
    port: Port,
    preparing: Option<Preparing>,
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
        Ok(Self {
            port,
            preparing: None,
        })
    }

    /// Answers every pending recorder request, and a replay request whose
    /// preparation finished (starting that replay).
    pub(crate) fn handle(&mut self, domains: &mut Domains) -> Result<(), ServerError> {
        if self.preparing.as_ref().is_some_and(|p| p.job.is_finished()) {
            if let Some(preparing) = self.preparing.take() {
                let result = preparing.job.join().unwrap_or_else(|_| {
                    Err((
                        RecorderRefusal::BadFile,
                        format!("reading {} failed unexpectedly", preparing.path),
                    ))
                });
                let done = result.map(|prepared| domains.start_replay(prepared));
                respond(
                    &preparing.request,
                    reply(domains, RecorderKind::Replay, 0, done),
                );
            }
        }
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| ServerError::transport("recorder receive", e))?
        {
            let payload = *request.payload();
            if payload.protocol_version == PROTOCOL_VERSION
                && payload.kind == RecorderKind::Replay as u32
            {
                match self.start_preparing(domains, &payload) {
                    Ok(job) => {
                        self.preparing = Some(Preparing {
                            request,
                            path: payload.path.to_string_lossy(),
                            job,
                        });
                    }
                    Err(refused) => respond(
                        &request,
                        reply(
                            domains,
                            RecorderKind::Replay,
                            payload.client_pid,
                            Err(refused),
                        ),
                    ),
                }
                continue;
            }
            let response = answer(
                domains,
                &payload,
                self.preparing.as_ref().map(|p| p.path.as_str()),
            );
            respond(&request, response);
        }
        Ok(())
    }

    /// Checks a replay request against what runs, then reads its recording
    /// on a thread of its own.
    fn start_preparing(
        &self,
        d: &Domains,
        request: &RecorderRequest,
    ) -> Result<JoinHandle<Result<Prepared, Refused>>, Refusal> {
        if let Some(preparing) = &self.preparing {
            return Err((
                RecorderRefusal::Replaying,
                format!("already preparing a replay of {}", preparing.path),
            ));
        }
        let replay = replay_request(d, request)?;
        std::thread::Builder::new()
            .name("simbus-replay-prepare".into())
            .spawn(move || prepare(&replay))
            .map_err(|e| {
                (
                    RecorderRefusal::BadFile,
                    format!("cannot start reading: {e}"),
                )
            })
    }
}

fn respond(request: &Request, response: RecorderResponse) {
    if let Err(e) = request.send_copy(response) {
        debug!("recorder response not delivered (client gone?): {e:?}");
    }
}

/// A refusal: the reason as a code and in words.
type Refusal = Refused;

fn answer(d: &mut Domains, request: &RecorderRequest, preparing: Option<&str>) -> RecorderResponse {
    if request.protocol_version != PROTOCOL_VERSION {
        warn!(
            client_pid = request.client_pid,
            "refused a recorder request: protocol version {} is not the server's {PROTOCOL_VERSION}",
            request.protocol_version
        );
        return d.recorder_status(
            RecorderKind::Status,
            RecorderResponse::new(ResponseStatus::ProtocolMismatch),
        );
    }
    let Some(kind) = RecorderKind::from_u32(request.kind) else {
        return d.recorder_status(
            RecorderKind::Status,
            RecorderResponse::new(ResponseStatus::UnknownRequest),
        );
    };
    let done = match kind {
        RecorderKind::Status => Ok(()),
        RecorderKind::Start => match preparing {
            Some(path) => Err((
                RecorderRefusal::Replaying,
                format!("a replay of {path} is being prepared"),
            )),
            None => start(d, request),
        },
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
        // Answered by `RecorderPort::handle` once prepared.
        RecorderKind::Replay => Ok(()),
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
    reply(d, kind, request.client_pid, done)
}

/// The answer to a request of `kind` that did `done`.
fn reply(
    d: &Domains,
    kind: RecorderKind,
    client_pid: u32,
    done: Result<(), Refusal>,
) -> RecorderResponse {
    match done {
        Ok(()) => d.recorder_status(kind, RecorderResponse::new(ResponseStatus::Ok)),
        Err((refusal, message)) => {
            info!(client_pid, ?kind, "refused: {message}");
            let mut response =
                d.recorder_status(kind, RecorderResponse::new(ResponseStatus::Refused));
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
        .map_err(|e| (RecorderRefusal::CannotWrite, e.to_string()))
}

/// A replay request checked against what runs now.
fn replay_request(d: &Domains, request: &RecorderRequest) -> Result<ReplayRequest, Refusal> {
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
    Ok(replay)
}
