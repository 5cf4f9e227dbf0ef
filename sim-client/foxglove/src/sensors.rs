//! Depth cameras and lidars forwarded to Foxglove: each depth camera as a
//! `foxglove.RawImage` on `/simbus/sensor/<id>/depth`, each lidar as a
//! `foxglove.PointCloud` on `/simbus/sensor/<id>/points`.

use std::collections::BTreeMap;
use std::sync::Arc;

use foxglove::messages::{
    packed_element_field::NumericType, PackedElementField, PointCloud, Pose, RawImage,
};
use foxglove::{Channel, Context};
use shared_types::{ActorState, SensorInfo, SensorKind};
use sim_client::{Client, Sensor, SensorError};

use crate::scene::{placed, pose, stamp, IDENTITY};

/// A sensor forwarded to Foxglove.
pub(crate) enum Forward {
    Depth(Sensor, Channel<RawImage>),
    Lidar(Sensor, Channel<PointCloud>),
}

/// Subscribes to the depth cameras and lidars not forwarded yet.
pub(crate) fn pick_up(
    client: &Client,
    ctx: &Arc<Context>,
    forwards: &mut BTreeMap<u64, Forward>,
) -> Result<(), SensorError> {
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
pub(crate) fn forward_capture(forward: &mut Forward, actors: &[ActorState]) {
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
