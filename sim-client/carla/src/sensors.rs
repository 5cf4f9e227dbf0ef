//! Sensor streams: while a CARLA client listens to a sensor, a forwarder
//! thread reads its captures from shared memory and sends each as the
//! message CARLA's client decodes (`carla.Image` in the depth encoding,
//! `carla.LidarMeasurement`, `carla.IMUMeasurement`).

use std::sync::mpsc;
use std::sync::Arc;
use std::time::Duration;

use rmpv::Value;
use shared_types::{SensorKind, SensorSpec};
use sim_client::{Capture, Client, Sensor, WaitError};
use tracing::{debug, info};

use crate::convert;
use crate::derived::{self, Derived};
use crate::error::{CallError, Source};
use crate::locks::lock;
use crate::records::record_of;
use crate::stream::Hub;
use crate::wire as carla;

/// A forwarder's wait for a capture while no token is pending: none in
/// effect (it ends with a capture, the sensor, the server or its
/// listeners, never by the clock); finite only because a wait's deadline
/// is an `Instant`.
const NO_DEADLINE: Duration = Duration::from_secs(24 * 60 * 60);
/// The longest a capture waits for its frame's world state to go out
/// first (see [`Hub::after_world_state`]); past it, it goes anyway (the
/// world stream lags, or lost its server).
const WORLD_STATE_FIRST: Duration = Duration::from_millis(200);

/// A client will connect to sensor stream `stream` (it asked for its
/// token): make sure a forwarder feeds it, subscribed before this returns,
/// so that every capture from now on reaches the listener. The forwarder
/// follows a server restart: when the server exits and one resumed from
/// its journal comes back within `timeout`, it reads the same sensor from
/// it (a resume brings sensors back under their ids).
pub(crate) fn expect(
    hub: &Arc<Hub>,
    (world, run_pid, streaming_port): (&str, u32, u16),
    stream: u32,
    timeout: Duration,
) -> Result<(), CallError> {
    let spec = {
        let registry = lock(&hub.registry);
        registry
            .sensors
            .get(&stream)
            .filter(|s| !s.gone && s.simbus_id != 0)
            .map(|s| (s.simbus_id, s.spec, s.description.clone(), s.parent))
    };
    let Some((simbus_id, spec, description, parent)) = spec else {
        return Err(CallError::NoSensorStream(stream));
    };
    // A camera the gateway computes from the simbus one.
    let derived = description
        .as_array()
        .and_then(|d| d.get(1)?.as_str())
        .and_then(|id| Derived::of(id, |name| derived::attribute(&description, name)));
    if !hub.expect(stream) {
        return Ok(());
    }
    let (ready, started) = mpsc::channel();
    let (hub2, world) = (hub.clone(), world.to_string());
    let source = Forwarded {
        stream,
        simbus_id,
        spec,
        parent,
        streaming_port,
        run_pid,
        follow: timeout,
    };
    std::thread::spawn(move || forward(&hub2, &world, source, derived, &ready));
    match started.recv_timeout(timeout) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => {
            hub.forwarder_failed(stream);
            Err(e)
        }
        Err(_) => Err(CallError::SensorTimeout {
            id: simbus_id,
            timeout,
        }),
    }
}

/// The sensor a forwarder reads, and the CARLA stream it feeds.
#[derive(Debug, Clone, Copy)]
struct Forwarded {
    stream: u32,
    simbus_id: u64,
    spec: SensorSpec,
    /// The CARLA id of the actor it rides on (0: none).
    parent: u32,
    /// Where CARLA's clients read streams (an event's actors carry tokens).
    streaming_port: u16,
    /// The run of the world's server ([`sim_client::Status::run_pid`]).
    run_pid: u32,
    /// How long it waits for a server to come back after its own exited.
    follow: Duration,
}

/// The world's client and sensor `simbus_id` read from it.
fn open_sensor(world: &str, simbus_id: u64) -> Result<(Client, Sensor), Source> {
    let client =
        Client::connect(world, Duration::from_secs(5)).map_err(|e| Arc::new(e) as Source)?;
    let sensor = client
        .sensor(simbus_id)
        .map_err(|e| Arc::new(e) as Source)?;
    Ok((client, sensor))
}

/// After `client`'s server exited: the same sensor from the server that
/// came back within `timeout` to go on with run `run_pid` (resumed from
/// its journal), or `None` when none came, or a fresh run did.
fn follow_restart(
    client: &mut Client,
    run_pid: u32,
    simbus_id: u64,
    timeout: Duration,
) -> Option<Sensor> {
    let restarted = client
        .reconnect(timeout)
        .map_err(|e| debug!(sensor = simbus_id, "no server came back: {e}"))
        .ok()?;
    let run = client.status().ok()?.run_pid;
    if run != run_pid {
        debug!(
            sensor = simbus_id,
            "a new run began on the world: the sensor is gone"
        );
        return None;
    }
    let sensor = client
        .sensor(simbus_id)
        .map_err(|e| debug!(sensor = simbus_id, "not back with the resumed server: {e}"))
        .ok()?;
    info!(
        sensor = simbus_id,
        "{restarted}; forwarding the sensor goes on"
    );
    Some(sensor)
}

fn forward(
    hub: &Hub,
    world: &str,
    source: Forwarded,
    mut derived: Option<Derived>,
    ready: &mpsc::Sender<Result<(), CallError>>,
) {
    let Forwarded {
        stream,
        simbus_id,
        spec,
        parent,
        streaming_port,
        run_pid,
        follow,
    } = source;
    let (mut client, mut sensor) = match open_sensor(world, simbus_id) {
        Ok(opened) => opened,
        Err(e) => {
            let _ = ready.send(Err(CallError::SensorOpen {
                id: simbus_id,
                source: e,
            }));
            return;
        }
    };
    let _ = ready.send(Ok(()));
    info!(sensor = simbus_id, "forwarding a sensor to CARLA listeners");
    loop {
        // The one wait point: a capture, the sensor's or the server's end,
        // or a handed-out token giving up on its connection.
        let patience = hub.patience(stream).unwrap_or(NO_DEADLINE);
        match sensor.recv(patience) {
            Ok(capture) => {
                let h = capture.header();
                hub.after_world_state(run_pid, h.episode, h.frame, WORLD_STATE_FIRST);
                let actor = |id: u32| record_of(hub, id, streaming_port);
                let converted = match &mut derived {
                    Some(derived) => {
                        // A copy: the frame's pump is not held up meanwhile.
                        let actors = lock(&hub.actors).clone();
                        derived
                            .message(&capture, &spec, actors.get(&parent), &actors)
                            .map(|m| vec![m])
                    }
                    None => messages(&capture, &spec, stream, actor),
                };
                let sent = converted.is_some_and(|messages| {
                    messages
                        .iter()
                        .all(|m| hub.send_capture(stream, run_pid, h.episode, m))
                });
                if !sent {
                    debug!(
                        sensor = simbus_id,
                        frame = h.frame,
                        "a capture not forwarded"
                    );
                }
            }
            Err(WaitError::NoCapture { .. }) => {}
            Err(WaitError::ServerGone { .. }) => {
                match follow_restart(&mut client, run_pid, simbus_id, follow) {
                    Some(back) => sensor = back,
                    None => {
                        end_stream(hub, stream);
                        return;
                    }
                }
            }
            Err(e) => {
                debug!(sensor = simbus_id, "sensor stream ended: {e}");
                end_stream(hub, stream);
                return;
            }
        }
        if hub.retire(stream) {
            debug!(sensor = simbus_id, "nobody listens any more");
            return;
        }
    }
}

/// Sensor stream `stream` ended with its sensor: it is dying until a client
/// destroys it (or its episode ends).
fn end_stream(hub: &Hub, stream: u32) {
    if let Some(sensor) = lock(&hub.registry).sensors.get_mut(&stream) {
        sensor.gone = true;
    }
    hub.end(stream);
}

/// One capture as CARLA's stream messages: one per capture, but one per
/// event for a collision sensor (as CARLA sends them). `actor` gives the
/// `rpc::Actor` of a CARLA id: an event names the actor its sensor rides
/// on (CARLA's sensors report for their owner; the sensor itself, `stream`,
/// when it rides on nothing) and the actor met.
pub(crate) fn messages(
    capture: &Capture,
    spec: &SensorSpec,
    stream: u32,
    actor: impl Fn(u32) -> Option<Value>,
) -> Option<Vec<Vec<u8>>> {
    let h = capture.header();
    let transform = convert::transform(h.position, h.rotation);
    let elapsed = shared_types::nanos_to_seconds(h.elapsed_ns);
    let header = |sensor_type| {
        let mut out = Vec::with_capacity(carla::SENSOR_HEADER_LEN + 256);
        carla::sensor_header(&mut out, sensor_type, h.frame, elapsed, transform);
        out
    };
    // An event's two actors; an actor gone (or unknown to CARLA's ids)
    // drops the event.
    let owner = match spec.attach_to {
        0 => stream,
        parent => convert::actor_id(parent),
    };
    let pair = |other: u64| Some((actor(owner)?, actor(u32::try_from(other).ok()?)?));
    match capture {
        Capture::Collision(_) => {
            let events = capture.collisions()?;
            Some(
                events
                    .iter()
                    .filter_map(|e| {
                        let (me, other) = pair(e.other_actor)?;
                        let impulse = convert::vector(e.normal_impulse);
                        let payload = Value::Array(vec![
                            me,
                            other,
                            Value::Array(impulse.iter().map(|&v| Value::F32(v)).collect()),
                        ]);
                        let mut out = header(carla::COLLISION_SENSOR_TYPE);
                        rmpv::encode::write_value(&mut out, &payload).ok()?;
                        Some(out)
                    })
                    .collect(),
            )
        }
        Capture::Obstacle(_) => {
            let seen = capture.obstacle()?;
            let (me, other) = pair(seen.other_actor)?;
            let payload = Value::Array(vec![me, other, Value::F32(seen.distance)]);
            let mut out = header(carla::OBSTACLE_SENSOR_TYPE);
            rmpv::encode::write_value(&mut out, &payload).ok()?;
            Some(vec![out])
        }
        _ => message(capture, spec).map(|m| vec![m]),
    }
}

/// One capture of a camera, a lidar, an IMU or a GNSS receiver as CARLA's
/// stream message.
fn message(capture: &Capture, spec: &SensorSpec) -> Option<Vec<u8>> {
    let h = capture.header();
    let transform = convert::transform(h.position, h.rotation);
    let elapsed = shared_types::nanos_to_seconds(h.elapsed_ns);
    let sensor_type = match capture {
        Capture::Depth(_) => carla::DEPTH_SENSOR_TYPE,
        Capture::Image(_) => match SensorKind::from_u32(h.kind) {
            Some(SensorKind::Semantic) => carla::SEMANTIC_SENSOR_TYPE,
            Some(SensorKind::Instance) => carla::INSTANCE_SENSOR_TYPE,
            _ => carla::RGB_SENSOR_TYPE,
        },
        Capture::Lidar(_) => carla::LIDAR_SENSOR_TYPE,
        Capture::SemanticLidar(_) => carla::SEMANTIC_LIDAR_SENSOR_TYPE,
        Capture::Radar(_) => carla::RADAR_SENSOR_TYPE,
        Capture::Imu(_) => carla::IMU_SENSOR_TYPE,
        Capture::Gnss(_) => carla::GNSS_SENSOR_TYPE,
        Capture::Collision(_) | Capture::Obstacle(_) => return None,
    };
    // Room for the headers and the payload: one allocation for an image.
    let room = carla::SENSOR_HEADER_LEN + carla::IMAGE_HEADER_LEN + capture.bytes().len();
    let mut out = Vec::with_capacity(room);
    carla::sensor_header(&mut out, sensor_type, h.frame, elapsed, transform);
    match capture {
        Capture::Depth(_) => depth(&mut out, capture, spec)?,
        Capture::Image(_) => image(&mut out, capture, spec)?,
        Capture::Lidar(_) => lidar(&mut out, capture, spec)?,
        Capture::SemanticLidar(_) => semantic_lidar(&mut out, capture, spec)?,
        Capture::Radar(_) => radar(&mut out, capture)?,
        Capture::Imu(_) => imu(&mut out, capture)?,
        Capture::Gnss(_) => gnss(&mut out, capture)?,
        Capture::Collision(_) | Capture::Obstacle(_) => return None,
    }
    Some(out)
}

/// A depth capture as `carla.Image`'s payload: the image header, then
/// CARLA's depth encoding per pixel.
fn depth(out: &mut Vec<u8>, capture: &Capture, spec: &SensorSpec) -> Option<()> {
    let depth = capture.depth()?;
    let [w, hgt] = capture.header().size;
    out.reserve(carla::IMAGE_HEADER_LEN + depth.len() * 4);
    carla::image_header(out, w, hgt, spec.camera()?.fov);
    for &d in depth {
        out.extend_from_slice(&carla::depth_pixel(d));
    }
    Some(())
}

/// An RGB, semantic or instance capture as `carla.Image`'s payload: the
/// image header, then the pixels as they are (CARLA's BGRA).
fn image(out: &mut Vec<u8>, capture: &Capture, spec: &SensorSpec) -> Option<()> {
    let [w, hgt] = capture.header().size;
    carla::image_header(out, w, hgt, spec.camera()?.fov);
    out.extend_from_slice(capture.bytes());
    Some(())
}

/// A lidar's header as CARLA's lidar measurements start: the horizontal
/// angle the capture ended at (radians) and the returns per channel, each
/// return's channel found from its elevation (simbus writes them channel
/// by channel, as CARLA reads them).
fn lidar_header(
    out: &mut Vec<u8>,
    capture: &Capture,
    spec: &SensorSpec,
    points: impl ExactSizeIterator<Item = [f32; 3]> + Clone,
) -> Option<()> {
    let [channels, ..] = capture.header().size;
    let lidar_params = spec.lidar_params()?;
    let (upper, lower) = (lidar_params.upper_fov, lidar_params.lower_fov);
    let channel_of = |[x, y, z]: [f32; 3]| {
        if channels <= 1 {
            return 0;
        }
        let r = (x * x + y * y + z * z).sqrt().max(f32::MIN_POSITIVE);
        let elevation = (y / r).clamp(-1.0, 1.0).asin().to_degrees();
        let c = ((upper - elevation) / (upper - lower) * (channels - 1) as f32).round();
        (c.max(0.0) as usize).min(channels as usize - 1)
    };
    let mut counts = vec![0u32; channels.max(1) as usize];
    for p in points.clone() {
        counts[channel_of(p)] += 1;
    }
    let angle = points.last().map_or(0.0, |[x, _, z]| {
        z.atan2(x).rem_euclid(std::f32::consts::TAU)
    });
    carla::lidar_header(out, angle, &counts);
    Some(())
}

/// A lidar capture as `carla.LidarMeasurement`'s payload: the header, then
/// each return in CARLA's axes with its intensity.
fn lidar(out: &mut Vec<u8>, capture: &Capture, spec: &SensorSpec) -> Option<()> {
    let points = capture.points()?;
    lidar_header(out, capture, spec, points.iter().map(|p| [p.x, p.y, p.z]))?;
    for p in points {
        let [x, y, z] = convert::vector([p.x, p.y, p.z]);
        for v in [x, y, z, p.intensity] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    Some(())
}

/// A semantic lidar capture as `carla.SemanticLidarMeasurement`'s payload:
/// the header, then CARLA's 24-byte detections (the point in CARLA's axes,
/// the cosine of the incidence angle, the actor's id and its tag).
fn semantic_lidar(out: &mut Vec<u8>, capture: &Capture, spec: &SensorSpec) -> Option<()> {
    let points = capture.semantic_points()?;
    lidar_header(out, capture, spec, points.iter().map(|p| [p.x, p.y, p.z]))?;
    out.reserve(std::mem::size_of_val(points));
    for p in points {
        let [x, y, z] = convert::vector([p.x, p.y, p.z]);
        for v in [x, y, z, p.cos_inc_angle] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&p.object_idx.to_le_bytes());
        out.extend_from_slice(&p.object_tag.to_le_bytes());
    }
    Some(())
}

/// A radar capture as `carla.RadarMeasurement`'s payload: the detections
/// as they are (velocity, azimuth, altitude, depth; CARLA's axes share
/// simbus's azimuth to the right and altitude up), no count before them.
fn radar(out: &mut Vec<u8>, capture: &Capture) -> Option<()> {
    let bytes = std::mem::size_of_val(capture.detections()?);
    out.extend_from_slice(capture.bytes().get(..bytes)?);
    Some(())
}

/// An IMU capture as `carla.IMUMeasurement`'s payload (msgpack):
/// accelerometer, gyroscope (rad/s) and compass, in CARLA's axes.
fn imu(out: &mut Vec<u8>, capture: &Capture) -> Option<()> {
    let imu = capture.imu()?;
    let vector = |v: [f32; 3]| Value::Array(v.iter().map(|&x| Value::F32(x)).collect());
    let gyro = convert::angular_velocity(imu.gyroscope).map(f32::to_radians);
    let payload = Value::Array(vec![
        vector(convert::vector(imu.accelerometer)),
        vector(gyro),
        Value::F32(convert::compass(capture.header().rotation)),
    ]);
    rmpv::encode::write_value(out, &payload).ok()
}

/// A GNSS capture as `carla.GnssMeasurement`'s payload (msgpack):
/// CARLA's `GeoLocation`, latitude, longitude and altitude as doubles.
fn gnss(out: &mut Vec<u8>, capture: &Capture) -> Option<()> {
    let g = capture.gnss()?;
    let payload = Value::Array(vec![
        Value::F64(g.latitude),
        Value::F64(g.longitude),
        Value::F64(g.altitude),
    ]);
    rmpv::encode::write_value(out, &payload).ok()
}
