//! How `sim-client sensor watch` and `sensor save` show a capture: one
//! readable line, or one JSON object.

use shared_types::{GnssMeasurement, ImuMeasurement, SensorKind};
use sim_client::Capture;
use simbus_pose::compass;

use super::words::count;

/// What `sensor watch --json` prints for a capture, and `sensor save`
/// writes for an IMU's: the header, and an IMU's readings.
pub(super) fn capture_json(capture: &Capture, missed: u64) -> serde_json::Value {
    let h = capture.header();
    let kind = SensorKind::from_u32(h.kind).map_or("?", |k| k.name());
    let mut json = serde_json::json!({"sensor": h.sensor_id, "kind": kind, "frame": h.frame,
        "elapsed_ns": h.elapsed_ns, "sequence": h.sequence, "count": h.count,
        "bytes": capture.bytes().len(), "missed": missed,
        "position": h.position});
    if let (Some(imu), Some(object)) = (capture.imu(), json.as_object_mut()) {
        object.insert("accelerometer".into(), imu.accelerometer.into());
        object.insert("gyroscope".into(), imu.gyroscope.into());
        object.insert("compass".into(), compass(h.rotation).into());
    }
    if let (Some(events), Some(object)) = (capture.collisions(), json.as_object_mut()) {
        let events: Vec<_> = events
            .iter()
            .map(|e| serde_json::json!({"other_actor": e.other_actor, "normal_impulse": e.normal_impulse}))
            .collect();
        object.insert("collisions".into(), events.into());
    }
    if let (Some(seen), Some(object)) = (capture.obstacle(), json.as_object_mut()) {
        object.insert("other_actor".into(), seen.other_actor.into());
        object.insert("distance".into(), seen.distance.into());
    }
    if let (Some(gnss), Some(object)) = (capture.gnss(), json.as_object_mut()) {
        object.insert("latitude".into(), gnss.latitude.into());
        object.insert("longitude".into(), gnss.longitude.into());
        object.insert("altitude".into(), gnss.altitude.into());
    }
    json
}

/// A GNSS reading as one readable phrase.
pub(super) fn gnss_text(gnss: &GnssMeasurement) -> String {
    format!(
        "latitude {:.9}°  longitude {:.9}°  altitude {:.3} m",
        gnss.latitude, gnss.longitude, gnss.altitude
    )
}

/// An IMU's readings as one readable phrase.
pub(super) fn imu_text(imu: &ImuMeasurement, rotation: [f32; 4]) -> String {
    let [ax, ay, az] = imu.accelerometer;
    let [gx, gy, gz] = imu.gyroscope;
    format!(
        "accelerometer ({ax:.3}, {ay:.3}, {az:.3}) m/s²  gyroscope ({gx:.3}, {gy:.3}, {gz:.3}) rad/s  compass {:.3} rad",
        compass(rotation)
    )
}

pub(super) fn print_capture(capture: &Capture, missed: u64, json: bool) {
    let h = capture.header();
    let kind = SensorKind::from_u32(h.kind).map_or("?", |k| k.name());
    if json {
        println!("{}", capture_json(capture, missed));
    } else {
        let readings = capture
            .imu()
            .map(|imu| format!("  {}", imu_text(imu, h.rotation)))
            .or_else(|| capture.gnss().map(|g| format!("  {}", gnss_text(g))))
            .or_else(|| {
                let seen = capture.obstacle()?;
                Some(format!(
                    "  actor {} ahead at {:.3} m",
                    seen.other_actor, seen.distance
                ))
            })
            .or_else(|| {
                let detections = capture.detections()?;
                let nearest = detections
                    .iter()
                    .min_by(|a, b| a.depth.total_cmp(&b.depth))?;
                Some(format!(
                    "  nearest at {:.3} m moving {:+.3} m/s along the ray",
                    nearest.depth, nearest.velocity
                ))
            })
            .or_else(|| {
                let events = capture.collisions()?;
                let hits: Vec<String> = events
                    .iter()
                    .map(|e| {
                        let [x, y, z] = e.normal_impulse;
                        format!(
                            "actor {} impulse ({x:.3}, {y:.3}, {z:.3}) N·s",
                            e.other_actor
                        )
                    })
                    .collect();
                Some(format!("  hit {}", hits.join(", ")))
            })
            .unwrap_or_default();
        println!(
            "sensor {} {kind:<5} frame {:>7}  t = {:.6} s  #{}  {}  {}{readings}",
            h.sensor_id,
            h.frame,
            h.elapsed_ns as f64 / 1e9,
            h.sequence,
            count(capture.bytes().len() as u64, "byte"),
            count(h.count, "value")
        );
    }
}
