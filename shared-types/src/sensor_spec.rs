//! Building a [`SensorSpec`] for each kind of sensor from its typed
//! parameters, and the size of the captures it will make.

use crate::camera::Bgra;
use crate::events::{CollisionEvent, ObstacleDetection, MAX_COLLISION_EVENTS};
use crate::gnss::{Gnss, GnssMeasurement};
use crate::ranging::{RadarDetection, SemanticLidarPoint};
use crate::sensor::{ImuMeasurement, LidarPoint, SensorKind, SensorSpec};
use crate::sensor_params::{Camera, Imu, Lidar, SensorParams};

impl SensorSpec {
    /// A depth camera of `width` × `height` pixels, horizontal field of view
    /// `fov_degrees`, reading `far` metres where nothing is hit.
    pub fn depth(position: [f32; 3], width: u32, height: u32, fov_degrees: f32, far: f32) -> Self {
        let camera = Camera {
            width,
            height,
            fov: fov_degrees,
            range: far,
        };
        Self::with_params(position, camera)
    }

    /// A lidar with `channels` × `points_per_channel` rays per full turn,
    /// taking a full turn every capture (see [`SensorSpec::rotating`]).
    pub fn lidar(
        position: [f32; 3],
        channels: u32,
        points_per_channel: u32,
        range: f32,
        upper_fov: f32,
        lower_fov: f32,
    ) -> Self {
        let lidar = Lidar {
            channels,
            points: points_per_channel,
            range,
            upper_fov,
            lower_fov,
            rotation_hz: 0.0,
            noise: Default::default(),
        };
        Self::with_params(position, lidar)
    }

    /// A lidar spinning at `hz`: each capture covers `hz × Δt` of a turn
    /// (CARLA's partial scans); 0 takes a full turn every capture. Other
    /// kinds are returned unchanged.
    pub fn rotating(mut self, hz: f32) -> Self {
        let Some(lidar) = self.lidar_params() else {
            return self;
        };
        let lidar = Lidar {
            rotation_hz: hz,
            ..lidar
        };
        self.set_params(match self.sensor_kind() {
            Some(SensorKind::SemanticLidar) => SensorParams::SemanticLidar(lidar),
            _ => SensorParams::Lidar(lidar),
        });
        self
    }

    /// A semantic lidar with `lidar`'s parameters.
    pub fn semantic_lidar(position: [f32; 3], lidar: Lidar) -> Self {
        Self::with_params(position, SensorParams::SemanticLidar(lidar))
    }

    /// A camera of `kind` (depth, RGB, semantic or instance segmentation)
    /// of `width` × `height` pixels and horizontal field of view
    /// `fov_degrees`, seeing `far` metres; `None` for a kind that is not a
    /// camera.
    pub fn camera_of(
        kind: SensorKind,
        position: [f32; 3],
        (width, height): (u32, u32),
        fov_degrees: f32,
        far: f32,
    ) -> Option<Self> {
        let camera = Camera {
            width,
            height,
            fov: fov_degrees,
            range: far,
        };
        Some(Self::with_params(
            position,
            SensorParams::camera_of(kind, camera)?,
        ))
    }

    /// An IMU.
    pub fn imu(position: [f32; 3]) -> Self {
        Self::with_params(position, Imu)
    }

    /// A GNSS receiver without noise.
    pub fn gnss(position: [f32; 3]) -> Self {
        Self::with_params(position, Gnss::default())
    }

    /// How many payload elements one capture holds (pixels, lidar slots, 1).
    pub fn elements(&self) -> usize {
        match self.sensor_params() {
            Some(p) if p.kind().is_camera() => {
                let [w, h] = p.size();
                w as usize * h as usize
            }
            Some(SensorParams::Lidar(l) | SensorParams::SemanticLidar(l)) => {
                l.channels as usize * l.points as usize
            }
            Some(SensorParams::Radar(r)) => r.capacity().max(1),
            Some(SensorParams::Collision(_)) => MAX_COLLISION_EVENTS,
            _ => 1,
        }
    }

    /// The bytes of one capture's payload.
    pub fn payload_bytes(&self) -> usize {
        let element = match self.sensor_kind() {
            Some(SensorKind::Depth) => std::mem::size_of::<f32>(),
            Some(SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance) => {
                std::mem::size_of::<Bgra>()
            }
            Some(SensorKind::Lidar) => std::mem::size_of::<LidarPoint>(),
            Some(SensorKind::SemanticLidar) => std::mem::size_of::<SemanticLidarPoint>(),
            Some(SensorKind::Radar) => std::mem::size_of::<RadarDetection>(),
            Some(SensorKind::Gnss) => std::mem::size_of::<GnssMeasurement>(),
            Some(SensorKind::Collision) => std::mem::size_of::<CollisionEvent>(),
            Some(SensorKind::Obstacle) => std::mem::size_of::<ObstacleDetection>(),
            _ => std::mem::size_of::<ImuMeasurement>(),
        };
        self.elements() * element
    }
}
