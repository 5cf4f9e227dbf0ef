//! [`Capture`]: one sensor capture, borrowed from shared memory.

use iceoryx2::sample::Sample;
use shared_types::{
    Bgra, CollisionEvent, GnssMeasurement, ImuMeasurement, LidarPoint, ObstacleDetection,
    RadarDetection, SemanticLidarPoint, SensorHeader,
};
use simbus_transport::Bus;

/// One capture, borrowed from shared memory: nothing is copied until you do.
pub enum Capture {
    /// A depth image: `f32` planar depths, row by row.
    Depth(Sample<Bus, [f32], SensorHeader>),
    /// An RGB, semantic or instance segmentation image: [`Bgra`] pixels,
    /// row by row (the header's kind says which).
    Image(Sample<Bus, [Bgra], SensorHeader>),
    /// A lidar scan.
    Lidar(Sample<Bus, [LidarPoint], SensorHeader>),
    /// An IMU reading.
    Imu(Sample<Bus, [ImuMeasurement], SensorHeader>),
    /// A semantic lidar's returns.
    SemanticLidar(Sample<Bus, [SemanticLidarPoint], SensorHeader>),
    /// A radar's detections.
    Radar(Sample<Bus, [RadarDetection], SensorHeader>),
    /// A GNSS reading.
    Gnss(Sample<Bus, [GnssMeasurement], SensorHeader>),
    /// The contacts a collision sensor's parent started this frame.
    Collision(Sample<Bus, [CollisionEvent], SensorHeader>),
    /// What an obstacle detector saw ahead.
    Obstacle(Sample<Bus, [ObstacleDetection], SensorHeader>),
}

impl Capture {
    /// The capture's header: sensor, frame, simulation time, pose at capture.
    pub fn header(&self) -> &SensorHeader {
        match self {
            Self::Depth(s) => s.user_header(),
            Self::Image(s) => s.user_header(),
            Self::Lidar(s) => s.user_header(),
            Self::Imu(s) => s.user_header(),
            Self::Gnss(s) => s.user_header(),
            Self::SemanticLidar(s) => s.user_header(),
            Self::Radar(s) => s.user_header(),
            Self::Collision(s) => s.user_header(),
            Self::Obstacle(s) => s.user_header(),
        }
    }

    /// The depth image in place (width × height, row-major), if a depth capture.
    pub fn depth(&self) -> Option<&[f32]> {
        match self {
            Self::Depth(s) => Some(s.payload()),
            _ => None,
        }
    }

    /// The image's pixels in place (width × height, row-major, blue,
    /// green, red, alpha), if an RGB, semantic or instance capture.
    pub fn image(&self) -> Option<&[Bgra]> {
        match self {
            Self::Image(s) => Some(s.payload()),
            _ => None,
        }
    }

    /// The lidar returns in place (sensor frame), if a lidar capture.
    pub fn points(&self) -> Option<&[LidarPoint]> {
        match self {
            Self::Lidar(s) => Some(counted(s.payload(), s.user_header())),
            _ => None,
        }
    }

    /// The semantic lidar's returns in place (sensor frame), if a
    /// semantic lidar capture.
    pub fn semantic_points(&self) -> Option<&[SemanticLidarPoint]> {
        match self {
            Self::SemanticLidar(s) => Some(counted(s.payload(), s.user_header())),
            _ => None,
        }
    }

    /// The radar's detections in place, if a radar capture.
    pub fn detections(&self) -> Option<&[RadarDetection]> {
        match self {
            Self::Radar(s) => Some(counted(s.payload(), s.user_header())),
            _ => None,
        }
    }

    /// The IMU reading, if an IMU capture.
    pub fn imu(&self) -> Option<&ImuMeasurement> {
        match self {
            Self::Imu(s) => s.payload().first(),
            _ => None,
        }
    }

    /// The GNSS reading, if a GNSS capture.
    pub fn gnss(&self) -> Option<&GnssMeasurement> {
        match self {
            Self::Gnss(s) => s.payload().first(),
            _ => None,
        }
    }

    /// The collision events (one per contact the parent started this
    /// frame), if a collision capture.
    pub fn collisions(&self) -> Option<&[CollisionEvent]> {
        match self {
            Self::Collision(s) => Some(counted(s.payload(), s.user_header())),
            _ => None,
        }
    }

    /// What an obstacle detector saw, if an obstacle capture.
    pub fn obstacle(&self) -> Option<&ObstacleDetection> {
        match self {
            Self::Obstacle(s) => s.payload().first(),
            _ => None,
        }
    }

    /// The payload's bytes in place.
    pub fn bytes(&self) -> &[u8] {
        match self {
            Self::Depth(s) => bytemuck::cast_slice(s.payload()),
            Self::Image(s) => bytemuck::cast_slice(s.payload()),
            Self::Lidar(s) => bytemuck::cast_slice(s.payload()),
            Self::Imu(s) => bytemuck::cast_slice(s.payload()),
            Self::Gnss(s) => bytemuck::cast_slice(s.payload()),
            Self::SemanticLidar(s) => bytemuck::cast_slice(s.payload()),
            Self::Radar(s) => bytemuck::cast_slice(s.payload()),
            Self::Collision(s) => bytemuck::cast_slice(s.payload()),
            Self::Obstacle(s) => bytemuck::cast_slice(s.payload()),
        }
    }
}

/// The first `header.count` elements of `payload` (all of them if the
/// header says more: the sample's length bounds what is read).
fn counted<'a, T>(payload: &'a [T], header: &SensorHeader) -> &'a [T] {
    &payload[..(header.count as usize).min(payload.len())]
}
