//! The mirror's side of a local request: the bytes it is forwarded as,
//! and the answer it gets — the exporter's, a refusal, or
//! [`ResponseStatus::Unreachable`] while the exporter cannot be reached.

use iceoryx2::prelude::*;
use shared_types::bridge::{self, Forwarded};
use shared_types::{
    BatchResponseHeader, Bus, CommandResult, ControlResponse, LockstepResponse, RecorderResponse,
    ResponseStatus, SensorInfo, SensorResponseHeader, ServiceNames, TickRequest, TickRequestKind,
    TickResponse, PROTOCOL_VERSION,
};
use tracing::warn;

use super::local::{Active, Local, LocalServices, SensorPorts};

/// The pid of the process that sent a local request.
pub(super) fn sender_pid(
    header: &iceoryx2::service::header::request_response::RequestHeader,
) -> u32 {
    header
        .node_id()
        .pid::<Bus>()
        .map_or(0, |pid| u32::try_from(pid.value()).unwrap_or(0))
}

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
        Local::Control(a) => (Forwarded::Control, bridge::bytes_of(a.payload()).to_vec()),
        Local::Tick(_, payload) => (Forwarded::Tick, bridge::bytes_of(payload).to_vec()),
        Local::Lockstep(a) => {
            let mut payload = *a.payload();
            payload.pid = sender_pid(a.header());
            (Forwarded::Lockstep, bridge::bytes_of(&payload).to_vec())
        }
        Local::Recorder(a) => (Forwarded::Recorder, bridge::bytes_of(a.payload()).to_vec()),
        Local::Batch(a) => {
            let mut bytes = Vec::new();
            bridge::encode_slice(a.user_header(), a.payload(), &mut bytes);
            (Forwarded::Batch, bytes)
        }
        Local::Sensors(a) => (Forwarded::Sensors, bridge::bytes_of(a.payload()).to_vec()),
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
    Unreadable(String),
    /// A tick's answer, to be sent once its frame is published here.
    AfterFrame(Box<TickResponse>),
}

pub(super) fn send_tick(active: &Active<TickRequest, TickResponse>, answer: TickResponse) {
    if let Err(e) = active.send_copy(answer) {
        tracing::debug!("tick answer not delivered: {e:?}");
    }
}

/// Sends the exporter's answer `bytes` to the local request. A claim's
/// answer names the local ticker; a sensor list creates the listed
/// sensors' services here first.
pub(super) fn answer_local(
    request: &Local,
    bytes: &[u8],
    names: &ServiceNames,
    limits: &shared_types::limits::WorldLimits,
    local: &LocalServices,
    sensors: &mut SensorPorts,
    local_ticker: &mut Option<(u32, String)>,
) -> Answered {
    let bad = |e: shared_types::bridge::PayloadError| Answered::Unreadable(e.to_string());
    let sent = match request {
        Local::Control(a) => match bridge::decode_fixed::<ControlResponse>(bytes, "control answer")
        {
            Ok(mut answer) => {
                answer.report.server_pid = std::process::id();
                a.send_copy(answer)
            }
            Err(e) => return bad(e),
        },
        Local::Tick(a, request) => match bridge::decode_fixed::<TickResponse>(bytes, "tick answer")
        {
            Ok(answer) => {
                let ok = answer.status == ResponseStatus::Ok as u32;
                match TickRequestKind::from_u32(request.kind) {
                    Some(TickRequestKind::Claim) if ok => {
                        *local_ticker = Some((request.pid, request.node_name.to_string_lossy()));
                    }
                    Some(TickRequestKind::Release) if ok => *local_ticker = None,
                    _ => {}
                }
                if ok && TickRequestKind::from_u32(request.kind) == Some(TickRequestKind::Tick) {
                    return Answered::AfterFrame(Box::new(answer));
                }
                a.send_copy(answer)
            }
            Err(e) => return bad(e),
        },
        Local::Lockstep(a) => {
            match bridge::decode_fixed::<LockstepResponse>(bytes, "lockstep answer") {
                Ok(answer) => a.send_copy(answer),
                Err(e) => return bad(e),
            }
        }
        Local::Recorder(a) => {
            match bridge::decode_fixed::<RecorderResponse>(bytes, "recorder answer") {
                Ok(answer) => a.send_copy(answer),
                Err(e) => return bad(e),
            }
        }
        Local::Batch(a) => match bridge::decode_slice::<BatchResponseHeader, CommandResult>(
            bytes,
            "batch answer",
            super::relay::MAX_FORWARDED_BATCH,
        ) {
            Ok((header, results)) => a
                .loan_slice_uninit(results.len())
                .map_err(iceoryx2::port::SendError::from)
                .and_then(|mut r| {
                    *r.user_header_mut() = header;
                    r.write_from_slice(&results).send()
                }),
            Err(e) => return bad(e),
        },
        Local::Sensors(a) => match bridge::decode_slice::<SensorResponseHeader, SensorInfo>(
            bytes,
            "sensor answer",
            4096,
        ) {
            Ok((header, infos)) => {
                for info in &infos {
                    if let Err(e) = sensors.ensure(
                        names,
                        limits,
                        local,
                        info.id,
                        info.spec.kind,
                        info.spec.elements(),
                    ) {
                        warn!(
                            sensor = info.id,
                            "cannot create the sensor's service here: {e:#}"
                        );
                    }
                }
                a.loan_slice_uninit(infos.len())
                    .map_err(iceoryx2::port::SendError::from)
                    .and_then(|mut r| {
                        *r.user_header_mut() = header;
                        r.write_from_slice(&infos).send()
                    })
            }
            Err(e) => return bad(e),
        },
    };
    if let Err(e) = sent {
        tracing::debug!("answer to a local request not delivered: {e:?}");
    }
    Answered::Sent
}
