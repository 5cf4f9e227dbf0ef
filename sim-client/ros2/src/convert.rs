//! One capture as its ROS 2 message: cameras as `sensor_msgs/Image` (+
//! `CameraInfo`), lidars and radars as `PointCloud2`, the IMU as `Imu`,
//! GNSS as `NavSatFix`, collisions as `carla_msgs/CarlaCollisionEvent`.
//! Stamped with the capture's simulation time; points in ROS's axes.

use shared_types::Camera;
use sim_client::Capture;

use crate::axes;
use crate::msg::{
    CameraInfo, CarlaCollisionEvent, Header, Image, Imu, NavSatFix, NavSatStatus, PointCloud2,
    PointField,
};

/// A camera capture as an image: RGB, semantic and instance cameras as
/// `bgra8` (CARLA's layouts: the semantic tag in red), depth as `32FC1`
/// in metres. `None` for a capture that is not an image.
pub(crate) fn image(capture: &Capture, frame_id: &str) -> Option<Image> {
    let header = capture.header();
    let [width, height] = header.size;
    let encoding = match capture {
        Capture::Depth(_) => "32FC1",
        Capture::Image(_) => "bgra8",
        _ => return None,
    };
    Some(Image {
        header: Header::new(header.elapsed_ns, frame_id),
        height,
        width,
        encoding: encoding.into(),
        is_bigendian: 0,
        step: width * 4,
        data: capture.bytes().to_vec(),
    })
}

/// The ideal pinhole model of `camera`: focal length from its horizontal
/// field of view, principal point at the centre, no distortion.
pub(crate) fn camera_info(camera: &Camera, elapsed_ns: u64, frame_id: &str) -> CameraInfo {
    let (w, h) = (f64::from(camera.width), f64::from(camera.height));
    let f = w / (2.0 * (f64::from(camera.fov).to_radians() / 2.0).tan());
    let (cx, cy) = (w / 2.0, h / 2.0);
    CameraInfo {
        header: Header::new(elapsed_ns, frame_id),
        height: camera.height,
        width: camera.width,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        ..CameraInfo::default()
    }
}

/// A cloud of `points` with `fields`, each point `step` bytes.
fn cloud(header: Header, fields: Vec<PointField>, step: u32, data: Vec<u8>) -> PointCloud2 {
    let width = u32::try_from(data.len()).unwrap_or(u32::MAX) / step.max(1);
    PointCloud2 {
        header,
        height: 1,
        width,
        fields,
        is_bigendian: false,
        point_step: step,
        row_step: step * width,
        data,
        is_dense: true,
    }
}

/// Appends the `f32`s to `data`, little-endian.
fn put(data: &mut Vec<u8>, values: &[f32]) {
    for v in values {
        data.extend_from_slice(&v.to_le_bytes());
    }
}

/// A lidar, semantic lidar or radar capture as a point cloud in the
/// sensor's frame, ROS's axes:
///
/// - lidar: `x, y, z, intensity` (float32, 16 bytes);
/// - semantic lidar: `x, y, z, cos_inc_angle` (float32), `object_idx`,
///   `object_tag` (uint32; CARLA's tags), 24 bytes;
/// - radar: `x, y, z, velocity, azimuth, altitude, depth` (float32, 28
///   bytes; velocity, azimuth and altitude as CARLA's radar gives them:
///   m/s, negative towards the sensor; radians, azimuth positive right).
pub(crate) fn points(capture: &Capture, frame_id: &str) -> Option<PointCloud2> {
    let header = Header::new(capture.header().elapsed_ns, frame_id);
    let float = |name: &str, at: u32| PointField::new(name, at, PointField::FLOAT32);
    let xyz = || vec![float("x", 0), float("y", 4), float("z", 8)];
    if let Some(points) = capture.points() {
        let mut data = Vec::with_capacity(points.len() * 16);
        for p in points {
            let [x, y, z] = axes::vector([p.x, p.y, p.z]);
            put(&mut data, &[x as f32, y as f32, z as f32, p.intensity]);
        }
        let mut fields = xyz();
        fields.push(float("intensity", 12));
        return Some(cloud(header, fields, 16, data));
    }
    if let Some(points) = capture.semantic_points() {
        let mut data = Vec::with_capacity(points.len() * 24);
        for p in points {
            let [x, y, z] = axes::vector([p.x, p.y, p.z]);
            put(&mut data, &[x as f32, y as f32, z as f32, p.cos_inc_angle]);
            data.extend_from_slice(&p.object_idx.to_le_bytes());
            data.extend_from_slice(&p.object_tag.to_le_bytes());
        }
        let mut fields = xyz();
        fields.push(float("cos_inc_angle", 12));
        fields.push(PointField::new("object_idx", 16, PointField::UINT32));
        fields.push(PointField::new("object_tag", 20, PointField::UINT32));
        return Some(cloud(header, fields, 24, data));
    }
    let detections = capture.detections()?;
    let mut data = Vec::with_capacity(detections.len() * 28);
    for d in detections {
        // Along the ray: forward, then right (azimuth) and up (altitude).
        let (forward, right, up) = (
            d.depth * d.altitude.cos() * d.azimuth.cos(),
            d.depth * d.altitude.cos() * d.azimuth.sin(),
            d.depth * d.altitude.sin(),
        );
        put(
            &mut data,
            &[
                forward, -right, up, d.velocity, d.azimuth, d.altitude, d.depth,
            ],
        );
    }
    let mut fields = xyz();
    for (i, name) in ["velocity", "azimuth", "altitude", "depth"]
        .iter()
        .enumerate()
    {
        fields.push(float(name, 12 + 4 * i as u32));
    }
    Some(cloud(header, fields, 28, data))
}

/// An IMU capture: its orientation in `map` (the sensor's pose at
/// capture), angular velocity and specific force in its own axes.
pub(crate) fn imu(capture: &Capture, frame_id: &str) -> Option<Imu> {
    let reading = capture.imu()?;
    let header = capture.header();
    Some(Imu {
        header: Header::new(header.elapsed_ns, frame_id),
        orientation: axes::quaternion(header.rotation),
        orientation_covariance: [0.0; 9],
        angular_velocity: axes::vector3(reading.gyroscope),
        angular_velocity_covariance: [0.0; 9],
        linear_acceleration: axes::vector3(reading.accelerometer),
        linear_acceleration_covariance: [0.0; 9],
    })
}

/// A GNSS capture as a fix.
pub(crate) fn fix(capture: &Capture, frame_id: &str) -> Option<NavSatFix> {
    let reading = capture.gnss()?;
    Some(NavSatFix {
        header: Header::new(capture.header().elapsed_ns, frame_id),
        status: NavSatStatus {
            status: 0,  // STATUS_FIX
            service: 1, // SERVICE_GPS
        },
        latitude: reading.latitude,
        longitude: reading.longitude,
        altitude: reading.altitude,
        position_covariance: [0.0; 9],
        position_covariance_type: 0, // COVARIANCE_TYPE_UNKNOWN
    })
}

/// A collision capture: one event per contact started this frame.
pub(crate) fn collisions(capture: &Capture, frame_id: &str) -> Vec<CarlaCollisionEvent> {
    let elapsed_ns = capture.header().elapsed_ns;
    capture
        .collisions()
        .unwrap_or_default()
        .iter()
        .map(|c| CarlaCollisionEvent {
            header: Header::new(elapsed_ns, frame_id),
            other_actor_id: u32::try_from(c.other_actor).unwrap_or(u32::MAX),
            normal_impulse: axes::vector3(c.normal_impulse),
        })
        .collect()
}
