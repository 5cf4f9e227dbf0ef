//! The mirroring bridge, on another host: the world's services created in
//! this host's shared memory, as a server would create them; every frame
//! and capture received from the exporting bridge published there; every
//! local request forwarded as a Zenoh query and its replies sent back.
//!
//! The mirror is the local clients' server: frames carry its pid, so a
//! local client notices when the mirror dies. While the exporter cannot be
//! reached, every request is answered at once with
//! [`ResponseStatus::Unreachable`]; frames missed meanwhile are reported as
//! a gap, never invented.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Sender, TryRecvError};
use std::time::{Duration, Instant};

use shared_types::bridge::{self, BridgeKeys, Forwarded};
use shared_types::{
    ControlRequest, ControlResponse, FixedText, RequestKind, ResponseStatus, ServiceNames,
    TickRequest, TickRequestKind, TickResponse, WorldName,
};
use tracing::{info, warn};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait as _};

use super::answers::{
    answer_local, refuse_local, request_bytes, send_tick, sender_pid, status_answer,
    unreachable_answer, Answered,
};
use super::local::{Active, Local, LocalServices, SensorPorts};
use super::ZenohArgs;
use crate::Failure;

/// How long a tick's answer waits here for its frame.
const HOLD_LIMIT: Duration = Duration::from_secs(2);

/// What wakes the mirror's main thread.
enum Event {
    /// A frame from the exporter.
    Frame(Vec<u8>),
    /// A capture from the exporter.
    Capture(Vec<u8>),
    /// A reply to forwarded request `id` (an error reply as its text).
    Reply(u64, Result<Vec<u8>, String>),
    /// Forwarded request `id` will get no more replies.
    Done(u64),
    /// The exporter's liveliness token appeared (`true`) or went.
    Exporter(bool),
}

/// A forwarded request: the local request and whether it was answered.
struct InFlight {
    local: Local,
    answered: bool,
}

/// This host's name, as remote tickers are reported (`host/node`).
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "mirror".to_owned())
}

pub(super) fn run(
    world: &WorldName,
    timeout: Duration,
    args: &ZenohArgs,
    session: Session,
    stop: &'static AtomicBool,
) -> Result<(), Failure> {
    let keys = BridgeKeys::new(world);
    let names = ServiceNames::new(world);
    let zid = session.zid().to_string();
    let endpoint = args.connect.as_deref().unwrap_or("?");
    let zenoh = |e: zenoh::Error| anyhow::anyhow!("{e}");

    // The world must be exported there: its status, then its current frame.
    let hello = ControlRequest::new(RequestKind::Status);
    info!(%world, %endpoint, "asking for the world's status (waiting up to {timeout:?})");
    let status = match query_until(
        &session,
        &keys.rpc(Forwarded::Control),
        &zid,
        bridge::bytes_of(&hello),
        timeout,
    ) {
        Ok(bytes) => bytes,
        Err(None) => {
            return Err(anyhow::anyhow!(
            "no bridge exports world '{world}' at {endpoint} (nothing answered within {timeout:?})"
        )
            .into())
        }
        Err(Some(e)) => return Err(anyhow::anyhow!("the exporting bridge refused: {e}").into()),
    };
    let status = match bridge::decode_fixed::<ControlResponse>(&status, "status answer") {
        Ok(answer) => answer,
        Err(e) => {
            return Err(anyhow::anyhow!(
                "cannot mirror world '{world}' from {endpoint}: {e} (mirror and exporter must be the same simbus version)"
            )
            .into())
        }
    };
    let first = query_once(&session, &keys.latest_frame(), &zid, &[], timeout).map_err(|e| {
        anyhow::anyhow!(
            "world '{world}' has no frame to mirror: {}",
            e.unwrap_or_default()
        )
    })?;
    let (mut header, actors) = bridge::decode_frame(&first)
        .map_err(|e| anyhow::anyhow!("the exporter's frame is unreadable: {e}"))?;

    let limits = shared_types::limits::WorldLimits {
        max_clients: status.report.max_clients.max(1) as usize,
        max_sensor_readers: status.report.max_sensor_readers.max(1) as usize,
    };
    let local = LocalServices::create(&names, &limits)?;
    let my_pid = std::process::id();
    header.server_pid = my_pid;
    local.publish_frame(&header, &actors)?;
    let mut last = (header.episode, header.timestamp.frame);

    let (events, incoming) = mpsc::channel::<Event>();
    let _token = session
        .liveliness()
        .declare_token(keys.mirror(&zid))
        .wait()
        .map_err(zenoh)?;
    let (to_main, wake_names) = (events.clone(), names.clone());
    let _exporter = session
        .liveliness()
        .declare_subscriber(keys.exporter())
        .history(true)
        .callback(move |sample| {
            let _ = to_main.send(Event::Exporter(sample.kind() == SampleKind::Put));
            super::local::wake(&wake_names);
        })
        .wait()
        .map_err(zenoh)?;
    let (to_main, wake_names) = (events.clone(), names.clone());
    let _frames = session
        .declare_subscriber(keys.frames())
        .callback(move |sample| {
            let _ = to_main.send(Event::Frame(sample.payload().to_bytes().into_owned()));
            super::local::wake(&wake_names);
        })
        .wait()
        .map_err(zenoh)?;
    let (to_main, wake_names) = (events.clone(), names.clone());
    let _captures = session
        .declare_subscriber(keys.sensors())
        .callback(move |sample| {
            let _ = to_main.send(Event::Capture(sample.payload().to_bytes().into_owned()));
            super::local::wake(&wake_names);
        })
        .wait()
        .map_err(zenoh)?;
    println!(
        "mirroring world '{world}' from {endpoint} (server pid {} there, frame {}); local clients connect as usual",
        status.report.server_pid, header.timestamp.frame
    );
    info!(%world, zid = %zid, "mirroring");

    let host = host_name();
    let mut sensors = SensorPorts::default();
    let mut in_flight: HashMap<u64, InFlight> = HashMap::new();
    // Tick answers waiting for their frame, and since when.
    let mut held: Vec<(Active<TickRequest, TickResponse>, TickResponse, Instant)> = Vec::new();
    let mut next_id = 0u64;
    let mut linked = true;
    let mut local_ticker: Option<(u32, String)> = None;
    let mut next_liveness_check = Instant::now();
    let mut dropped = 0u64;
    let mut requests = Vec::new();
    let request_timeout = args.request_timeout;

    let result = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        // One wait for everything: local clients and Zenoh's callbacks
        // both wake the listener (see `local::wake`).
        let event = match incoming.try_recv() {
            Ok(event) => Some(event),
            Err(TryRecvError::Empty) => {
                local.wait(Duration::from_millis(50))?;
                incoming.try_recv().ok()
            }
            Err(TryRecvError::Disconnected) => break Ok(()),
        };
        match event {
            Some(Event::Frame(bytes)) => match bridge::decode_frame(&bytes) {
                Ok((mut header, actors)) => {
                    let key = (header.episode, header.timestamp.frame);
                    if key <= last {
                        continue;
                    }
                    let sync = header.settings.synchronous_mode != 0;
                    if sync && header.episode == last.0 && key.1 > last.1 + 1 {
                        warn!(
                            from = last.1 + 1,
                            to = key.1 - 1,
                            "frames {}..={} never arrived (the link was down); they are not invented",
                            last.1 + 1,
                            key.1 - 1
                        );
                    }
                    last = key;
                    header.server_pid = my_pid;
                    local.publish_frame(&header, &actors)?;
                    // Tick answers held for this frame go now.
                    held.retain(|(active, answer, _)| {
                        if answer.frame > key.1 {
                            return true;
                        }
                        send_tick(active, *answer);
                        false
                    });
                    local.notify();
                }
                Err(e) => {
                    dropped += 1;
                    warn!(dropped, "dropped a frame publication: {e}");
                }
            },
            Some(Event::Capture(bytes)) => match bridge::decode_capture(&bytes) {
                Ok((header, payload)) => {
                    if let Err(e) = sensors.publish(&names, &limits, &local, &header, payload) {
                        dropped += 1;
                        warn!(
                            dropped,
                            sensor = header.sensor_id,
                            "dropped a capture: {e:#}"
                        );
                    } else {
                        local.notify();
                    }
                }
                Err(e) => {
                    dropped += 1;
                    warn!(dropped, "dropped a capture publication: {e}");
                }
            },
            Some(Event::Reply(id, reply)) => {
                let Some(flight) = in_flight.get_mut(&id) else {
                    continue;
                };
                flight.answered = true;
                let answered = match reply {
                    Ok(bytes) => answer_local(
                        &flight.local,
                        &bytes,
                        &names,
                        &limits,
                        &local,
                        &mut sensors,
                        &mut local_ticker,
                    ),
                    Err(e) => {
                        warn!("the exporter refused a request: {e}");
                        refuse_local(&flight.local, ResponseStatus::Refused);
                        Answered::Sent
                    }
                };
                match answered {
                    Answered::Sent => {}
                    Answered::Unreadable(why) => {
                        dropped += 1;
                        warn!(dropped, "an answer from the exporter is unreadable: {why}");
                        unreachable_answer(&flight.local);
                    }
                    Answered::AfterFrame(answer) => {
                        let answer = *answer;
                        // Sent once its frame is published here.
                        if let Some(InFlight {
                            local: Local::Tick(active, _),
                            ..
                        }) = in_flight.remove(&id)
                        {
                            if answer.frame <= last.1 {
                                send_tick(&active, answer);
                            } else {
                                held.push((active, answer, Instant::now()));
                            }
                        }
                    }
                }
                local.notify();
            }
            Some(Event::Done(id)) => {
                if let Some(flight) = in_flight.remove(&id) {
                    if !flight.answered {
                        // No reply at all: the exporter is out of reach.
                        unreachable_answer(&flight.local);
                        local.notify();
                    }
                }
            }
            Some(Event::Exporter(alive)) if alive != linked => {
                linked = alive;
                if alive {
                    info!("the exporting bridge is reachable again");
                    println!("link up: the exporting bridge is reachable again");
                } else {
                    warn!(
                        "the exporting bridge is out of reach; requests are answered 'unreachable'"
                    );
                    println!("link down: the exporting bridge is out of reach");
                    for (_, flight) in in_flight.drain() {
                        if !flight.answered {
                            unreachable_answer(&flight.local);
                        }
                    }
                    for (active, _, _) in held.drain(..) {
                        let _ = active.send_copy(status_answer(ResponseStatus::Unreachable));
                    }
                    // The exporter releases the ownership it held for us.
                    local_ticker = None;
                    local.notify();
                }
            }
            Some(Event::Exporter(_)) => {}
            None => {}
        }
        // Local requests: forwarded, or answered 'unreachable' at once.
        local.connect_new_subscribers();
        local.receive_requests(&mut requests)?;
        for mut request in requests.drain(..) {
            if let Local::Tick(active, payload) = &mut request {
                payload.pid = sender_pid(active.header());
                let name = format!("{host}/{}", payload.node_name.to_string_lossy());
                payload.node_name = FixedText::new(&name);
            }
            if !linked {
                unreachable_answer(&request);
                local.notify();
                continue;
            }
            next_id += 1;
            let id = next_id;
            let (service, bytes) = request_bytes(&request);
            forward(
                &session,
                &names,
                &keys,
                service,
                &zid,
                bytes,
                request_timeout,
                id,
                &events,
            );
            in_flight.insert(
                id,
                InFlight {
                    local: request,
                    answered: false,
                },
            );
        }
        // A local ticker that died is released for it; a tick answer whose
        // frame never came (a new episode, a lost publication) goes anyway.
        if Instant::now() >= next_liveness_check {
            next_liveness_check = Instant::now() + Duration::from_millis(100);
            held.retain(|(active, answer, since)| {
                if since.elapsed() < HOLD_LIMIT {
                    return true;
                }
                warn!(
                    frame = answer.frame,
                    "the frame of a tick's answer did not arrive; answering without it"
                );
                send_tick(active, *answer);
                false
            });
            if let Some((pid, name)) = local_ticker.clone() {
                if !sim_client::process_alive(pid) {
                    info!(pid, "the local ticker died; releasing its ownership");
                    let mut release = TickRequest::new(TickRequestKind::Release, &name);
                    release.pid = pid;
                    next_id += 1;
                    forward(
                        &session,
                        &names,
                        &keys,
                        Forwarded::Tick,
                        &zid,
                        bridge::bytes_of(&release).to_vec(),
                        request_timeout,
                        next_id,
                        &events,
                    );
                    local_ticker = None;
                }
            }
        }
    };
    info!(dropped, "mirror ended");
    result
}

/// Sends `bytes` to the exporter's `service` as a query; its replies come
/// back as [`Event::Reply`] and its end as [`Event::Done`].
#[allow(clippy::too_many_arguments)]
fn forward(
    session: &Session,
    names: &ServiceNames,
    keys: &BridgeKeys,
    service: Forwarded,
    zid: &str,
    bytes: Vec<u8>,
    timeout: Duration,
    id: u64,
    events: &Sender<Event>,
) {
    /// Sends [`Event::Done`] when Zenoh drops the callback (no more replies).
    struct Finished(u64, Sender<Event>, ServiceNames);
    impl Drop for Finished {
        fn drop(&mut self) {
            let _ = self.1.send(Event::Done(self.0));
            super::local::wake(&self.2);
        }
    }
    let finished = Finished(id, events.clone(), names.clone());
    let (to_main, wake_names) = (events.clone(), names.clone());
    let selector = format!("{}?mirror={zid}", keys.rpc(service));
    let sent = session
        .get(selector)
        .payload(bytes)
        .timeout(timeout)
        .express(true)
        .callback(move |reply| {
            let _ = &finished;
            let reply = match reply.result() {
                Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
            };
            let _ = to_main.send(Event::Reply(id, reply));
            super::local::wake(&wake_names);
        })
        .wait();
    if let Err(e) = sent {
        warn!("cannot forward a request: {e}");
    }
}

/// [`query_once`] asked again until something answers or `timeout` is
/// over: while the link is still being made (the exporter not up yet, or
/// Zenoh retrying the connection), a query finds no route and ends at
/// once, which is not "nothing answered within `timeout`".
fn query_until(
    session: &Session,
    key: &str,
    zid: &str,
    payload: &[u8],
    timeout: Duration,
) -> Result<Vec<u8>, Option<String>> {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match query_once(session, key, zid, payload, left) {
            Err(None)
                if Instant::now() < deadline
                    && !crate::cli::interrupted().load(std::sync::atomic::Ordering::Relaxed) =>
            {
                // The next try after Zenoh's own connection retry (250 ms).
                std::thread::sleep(left.min(Duration::from_millis(100)));
            }
            other => return other,
        }
    }
}

/// One query and its first reply: `Err(None)` when nothing answered.
fn query_once(
    session: &Session,
    key: &str,
    zid: &str,
    payload: &[u8],
    timeout: Duration,
) -> Result<Vec<u8>, Option<String>> {
    let replies = session
        .get(format!("{key}?mirror={zid}"))
        .payload(payload.to_vec())
        .timeout(timeout)
        .wait()
        .map_err(|e| Some(e.to_string()))?;
    match replies.recv() {
        Ok(reply) => match reply.result() {
            Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
            Err(e) => Err(Some(
                String::from_utf8_lossy(&e.payload().to_bytes()).into_owned(),
            )),
        },
        Err(_) => Err(None),
    }
}
