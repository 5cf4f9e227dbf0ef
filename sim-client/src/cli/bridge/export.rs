//! The exporting bridge, on the server's host: the world's frames and
//! captures published on Zenoh, its request services answered as Zenoh
//! queryables through ordinary simbus ports, tick ownership held for a
//! remote ticker and released when its mirror goes.
//!
//! Threads: one forwards frames (and `/clock`) and the captures of every
//! sensor (`frames.rs`); it owns its simbus ports. The main thread owns the request
//! ports and is woken through one channel by Zenoh's callbacks and by the
//! frame thread (a tick's answer goes back only once its frame is out).

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use shared_types::bridge::{self, BridgeKeys, Forwarded};
use shared_types::{
    ControlRequest, ControlResponse, FixedText, LockstepKind, LockstepRequest, LockstepResponse,
    RecorderRequest, RecorderResponse, ResponseStatus, ServiceNames, TickRequest, TickRequestKind,
    TickResponse, TickerInfo, WorldName, WorldSettings,
};
use sim_client::Client;
use tracing::{info, warn};
use zenoh::query::Query;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait as _};

use super::frames::{follow_sensors, forward_frames, Follow};
use super::relay::{self, Answer, BatchRelay, FixedRelay, SensorRelay};
use super::ZenohArgs;
use crate::Failure;

/// What wakes the main thread.
enum Event {
    /// A query on one of the world's keys.
    Query(Query),
    /// A mirror's liveliness token appeared (`true`) or went.
    Mirror(String, bool),
    /// The frame thread published this frame.
    Forwarded,
    /// The frame thread ended (the server is gone), with why.
    FramesEnded(String),
}

/// A ticker on another host, as its mirror named it.
#[derive(Debug, Clone, PartialEq)]
struct RemoteTicker {
    mirror: String,
    pid: u32,
    node_name: String,
}

/// Malformed or refused inputs, counted and logged.
#[derive(Debug, Default)]
struct Dropped {
    count: u64,
    last_warning: Option<Instant>,
    unwarned: u64,
}

impl Dropped {
    fn note(&mut self, query: &Query, why: &str) {
        self.count += 1;
        relay::refuse(query, why);
        // At most one warning a second, with the count since the last.
        self.unwarned += 1;
        if self
            .last_warning
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
        {
            warn!(
                key = %query.key_expr(),
                dropped = self.unwarned,
                total = self.count,
                "dropped a request from another host: {why}"
            );
            self.last_warning = Some(Instant::now());
            self.unwarned = 0;
        }
    }
}

/// The mirror's Zenoh id a query names in its `mirror` parameter.
fn mirror_of(query: &Query) -> Option<String> {
    query
        .parameters()
        .get("mirror")
        .filter(|m| !m.is_empty() && m.len() <= 64)
        .map(str::to_owned)
}

pub(super) fn run(
    world: &WorldName,
    timeout: Duration,
    args: &ZenohArgs,
    session: Session,
    stop: &'static AtomicBool,
) -> Result<(), Failure> {
    let mut client = Client::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let status = client.status()?;
    let keys = BridgeKeys::new(world);
    let names = ServiceNames::new(world);
    let (events, incoming) = mpsc::channel::<Event>();
    let zenoh = |e: zenoh::Error| anyhow::anyhow!("{e}");

    let _token = session
        .liveliness()
        .declare_token(keys.exporter())
        .wait()
        .map_err(zenoh)?;
    let to_main = events.clone();
    let _mirrors = session
        .liveliness()
        .declare_subscriber(keys.mirrors())
        .history(true)
        .callback(move |sample| {
            let zid = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
            let alive = sample.kind() == SampleKind::Put;
            let _ = to_main.send(Event::Mirror(zid.to_owned(), alive));
        })
        .wait()
        .map_err(zenoh)?;
    let to_main = events.clone();
    let _rpc = session
        .declare_queryable(keys.every_rpc())
        .callback(move |query| {
            let _ = to_main.send(Event::Query(query));
        })
        .wait()
        .map_err(zenoh)?;
    let to_main = events.clone();
    let _status = session
        .declare_queryable(keys.status())
        .callback(move |query| {
            let _ = to_main.send(Event::Query(query));
        })
        .wait()
        .map_err(zenoh)?;
    let to_main = events.clone();
    let _settings = session
        .declare_queryable(keys.settings())
        .callback(move |query| {
            let _ = to_main.send(Event::Query(query));
        })
        .wait()
        .map_err(zenoh)?;
    let latest = Arc::new(Mutex::new(Vec::<u8>::new()));
    let latest_for_query = latest.clone();
    let latest_key = keys.latest_frame();
    let _latest = session
        .declare_queryable(&latest_key)
        .callback(move |query| {
            let bytes = latest_for_query
                .lock()
                .map(|b| b.clone())
                .unwrap_or_default();
            if bytes.is_empty() {
                relay::refuse(&query, "no frame published yet");
            } else {
                relay::reply(&query, &bytes);
            }
        })
        .wait()
        .map_err(zenoh)?;

    let forwarded = Arc::new(AtomicU64::new(0));
    let (follow, followed) = mpsc::channel::<Follow>();
    let frames = {
        let (session, keys, world, events) =
            (session.clone(), keys.clone(), world.clone(), events.clone());
        let (latest, ros2_clock, forwarded) = (latest.clone(), args.ros2_clock, forwarded.clone());
        std::thread::Builder::new()
            .name("frames".into())
            .spawn(move || {
                let forwarded_one = || {
                    let _ = events.send(Event::Forwarded);
                };
                let why = forward_frames(
                    &world,
                    timeout,
                    &session,
                    &keys,
                    &latest,
                    ros2_clock,
                    &forwarded,
                    &forwarded_one,
                    &followed,
                    stop,
                )
                .err()
                .map_or_else(|| "stopped".to_owned(), |e| format!("{e:#}"));
                let _ = events.send(Event::FramesEnded(why));
            })
            .context("starting the frame thread")?
    };

    let node = client.node();
    let mut control = FixedRelay::<ControlRequest, ControlResponse>::open(node, &names.control)?;
    let mut tick = FixedRelay::<TickRequest, TickResponse>::open(node, &names.tick)?;
    let mut recorder =
        FixedRelay::<RecorderRequest, RecorderResponse>::open(node, &names.recorder)?;
    let mut batch = BatchRelay::open(node, &names.batch)?;
    let mut sensors = SensorRelay::open(node, &names.sensors)?;
    let wake = super::local::wake_notifier_on(node, &names)?;
    // One lockstep port per remote participant: the server tells
    // participants apart by their port.
    let mut lockstep: HashMap<(String, u32), FixedRelay<LockstepRequest, LockstepResponse>> =
        HashMap::new();
    let mut following = BTreeSet::new();
    let mut owner: Option<RemoteTicker> = None;
    let mut claimants: Vec<RemoteTicker> = Vec::new();
    let mut mirrors = BTreeSet::new();
    let mut held: Vec<Answer> = Vec::new();
    let mut answers = Vec::new();
    let mut dropped = Dropped::default();
    let mut next_sensor_scan = Instant::now();
    let mut idle = Duration::from_micros(20);

    // Announced once the current frame is out (a peer that then asks for
    // the latest frame gets it).
    let deadline = Instant::now() + timeout;
    while latest.lock().map_or(true, |bytes| bytes.is_empty()) {
        if frames.is_finished() || Instant::now() >= deadline {
            return Err(anyhow::anyhow!(
                "the world's current frame was not forwarded within {timeout:?}"
            )
            .into());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    println!(
        "exporting world '{world}' on {} (server pid {}, frame {})",
        args.listen.as_deref().unwrap_or("?"),
        status.server_pid,
        status.frame
    );
    info!(%world, zid = %session.zid(), "exporting");

    let result = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        if Instant::now() >= next_sensor_scan {
            next_sensor_scan = Instant::now() + Duration::from_secs(1);
            follow_sensors(&client, timeout, &mut following, &follow);
        }
        let busy = tick.busy()
            || control.busy()
            || recorder.busy()
            || batch.busy()
            || sensors.busy()
            || lockstep.values().any(FixedRelay::busy)
            || !held.is_empty();
        let wait = if busy {
            idle
        } else {
            Duration::from_millis(100)
        };
        let event = match incoming.recv_timeout(wait) {
            Ok(event) => {
                idle = Duration::from_micros(20);
                Some(event)
            }
            Err(RecvTimeoutError::Timeout) => {
                idle = (idle * 2).min(Duration::from_millis(1));
                None
            }
            Err(RecvTimeoutError::Disconnected) => break Ok(()),
        };
        match event {
            Some(Event::Query(query)) => {
                let key = query.key_expr().as_str().to_owned();
                let bytes = query
                    .payload()
                    .map(|p| p.to_bytes().into_owned())
                    .unwrap_or_default();
                if key == keys.status() || key == keys.settings() {
                    answer_json(&client, &query, key == keys.settings());
                    continue;
                }
                let Some(service) = Forwarded::ALL.into_iter().find(|s| keys.rpc(*s) == key) else {
                    dropped.note(&query, "no such service");
                    continue;
                };
                let Some(mirror) = mirror_of(&query) else {
                    dropped.note(
                        &query,
                        "a request must name its mirror (?mirror=<zenoh id>)",
                    );
                    continue;
                };
                let sent = match service {
                    Forwarded::Control => {
                        match FixedRelay::<ControlRequest, ControlResponse>::decode(&bytes) {
                            Ok(request) => control.send(request, query),
                            Err(e) => Err(relay::refused(
                                query,
                                format!("malformed control request: {e}"),
                            )),
                        }
                    }
                    Forwarded::Recorder => {
                        match FixedRelay::<RecorderRequest, RecorderResponse>::decode(&bytes) {
                            Ok(request) => recorder.send(request, query),
                            Err(e) => Err(relay::refused(
                                query,
                                format!("malformed recorder request: {e}"),
                            )),
                        }
                    }
                    Forwarded::Batch => batch.forward(&bytes, query),
                    Forwarded::Sensors => sensors.forward(&bytes, query),
                    Forwarded::Lockstep => {
                        match FixedRelay::<LockstepRequest, LockstepResponse>::decode(&bytes) {
                            Ok(request) => {
                                let participant = (mirror, request.pid);
                                let port = match lockstep.entry(participant) {
                                    std::collections::hash_map::Entry::Occupied(e) => {
                                        Ok(e.into_mut())
                                    }
                                    std::collections::hash_map::Entry::Vacant(e) => {
                                        FixedRelay::open(client.node(), &names.lockstep)
                                            .map(|port| e.insert(port))
                                    }
                                };
                                match port {
                                    Ok(port) => port.send(request, query),
                                    Err(e) => Err(relay::refused(
                                        query,
                                        format!("no lockstep port for this participant: {e:#}"),
                                    )),
                                }
                            }
                            Err(e) => Err(relay::refused(
                                query,
                                format!("malformed lockstep request: {e}"),
                            )),
                        }
                    }
                    Forwarded::Tick => {
                        match FixedRelay::<TickRequest, TickResponse>::decode(&bytes) {
                            Ok(request) => forward_tick(
                                request,
                                mirror,
                                query,
                                &mut tick,
                                &owner,
                                &mut claimants,
                                &forwarded,
                            ),
                            Err(e) => Err(relay::refused(
                                query,
                                format!("malformed tick request: {e}"),
                            )),
                        }
                    }
                };
                match sent {
                    // An idle (paced or waiting) server answers at once.
                    Ok(()) => {
                        if let Err(e) = wake.notify() {
                            tracing::debug!("wake-up not delivered: {e:?}");
                        }
                    }
                    Err(refused) => {
                        let (query, why) = *refused;
                        dropped.note(&query, &why);
                    }
                }
            }
            Some(Event::Mirror(zid, true)) => {
                info!(mirror = %zid, "a mirror joined");
                mirrors.insert(zid);
            }
            Some(Event::Mirror(zid, false)) => {
                info!(mirror = %zid, "a mirror left (its link dropped or it stopped)");
                mirrors.remove(&zid);
                if owner.as_ref().is_some_and(|o| o.mirror == zid) {
                    let lost = owner.take().expect("checked");
                    release_for(&mut tick, &lost);
                }
                // Its lockstep participants leave.
                let gone: Vec<_> = lockstep
                    .keys()
                    .filter(|(m, _)| *m == zid)
                    .cloned()
                    .collect();
                for key in gone {
                    if let Some(port) = lockstep.remove(&key) {
                        leave_for(port, key.1);
                    }
                }
            }
            Some(Event::Forwarded) | None => {}
            Some(Event::FramesEnded(why)) => {
                break Err(Failure::Runtime(anyhow::anyhow!(
                    "stopped forwarding frames: {why}"
                )))
            }
        }
        tick.poll(relay::tick_interim, relay::tick_frame, &mut answers);
        for answer in answers.drain(..) {
            // The server's word on who ticks now decides the remote owner.
            if let Ok(response) = bridge::decode_fixed::<TickResponse>(&answer.bytes, "tick answer")
            {
                owner = remote_owner(&response.ticker, &mut claimants);
            }
            held.push(answer);
        }
        control.poll(|_| false, |_| None, &mut held);
        recorder.poll(|_| false, |_| None, &mut held);
        batch.poll(&mut held);
        let before = held.len();
        sensors.poll(&mut held);
        if held.len() > before {
            // A sensor may have been spawned: its captures are forwarded
            // from before the answer goes, so none is missed.
            follow_sensors(&client, timeout, &mut following, &follow);
        }
        for port in lockstep.values_mut() {
            port.poll(|_| false, |_| None, &mut held);
        }
        // A tick's answer goes once its frame is on Zenoh, so a remote
        // reader that sees the answer finds the frame.
        let out = forwarded.load(Ordering::Acquire);
        held.retain(|answer| {
            if answer.frame.is_some_and(|frame| frame > out) {
                return true;
            }
            relay::reply(&answer.query, &answer.bytes);
            false
        });
    };
    if let Some(lost) = owner.take() {
        release_for(&mut tick, &lost);
    }
    drop(frames);
    info!(dropped = dropped.count, "export ended");
    result
}

/// Forwards a remote ticker's request, keeping the single-ticker rule
/// among remote tickers: only the remote owner (by mirror and pid) may
/// tick, set, or release; a claim by anyone else while it holds is refused
/// naming it.
fn forward_tick(
    mut request: TickRequest,
    mirror: String,
    query: Query,
    port: &mut FixedRelay<TickRequest, TickResponse>,
    owner: &Option<RemoteTicker>,
    claimants: &mut Vec<RemoteTicker>,
    forwarded: &AtomicU64,
) -> Result<(), relay::Refused> {
    let kind = TickRequestKind::from_u32(request.kind);
    let me = RemoteTicker {
        mirror,
        pid: request.pid,
        node_name: request.node_name.to_string_lossy(),
    };
    if let Some(current) = owner.as_ref().filter(|o| **o != me) {
        let info = TickerInfo {
            active: 1,
            pid: current.pid,
            since_frame: 0,
            node_name: FixedText::new(&current.node_name),
        };
        let answer = TickResponse::new(
            ResponseStatus::NotTicker,
            forwarded.load(Ordering::Acquire),
            0,
            info,
        );
        relay::reply(&query, bridge::bytes_of(&answer));
        return Ok(());
    }
    request.flags |= TickRequest::ON_BEHALF;
    if kind == Some(TickRequestKind::Claim) && !claimants.contains(&me) {
        // The server's answer says whether it became the owner.
        if claimants.len() >= MAX_CLAIMANTS {
            claimants.remove(0);
        }
        claimants.push(me);
    }
    port.send(request, query)
}

/// Remote claimants remembered until the server's answer names the owner.
const MAX_CLAIMANTS: usize = 16;

/// The remote ticker the server names as the owner in `ticker`, if it is
/// one of the `claimants` (a local ticker, or nobody: `None`).
fn remote_owner(ticker: &TickerInfo, claimants: &mut [RemoteTicker]) -> Option<RemoteTicker> {
    let ticker = ticker.active()?;
    let name = ticker.node_name.to_string_lossy();
    claimants
        .iter()
        .rev()
        .find(|c| c.pid == ticker.pid && c.node_name == name)
        .cloned()
}

/// Releases the ownership the bridge held for `lost`, whose mirror is gone.
fn release_for(port: &mut FixedRelay<TickRequest, TickResponse>, lost: &RemoteTicker) {
    let mut request = TickRequest::new(TickRequestKind::Release, &lost.node_name);
    request.flags |= TickRequest::ON_BEHALF;
    request.pid = lost.pid;
    info!(
        pid = lost.pid,
        node = %lost.node_name,
        "releasing the tick ownership held for a ticker whose mirror is gone"
    );
    // The answer is not awaited: the next claim is answered after it.
    if let Err(e) = port.send_detached(request) {
        warn!("releasing the lost remote ticker's ownership: {e:#}");
    }
}

/// Makes the remote participant `pid` leave the lockstep, so the server
/// stops waiting for it.
fn leave_for(mut port: FixedRelay<LockstepRequest, LockstepResponse>, pid: u32) {
    let mut request = LockstepRequest::new(LockstepKind::Leave, "", 0, 0);
    request.pid = pid;
    if let Err(e) = port.send_detached(request) {
        warn!("removing a lost remote participant: {e:#}");
    }
}

/// Answers a status or settings query with JSON.
fn answer_json(client: &Client, query: &Query, settings_only: bool) {
    let text = match client.status() {
        Ok(status) if settings_only => serde_json::to_string(&crate::cli::settings_json(
            &WorldSettings::from(status.settings),
        )),
        Ok(status) => {
            serde_json::to_string(&crate::cli::status::status_json(client.world(), &status))
        }
        Err(e) => {
            relay::refuse(query, &e.to_string());
            return;
        }
    };
    match text {
        Ok(text) => relay::reply(query, text.as_bytes()),
        Err(e) => relay::refuse(query, &e.to_string()),
    }
}
