//! `sim-client foxglove`: the world live in Foxglove, over the Foxglove
//! WebSocket protocol (subprotocol `foxglove.sdk.v1`, the `foxglove` SDK's
//! server). Open `ws://HOST:PORT` in Foxglove:
//!
//! - `/simbus/scene`: every actor as a `foxglove.SceneUpdate` entity (boxes,
//!   spheres, capsules as a cylinder and two spheres, vehicles, the ground),
//!   in frame `world` (simbus's: Y up, metres), one update per frame sent;
//! - the server's clock is the simulation's (the protocol's `time`
//!   capability), and every message is stamped with the frame's time;
//! - `/simbus/sensor/<id>/depth`: each depth camera as a `foxglove.RawImage`
//!   (`32FC1`, metres), `/simbus/sensor/<id>/points`: each lidar as a
//!   `foxglove.PointCloud` (x, y, z, intensity as float32) posed at the
//!   sensor in frame `world`.
//!
//! Frames are sent at the simulation's rate or at most `--max-hz`; the
//! captures sent are those of the frames sent. Sensors spawned later are
//! picked up within a second.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use foxglove::messages::{
    packed_element_field::NumericType, Color, CubePrimitive, CylinderPrimitive, PackedElementField,
    PointCloud, Pose, Quaternion, RawImage, SceneEntity, SceneUpdate, SpherePrimitive, Timestamp,
    Vector3,
};
use foxglove::websocket::Capability;
use foxglove::{Channel, Context, WebSocketServer};
use shared_types::{ActorKind, ActorState, SensorInfo, SensorKind, WorldName, NANOS_PER_SECOND};
use sim_client::{Client, Sensor, WaitMode};

use super::carla::convert::compose;
use crate::Failure;

/// Serve the world live to Foxglove over its WebSocket protocol.
#[derive(Debug, Args)]
pub(crate) struct FoxgloveArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Port to listen on (0: any free port; the one taken is printed).
    #[arg(long, default_value_t = 8765, allow_negative_numbers = true)]
    port: u16,
    /// Most frames sent per wall second, at most 1e6 (0: every frame).
    #[arg(long, value_name = "HZ", default_value_t = 30.0, allow_negative_numbers = true, value_parser = shared_types::input::rate_limit)]
    max_hz: f64,
}

/// A frame's simulation time as a Foxglove timestamp.
fn stamp(elapsed_ns: u64) -> Timestamp {
    Timestamp::new(
        u32::try_from(elapsed_ns / NANOS_PER_SECOND).unwrap_or(u32::MAX),
        (elapsed_ns % NANOS_PER_SECOND) as u32,
    )
}

fn vector(v: [f32; 3]) -> Vector3 {
    Vector3 {
        x: f64::from(v[0]),
        y: f64::from(v[1]),
        z: f64::from(v[2]),
    }
}

fn pose(position: [f32; 3], rotation: [f32; 4]) -> Pose {
    let [x, y, z, w] = rotation.map(f64::from);
    Pose {
        position: Some(vector(position)),
        orientation: Some(Quaternion { x, y, z, w }),
    }
}

/// No rotation (x, y, z, w).
const IDENTITY: [f32; 4] = [0.0, 0.0, 0.0, 1.0];

fn colour(kind: Option<ActorKind>) -> Color {
    let (r, g, b) = match kind {
        Some(ActorKind::Static) => (0.55, 0.55, 0.55),
        Some(ActorKind::Box) => (0.85, 0.55, 0.25),
        Some(ActorKind::Sphere) => (0.25, 0.55, 0.85),
        Some(ActorKind::Capsule) => (0.35, 0.75, 0.35),
        Some(ActorKind::Vehicle) => (0.85, 0.2, 0.2),
        None => (1.0, 0.0, 1.0),
    };
    Color { r, g, b, a: 1.0 }
}

/// One actor as a scene entity: its body as primitives in the body's frame.
fn entity(actor: &ActorState, time: Timestamp) -> SceneEntity {
    let kind = ActorKind::from_u32(actor.kind);
    let [ex, ey, ez] = actor.extent;
    let color = Some(colour(kind));
    let mut entity = SceneEntity {
        timestamp: Some(time),
        frame_id: "world".into(),
        id: actor.id.to_string(),
        ..Default::default()
    };
    let body = Some(pose(actor.position, actor.rotation));
    match kind {
        Some(ActorKind::Sphere) => entity.spheres.push(SpherePrimitive {
            pose: body,
            size: Some(vector([2.0 * ex; 3])),
            color,
        }),
        Some(ActorKind::Capsule) => {
            // A capsule (radius, half height): a cylinder along the body's Y
            // (Foxglove's run along Z: a quarter turn about X) and a sphere
            // at each end, placed in the world through the body's pose.
            let (radius, half) = (ex, ey);
            let quarter = std::f32::consts::FRAC_1_SQRT_2;
            entity.cylinders.push(CylinderPrimitive {
                pose: Some(placed(actor, ([0.0; 3], [quarter, 0.0, 0.0, quarter]))),
                size: Some(vector([2.0 * radius, 2.0 * radius, 2.0 * half])),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color,
            });
            for end in [-half, half] {
                entity.spheres.push(SpherePrimitive {
                    pose: Some(placed(actor, ([0.0, end, 0.0], IDENTITY))),
                    size: Some(vector([2.0 * radius; 3])),
                    color,
                });
            }
        }
        _ => entity.cubes.push(CubePrimitive {
            pose: body,
            size: Some(vector([2.0 * ex, 2.0 * ey, 2.0 * ez])),
            color,
        }),
    }
    entity
}

/// Something at `offset` (position, rotation) in the body of `actor`, in
/// the world frame.
fn placed(actor: &ActorState, offset: ([f32; 3], [f32; 4])) -> Pose {
    let (position, rotation) = compose((actor.position, actor.rotation), offset);
    pose(position, rotation)
}

/// A sensor forwarded to Foxglove.
enum Forward {
    Depth(Sensor, Channel<RawImage>),
    Lidar(Sensor, Channel<PointCloud>),
}

/// Subscribes to the depth cameras and lidars not forwarded yet.
fn pick_up(
    client: &Client,
    ctx: &std::sync::Arc<Context>,
    forwards: &mut BTreeMap<u64, Forward>,
) -> anyhow::Result<()> {
    let infos: Vec<SensorInfo> = client.list_sensors()?;
    // Sensors gone from the world: their channels go too.
    forwards.retain(|id, _| infos.iter().any(|i| i.id == *id));
    for info in infos {
        if forwards.contains_key(&info.id) {
            continue;
        }
        let topic = match SensorKind::from_u32(info.spec.kind) {
            Some(SensorKind::Depth) => "depth",
            Some(SensorKind::Lidar) => "points",
            _ => continue,
        };
        // A sensor destroyed since the list was read is skipped, not fatal.
        let sensor = match client.sensor(info.id) {
            Ok(sensor) => sensor,
            Err(e) => {
                tracing::warn!("sensor {} not forwarded: {e}", info.id);
                continue;
            }
        };
        let builder = ctx.channel_builder(format!("/simbus/sensor/{}/{topic}", info.id));
        let forward = if topic == "depth" {
            Forward::Depth(sensor, builder.build())
        } else {
            Forward::Lidar(sensor, builder.build())
        };
        forwards.insert(info.id, forward);
    }
    Ok(())
}

/// The lidar's pose in the world: its parent's pose (from `actors`, or the
/// origin) times its relative pose.
fn sensor_pose(sensor: &Sensor, actors: &[ActorState]) -> Pose {
    let spec = sensor.spec();
    let rotation = if spec.rotation == [0.0; 4] {
        IDENTITY
    } else {
        spec.rotation
    };
    match actors.iter().find(|a| a.id == spec.attach_to) {
        Some(parent) if spec.attach_to != 0 => placed(parent, (spec.position, rotation)),
        _ => pose(spec.position, rotation),
    }
}

/// Sends the newest capture of `forward` queued, if any (a slow viewer
/// skips captures, as it skips frames).
fn forward_capture(forward: &mut Forward, actors: &[ActorState]) {
    let (Forward::Depth(sensor, _) | Forward::Lidar(sensor, _)) = forward;
    let id = sensor.id();
    let mut newest = None;
    for capture in sensor.queue() {
        match capture {
            Ok(c) => newest = Some(c),
            Err(e) => {
                tracing::debug!("sensor {id} ended: {e}");
                break;
            }
        }
    }
    let Some(capture) = newest else {
        return;
    };
    let time = stamp(capture.header().elapsed_ns);
    match forward {
        Forward::Depth(sensor, channel) => {
            let [width, height] = capture.header().size;
            channel.log_with_time(
                &RawImage {
                    timestamp: Some(time),
                    frame_id: format!("sensor/{}", sensor.id()),
                    width,
                    height,
                    encoding: "32FC1".into(),
                    step: width * 4,
                    data: capture.bytes().to_vec().into(),
                },
                capture.header().elapsed_ns,
            );
        }
        Forward::Lidar(sensor, channel) => {
            let points = capture.points().unwrap_or_default();
            let field = |name: &str, offset: u32| PackedElementField {
                name: name.into(),
                offset,
                r#type: NumericType::Float32 as i32,
            };
            channel.log_with_time(
                &PointCloud {
                    timestamp: Some(time),
                    frame_id: "world".into(),
                    pose: Some(sensor_pose(sensor, actors)),
                    point_stride: 16,
                    fields: vec![
                        field("x", 0),
                        field("y", 4),
                        field("z", 8),
                        field("intensity", 12),
                    ],
                    data: bytemuck::cast_slice::<_, u8>(points).to_vec().into(),
                },
                capture.header().elapsed_ns,
            );
        }
    }
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: FoxgloveArgs) -> Result<(), Failure> {
    if !(args.max_hz.is_finite() && args.max_hz >= 0.0) {
        return Err(Failure::Refused(anyhow::anyhow!(
            "--max-hz must be 0 (every frame) or a positive rate, not {}",
            args.max_hz
        )));
    }
    let mut client = Client::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    client.set_wait_mode(WaitMode::Block);
    let ctx = Context::new();
    let server = WebSocketServer::new()
        .name(format!("simbus {world}"))
        .context(&ctx)
        .bind(args.host.clone(), args.port)
        .capabilities([Capability::Time])
        .start_blocking()
        .with_context(|| format!("listening on {}:{}", args.host, args.port))?;
    let scene: Channel<SceneUpdate> = ctx.channel_builder("/simbus/scene").build();
    println!(
        "foxglove: world '{world}' on ws://{}:{} (open it in Foxglove: Open connection → Foxglove WebSocket)",
        args.host,
        server.port()
    );
    let min_gap = if args.max_hz > 0.0 {
        Duration::from_secs_f64(1.0 / args.max_hz)
    } else {
        Duration::ZERO
    };
    let stop = super::interrupted();
    let mut forwards = BTreeMap::new();
    let mut last_sent: Option<Instant> = None;
    let mut last_look: Option<Instant> = None;
    let mut sent = 0u64;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        if last_look.is_none_or(|at| at.elapsed() >= Duration::from_secs(1)) {
            pick_up(&client, &ctx, &mut forwards)?;
            last_look = Some(Instant::now());
        }
        let frame = match super::in_slices(timeout, |slice| client.wait_for_frame(slice)) {
            Ok(Some(frame)) => frame,
            Ok(None) => break,
            // A paused world (synchronous, nobody ticking): keep serving.
            // A dead server ends the wait with its own error instead.
            Err(sim_client::WaitError::Timeout { .. }) => continue,
            Err(e) => return Err(e.into()),
        };
        if last_sent.is_some_and(|at| at.elapsed() < min_gap) {
            continue;
        }
        last_sent = Some(Instant::now());
        let elapsed_ns = frame.timestamp().elapsed_ns;
        let time = stamp(elapsed_ns);
        let actors = frame.actors();
        let update = SceneUpdate {
            deletions: Vec::new(),
            entities: actors.iter().map(|a| entity(a, time)).collect(),
        };
        server.broadcast_time(elapsed_ns);
        scene.log_with_time(&update, elapsed_ns);
        for forward in forwards.values_mut() {
            forward_capture(forward, actors);
        }
        sent += 1;
        drop(frame);
    }
    server.stop().wait_blocking();
    eprintln!("foxglove: {} sent", super::words::count(sent, "frame"));
    Ok(())
}
