//! The mirror's side of a local request: the bytes it is forwarded as,
//! and the answer it gets — the exporter's, a refusal, or
//! [`ResponseStatus::Unreachable`] while the exporter cannot be reached.

use crate::error::Chain;
use crate::wire::{self, Forwarded, PayloadError};
use shared_types::{
    BatchResponseHeader, CommandResult, ControlResponse, LockstepResponse, RecorderResponse,
    ResponseStatus, SensorInfo, SensorResponseHeader, ServiceNames, TickRequest, TickRequestKind,
    TickResponse, PROTOCOL_VERSION,
};
use tracing::warn;

use shared_types::limits::WorldLimits;

use super::local::{Active, Local, LocalServices, SensorPorts};

/// An answer with `status` for a request whose answer type is `T` (every
/// answer starts with the protocol version and a status).
pub(super) fn status_answer<T: bytemuck::Pod>(status: ResponseStatus) -> T {
    let mut answer = T::zeroed();
    let bytes = bytemuck::bytes_of_mut(&mut answer);
    bytes[..4].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    bytes[4..8].copy_from_slice(&(status as u32).to_le_bytes());
    answer
}

/// The service and bytes a local request is forwarded as.
pub(super) fn request_bytes(request: &Local) -> (Forwarded, Vec<u8>) {
    match request {
        Local::Control(a) => (Forwarded::Control, wire::bytes_of(a.payload()).to_vec()),
        Local::Tick(_, payload) => (Forwarded::Tick, wire::bytes_of(payload).to_vec()),
        Local::Lockstep(a) => {
            let mut payload = *a.payload();
            payload.pid = sender_pid(a.header());
            (Forwarded::Lockstep, wire::bytes_of(&payload).to_vec())
        }
        Local::Recorder(a) => (Forwarded::Recorder, wire::bytes_of(a.payload()).to_vec()),
        Local::Batch(a) => {
            let mut bytes = Vec::new();
            wire::encode_slice(a.user_header(), a.payload(), &mut bytes);
            (Forwarded::Batch, bytes)
        }
        Local::Sensors(a) => (Forwarded::Sensors, wire::bytes_of(a.payload()).to_vec()),
    }
}

/// Answers a local request with `status` (nothing else in the answer).
pub(super) fn refuse_local(request: &Local, status: ResponseStatus) {
    let sent = match request {
        Local::Control(a) => a.send_copy(status_answer(status)),
        Local::Tick(a, _) => a.send_copy(status_answer(status)),
        Local::Lockstep(a) => a.send_copy(status_answer(status)),
        Local::Recorder(a) => a.send_copy(status_answer(status)),
        Local::Batch(a) => a
            .loan_slice_uninit(0)
            .map_err(iceoryx2::port::SendError::from)
            .and_then(|mut r| {
                *r.user_header_mut() = status_answer::<BatchResponseHeader>(status);
                r.write_from_slice(&[] as &[CommandResult]).send()
            }),
        Local::Sensors(a) => a
            .loan_slice_uninit(0)
            .map_err(iceoryx2::port::SendError::from)
            .and_then(|mut r| {
                *r.user_header_mut() = status_answer::<SensorResponseHeader>(status);
                r.write_from_slice(&[] as &[SensorInfo]).send()
            }),
    };
    if let Err(e) = sent {
        tracing::debug!("answer to a local request not delivered: {e:?}");
    }
}

/// Answers a local request with [`ResponseStatus::Unreachable`].
pub(super) fn unreachable_answer(request: &Local) {
    refuse_local(request, ResponseStatus::Unreachable);
}

/// What became of an answer from the exporter.
pub(super) enum Answered {
    /// Sent to the local client.
    Sent,
    /// Not an answer of the request's kind.
    Unreadable(PayloadError),
    /// A tick's answer, to be sent once its frame is published here.
    AfterFrame(Box<TickResponse>),
}

pub(super) fn send_tick(active: &Active<TickRequest, TickResponse>, answer: TickResponse) {
    if let Err(e) = active.send_copy(answer) {
        tracing::debug!("tick answer not delivered: {e:?}");
    }
}

/// [`Answered::Sent`], with a local client that left logged.
fn sent<E: std::fmt::Debug>(sent: Result<(), E>) -> Answered {
    if let Err(e) = sent {
        tracing::debug!("answer to a local request not delivered: {e:?}");
    }
    Answered::Sent
}

/// Sends the exporter's answer `bytes` to the local request. A claim's
/// answer names the local ticker; a sensor list creates the listed
/// sensors' services here first.
pub(super) fn answer_local(
    request: &Local,
    bytes: &[u8],
    names: &ServiceNames,
    limits: &WorldLimits,
    local: &LocalServices,
    sensors: &mut SensorPorts,
    local_ticker: &mut Option<(u32, String)>,
) -> Answered {
    let result = match request {
        Local::Control(a) => {
            wire::decode_fixed::<ControlResponse>(bytes, "control answer").map(|mut answer| {
                // Here the mirror serves the world, and its run is the
                // mirror's: it goes on across a resume behind the exporter
                // (a new run there ends the export).
                answer.report.server_pid = std::process::id();
                answer.report.run_pid = std::process::id();
                sent(a.send_copy(answer).map(drop))
            })
        }
        Local::Tick(a, request) => wire::decode_fixed::<TickResponse>(bytes, "tick answer")
            .map(|answer| answer_tick(a, request, answer, local_ticker)),
        Local::Lockstep(a) => wire::decode_fixed::<LockstepResponse>(bytes, "lockstep answer")
            .map(|answer| sent(a.send_copy(answer).map(drop))),
        Local::Recorder(a) => wire::decode_fixed::<RecorderResponse>(bytes, "recorder answer")
            .map(|answer| sent(a.send_copy(answer).map(drop))),
        Local::Batch(a) => wire::decode_slice::<BatchResponseHeader, CommandResult>(
            bytes,
            "batch answer",
            wire::MAX_FORWARDED_BATCH,
        )
        .map(|(header, results)| {
            sent(
                a.loan_slice_uninit(results.len())
                    .map_err(iceoryx2::port::SendError::from)
                    .and_then(|mut r| {
                        *r.user_header_mut() = header;
                        r.write_from_slice(&results).send()
                    }),
            )
        }),
        Local::Sensors(a) => {
            wire::decode_slice::<SensorResponseHeader, SensorInfo>(bytes, "sensor answer", 4096)
                .map(|(header, infos)| {
                    for info in &infos {
                        let kind = (info.spec.kind, info.spec.elements());
                        if let Err(e) =
                            sensors.ensure(names, limits, local, info.id, kind.0, kind.1)
                        {
                            warn!(
                                sensor = info.id,
                                "cannot create the sensor's service here: {}",
                                Chain(&e)
                            );
                        }
                    }
                    sent(
                        a.loan_slice_uninit(infos.len())
                            .map_err(iceoryx2::port::SendError::from)
                            .and_then(|mut r| {
                                *r.user_header_mut() = header;
                                r.write_from_slice(&infos).send()
                            }),
                    )
                })
        }
    };
    result.unwrap_or_else(Answered::Unreadable)
}

/// A tick's answer: a claim's names the local ticker, a release's clears
/// it; an OK tick's names it too (after a link drop, when the exporter
/// claimed the world again for it from a resumed server) and waits for
/// its frame.
fn answer_tick(
    active: &Active<TickRequest, TickResponse>,
    request: &TickRequest,
    answer: TickResponse,
    local_ticker: &mut Option<(u32, String)>,
) -> Answered {
    let ok = answer.status == ResponseStatus::Ok as u32;
    match TickRequestKind::from_u32(request.kind) {
        Some(TickRequestKind::Claim) if ok => {
            *local_ticker = Some((request.pid, request.node_name.to_string_lossy()));
        }
        Some(TickRequestKind::Release) if ok => *local_ticker = None,
        Some(TickRequestKind::Tick) if ok => {
            if local_ticker.is_none() {
                *local_ticker = Some((request.pid, request.node_name.to_string_lossy()));
            }
            return Answered::AfterFrame(Box::new(answer));
        }
        _ => {}
    }
    sent(active.send_copy(answer).map(drop))
}

pub(super) use simbus_transport::sender_pid;
