//! The publishers of one sensor and of one vehicle.

use ros2_client::{Publisher, Subscription};
use shared_types::{Camera, SensorKind};
use sim_client::{Capture, Sensor};

use crate::convert;
use crate::dds::{Dds, Qos};
use crate::msg::{
    AckermannDriveStamped, CameraInfo, CarlaCollisionEvent, CarlaEgoVehicleControl,
    Float32MultiArray, Image, Imu, NavSatFix, Odometry, PointCloud2,
};
use crate::routes::Naming;
use crate::Ros2Error;

/// Where one sensor's captures go.
pub(crate) enum Out {
    /// A camera: the image and its model.
    Camera(Box<(Publisher<Image>, Publisher<CameraInfo>, Camera)>),
    /// A lidar, semantic lidar or radar.
    Cloud(Publisher<PointCloud2>),
    /// An IMU.
    Imu(Publisher<Imu>),
    /// A GNSS receiver.
    Fix(Publisher<NavSatFix>),
    /// A collision sensor.
    Collision(Publisher<CarlaCollisionEvent>),
}

/// One sensor published: its subscription, its topics, its frame.
pub(crate) struct SensorOut {
    pub(crate) sensor: Sensor,
    pub(crate) out: Out,
    /// The frame its data is in (a camera's optical frame).
    pub(crate) frame_id: String,
    /// The topic prefix (for the log).
    pub(crate) topic: String,
}

impl SensorOut {
    /// Publishers for `sensor` under `topic` (`None` for a kind with no
    /// ROS message: the obstacle detector).
    pub(crate) fn new(
        dds: &mut Dds,
        naming: &Naming,
        sensor: Sensor,
        topic: &str,
        frame: &str,
    ) -> Result<Option<Self>, Ros2Error> {
        let spec = *sensor.spec();
        let Some(kind) = spec.sensor_kind() else {
            return Ok(None);
        };
        let qos = match naming {
            Naming::Carla => Qos::Carla,
            Naming::Simbus { .. } => Qos::SensorData,
        };
        let (at, info) = naming.data_topics(topic, kind);
        let (out, frame_id) = match (kind, info) {
            (_, Some(info)) => {
                let Some(camera) = spec.camera() else {
                    return Ok(None);
                };
                let info = dds.publisher(&info, qos)?;
                (
                    Out::Camera(Box::new((dds.publisher(&at, qos)?, info, camera))),
                    naming.image_frame(frame),
                )
            }
            (SensorKind::Lidar | SensorKind::SemanticLidar | SensorKind::Radar, None) => {
                (Out::Cloud(dds.publisher(&at, qos)?), frame.to_owned())
            }
            (SensorKind::Imu, None) => (Out::Imu(dds.publisher(&at, qos)?), frame.to_owned()),
            (SensorKind::Gnss, None) => (Out::Fix(dds.publisher(&at, qos)?), frame.to_owned()),
            (SensorKind::Collision, None) => (
                Out::Collision(dds.publisher(&at, Qos::Reliable)?),
                frame.to_owned(),
            ),
            _ => return Ok(None),
        };
        Ok(Some(Self {
            sensor,
            out,
            frame_id,
            topic: topic.to_owned(),
        }))
    }

    /// Publishes `capture`; `false` if DDS refused it (counted by the
    /// caller as dropped).
    pub(crate) fn publish(&self, capture: &Capture) -> bool {
        let frame_id = self.frame_id.as_str();
        match &self.out {
            Out::Camera(camera) => {
                let (image, info, camera) = camera.as_ref();
                let Some(message) = convert::image(capture, frame_id) else {
                    return true;
                };
                let model = convert::camera_info(camera, capture.header().elapsed_ns, frame_id);
                image.publish(message).is_ok() & info.publish(model).is_ok()
            }
            Out::Cloud(cloud) => {
                convert::points(capture, frame_id).is_none_or(|m| cloud.publish(m).is_ok())
            }
            Out::Imu(imu) => convert::imu(capture, frame_id).is_none_or(|m| imu.publish(m).is_ok()),
            Out::Fix(fix) => convert::fix(capture, frame_id).is_none_or(|m| fix.publish(m).is_ok()),
            Out::Collision(events) => convert::collisions(capture, frame_id)
                .into_iter()
                .all(|m| events.publish(m).is_ok()),
        }
    }
}

/// One vehicle: its odometry out, its controls in.
pub(crate) struct VehicleOut {
    pub(crate) frame: String,
    pub(crate) odometry: Publisher<Odometry>,
    pub(crate) control: Option<Subscription<Float32MultiArray>>,
    pub(crate) carla: Subscription<CarlaEgoVehicleControl>,
    pub(crate) ackermann: Subscription<AckermannDriveStamped>,
}

impl VehicleOut {
    /// Topics for the vehicle named `frame` under `topic`.
    pub(crate) fn new(
        dds: &mut Dds,
        naming: &Naming,
        topic: &str,
        frame: &str,
    ) -> Result<Self, Ros2Error> {
        let (control, carla, ackermann) = naming.control_topics(topic);
        Ok(Self {
            frame: frame.to_owned(),
            odometry: dds.publisher(&format!("{topic}/odometry"), Qos::Reliable)?,
            control: control.map(|c| dds.subscription(&c)).transpose()?,
            carla: dds.subscription(&carla)?,
            ackermann: dds.subscription(&ackermann)?,
        })
    }
}
