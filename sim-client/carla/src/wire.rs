//! CARLA 0.9.16's binary stream layouts, as its client library reads them:
//! the stream token, the 48-byte sensor header every stream message starts
//! with, and the world state (episode header and one 119-byte record per
//! actor). All little-endian and packed. The RPC side is msgpack (built in
//! the gateway with `rmpv`).
//!
//! Sources: CARLA's `LibCarla/source/carla/streaming/detail/Token.h`,
//! `sensor/s11n/SensorHeaderSerializer.h`, `sensor/s11n/EpisodeStateSerializer.h`,
//! `sensor/data/ActorDynamicState.h`, checked against the 0.9.16 wheel.

use shared_types::LightState;

/// Bytes of a stream token.
pub const TOKEN_LEN: usize = 24;
/// Bytes of the header every stream message starts with.
pub const SENSOR_HEADER_LEN: usize = 48;
/// Bytes of the world state's episode header (after the sensor header).
pub const EPISODE_HEADER_LEN: usize = 36;
/// Bytes of one actor's record in the world state.
pub const ACTOR_STATE_LEN: usize = 119;
/// The sensor type id of the world state in 0.9.16's sensor registry.
pub const WORLD_STATE_SENSOR_TYPE: u64 = 17;
/// The gateway's own key of the world stream. CARLA clients subscribe to
/// it under any id of [`is_world_stream`]: each `get_episode_info` hands
/// out a new one (see [`crate::stream::Hub::next_world_stream`]).
pub const WORLD_STREAM_ID: u32 = 1;
/// The sensor type id of a collision sensor's `carla.CollisionEvent`.
pub const COLLISION_SENSOR_TYPE: u64 = 0;
/// The sensor type id of an obstacle detector's
/// `carla.ObstacleDetectionEvent`.
pub const OBSTACLE_SENSOR_TYPE: u64 = 7;
/// The sensor type id of a depth camera's `carla.Image`.
pub const DEPTH_SENSOR_TYPE: u64 = 1;
/// The sensor type id of a GNSS receiver's `carla.GnssMeasurement`.
pub const GNSS_SENSOR_TYPE: u64 = 4;
/// The sensor type id of an IMU's `carla.IMUMeasurement`.
pub const IMU_SENSOR_TYPE: u64 = 5;
/// The sensor type id of a radar's `carla.RadarMeasurement`.
pub const RADAR_SENSOR_TYPE: u64 = 9;
/// The sensor type id of a semantic lidar's
/// `carla.SemanticLidarMeasurement`.
pub const SEMANTIC_LIDAR_SENSOR_TYPE: u64 = 10;
/// The sensor type id of a ray-cast lidar's `carla.LidarMeasurement`.
pub const LIDAR_SENSOR_TYPE: u64 = 11;
/// `ASceneCaptureCamera` (`sensor.camera.rgb`): `carla.Image`.
pub const RGB_SENSOR_TYPE: u64 = 13;
/// `ASemanticSegmentationCamera`: `carla.Image`, the tag in red.
pub const SEMANTIC_SENSOR_TYPE: u64 = 14;
/// `AInstanceSegmentationCamera`: `carla.Image`, the tag in red, the
/// actor's id in green and blue.
pub const INSTANCE_SENSOR_TYPE: u64 = 15;
/// Bytes of an image's header (width, height, field of view).
pub const IMAGE_HEADER_LEN: usize = 12;
/// CARLA's depth camera encodes 0..=1000 m in 24 bits.
pub const DEPTH_FAR_METRES: f32 = 1000.0;
/// CARLA actor ids at and above this name simbus sensors (sensor `n` is
/// `SENSOR_ID_BASE + n`): simbus numbers sensors apart from actors, CARLA
/// numbers them together. The sensor's stream id is its actor id.
pub const SENSOR_ID_BASE: u32 = 1_000_000_000;
/// Whether stream id `stream` names the world stream: every id below the
/// sensors' ([`SENSOR_ID_BASE`]) but 0.
pub fn is_world_stream(stream: u32) -> bool {
    (1..SENSOR_ID_BASE).contains(&stream)
}

/// The world stream id handed out after `previous` (0: none yet): the
/// next one, from 1 again past the last.
pub fn world_stream_after(previous: u32) -> u32 {
    match previous.checked_add(1) {
        Some(next) if is_world_stream(next) => next,
        _ => 1,
    }
}

/// CARLA actor ids at and above this name sensors CARLA's client computes
/// itself (the lane-invasion sensor): the gateway numbers them, simbus has
/// no sensor behind them.
pub const CLIENT_SIDE_SENSOR_BASE: u32 = 3_000_000_000;

/// The CARLA actor id (and stream id) of simbus sensor `id`.
pub fn carla_id(simbus_id: u64) -> Option<u32> {
    u32::try_from(simbus_id)
        .ok()
        .and_then(|n| n.checked_add(SENSOR_ID_BASE))
}

/// The simbus sensor behind CARLA actor `id`, if it names one.
pub fn simbus_id(id: u32) -> Option<u64> {
    id.checked_sub(SENSOR_ID_BASE)
        .filter(|&n| n > 0 && id < CLIENT_SIDE_SENSOR_BASE)
        .map(u64::from)
}

/// Whether CARLA actor `id` names a sensor: simbus's, or one CARLA's
/// client computes itself.
pub fn is_sensor(id: u32) -> bool {
    id > SENSOR_ID_BASE
}

/// The CARLA actor id of the `n`th client-side sensor (from 0), if in range.
pub fn client_side_id(n: u32) -> Option<u32> {
    CLIENT_SIDE_SENSOR_BASE.checked_add(n)
}
/// The CARLA actor id of the world's spectator: `SENSOR_ID_BASE` itself,
/// sensor 0, which simbus never numbers (its sensors count from 1), and
/// above every simbus actor id CARLA can name.
pub const SPECTATOR_ID: u32 = SENSOR_ID_BASE;
/// The version the gateway reports (`client.get_server_version()`).
pub const CARLA_VERSION: &str = "0.9.16";

/// CARLA's episode id of simbus episode `episode` of the run `run_pid`
/// (the pid of the server that began it, which a server resumed from its
/// journal goes on with): a fresh server on the same world starts a new
/// CARLA episode (CARLA's client resets its state when the id changes;
/// simbus numbers episodes from 1 in each run), a resumed one goes on with
/// the episode its clients had.
pub fn episode_id(run_pid: u32, episode: u64) -> u64 {
    (u64::from(run_pid) << 32) | (episode & 0xFFFF_FFFF)
}

/// A stream token: where (TCP, `port`, the RPC host) to subscribe to
/// `stream_id`. The address is left unset, so the client uses the host it
/// connected to for RPC.
pub fn token(stream_id: u32, port: u16) -> [u8; TOKEN_LEN] {
    let mut token = [0u8; TOKEN_LEN];
    token[0..4].copy_from_slice(&stream_id.to_le_bytes());
    token[4..6].copy_from_slice(&port.to_le_bytes());
    token[6] = 1; // TCP
    token[7] = 0; // address: the host the client connected to
    token
}

/// A CARLA transform: location in metres (x forward, y right, z up,
/// left-handed) and rotation in degrees (pitch, yaw, roll).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CarlaTransform {
    /// x, y, z.
    pub location: [f32; 3],
    /// pitch, yaw, roll.
    pub rotation: [f32; 3],
}

/// Appends the 48-byte sensor header.
pub fn sensor_header(
    out: &mut Vec<u8>,
    sensor_type: u64,
    frame: u64,
    elapsed_seconds: f64,
    transform: CarlaTransform,
) {
    out.extend_from_slice(&sensor_type.to_le_bytes());
    out.extend_from_slice(&frame.to_le_bytes());
    out.extend_from_slice(&elapsed_seconds.to_le_bytes());
    for v in transform.location.iter().chain(&transform.rotation) {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Appends the world state's episode header.
pub fn episode_header(
    out: &mut Vec<u8>,
    episode_id: u64,
    platform_timestamp: f64,
    delta_seconds: f32,
) {
    out.extend_from_slice(&episode_id.to_le_bytes());
    out.extend_from_slice(&platform_timestamp.to_le_bytes());
    out.extend_from_slice(&delta_seconds.to_le_bytes());
    out.extend_from_slice(&[0u8; 12]); // map origin (large worlds): 0, 0, 0
    out.extend_from_slice(&0u32.to_le_bytes()); // simulation state flags
}

/// Appends a `carla.Image` payload header: `width` × `height` pixels seen
/// with a horizontal field of view of `fov` degrees (4 bytes per pixel,
/// B, G, R, A, follow).
pub fn image_header(out: &mut Vec<u8>, width: u32, height: u32, fov: f32) {
    out.extend_from_slice(&width.to_le_bytes());
    out.extend_from_slice(&height.to_le_bytes());
    out.extend_from_slice(&fov.to_le_bytes());
}

/// A depth in metres as CARLA's depth camera pixel (B, G, R, A): the depth
/// over 1000 m in 24 bits, R the lowest byte, so that
/// `(R + G·256 + B·256²) / (256³ − 1) × 1000` gives it back (to 0.06 mm).
pub fn depth_pixel(metres: f32) -> [u8; 4] {
    let normalized = (metres / DEPTH_FAR_METRES).clamp(0.0, 1.0) as f64;
    let v = (normalized * f64::from(0xFF_FFFFu32)).round() as u32;
    [(v >> 16) as u8, (v >> 8) as u8, v as u8, 255]
}

/// The depth in metres of a CARLA depth pixel (B, G, R, A).
pub fn depth_of_pixel(bgra: [u8; 4]) -> f32 {
    let [b, g, r, _] = bgra.map(u32::from);
    let v = r + g * 256 + b * 65536;
    (f64::from(v) / f64::from(0xFF_FFFFu32) * f64::from(DEPTH_FAR_METRES)) as f32
}

/// Appends a `carla.LidarMeasurement` payload header: the horizontal angle
/// (radians) and the number of points of each channel; the points follow,
/// channel by channel, as x, y, z, intensity (`f32`, the sensor's axes).
pub fn lidar_header(out: &mut Vec<u8>, horizontal_angle: f32, points_per_channel: &[u32]) {
    out.extend_from_slice(&horizontal_angle.to_le_bytes());
    out.extend_from_slice(&(points_per_channel.len() as u32).to_le_bytes());
    for count in points_per_channel {
        out.extend_from_slice(&count.to_le_bytes());
    }
}

/// A vehicle's control as the world state carries it (what
/// `vehicle.get_control()` reads).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CarlaVehicleControl {
    /// 0..=1.
    pub throttle: f32,
    /// -1..=1, positive to the right.
    pub steer: f32,
    /// 0..=1.
    pub brake: f32,
    /// The hand brake.
    pub hand_brake: bool,
    /// Reverse gear.
    pub reverse: bool,
    /// Manual gear shift.
    pub manual_gear_shift: bool,
    /// The gear.
    pub gear: i32,
}

/// One actor of the world state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CarlaActorState {
    /// The actor id.
    pub id: u32,
    /// Where it is.
    pub transform: CarlaTransform,
    /// m/s.
    pub velocity: [f32; 3],
    /// deg/s.
    pub angular_velocity: [f32; 3],
    /// m/s².
    pub acceleration: [f32; 3],
    /// A vehicle's last control.
    pub vehicle: Option<CarlaVehicleControl>,
    /// A vehicle's speed limit and the light it is at.
    pub signals: VehicleSignals,
    /// A traffic light's state.
    pub light: Option<CarlaLight>,
    /// A traffic sign's OpenDRIVE id.
    pub sign: Option<u32>,
    /// Gone with its parent, not yet destroyed by a client: CARLA's
    /// `ActorState::PendingKill` (`is_alive` false, `destroy()` still sent).
    pub dying: bool,
}

/// The speed limit every vehicle reports, km/h: CARLA's default.
pub const SPEED_LIMIT_KMH: f32 = 30.0;

/// What CARLA's `VehicleData` says beyond the control: the speed limit the
/// traffic manager drives to, and the light or stop the vehicle is at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleSignals {
    /// km/h (0 would make the traffic manager's controller divide by zero).
    pub speed_limit: f32,
    /// CARLA's `TrafficLightState`: the light's, red at a stop sign, green
    /// elsewhere (CARLA's state away from a light).
    pub light_state: u8,
    /// At a traffic light (not at a stop sign).
    pub at_light: bool,
    /// That light's actor id (0: none).
    pub light_id: u32,
}

impl Default for VehicleSignals {
    fn default() -> Self {
        Self {
            speed_limit: SPEED_LIMIT_KMH,
            light_state: LightState::Green as u8,
            at_light: false,
            light_id: 0,
        }
    }
}

/// CARLA's `TrafficLightData`: what a light shows and its times.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CarlaLight {
    /// Its OpenDRIVE signal id (`sign_id`, written as decimal text).
    pub sign_id: u32,
    /// Green, yellow and red times, seconds.
    pub times: [f32; 3],
    /// Seconds in its phase (0 while it waits its turn).
    pub elapsed: f32,
    /// Its place in its junction's group.
    pub pole: u32,
    /// Its group's time is frozen.
    pub frozen: bool,
    /// CARLA's `TrafficLightState`.
    pub state: u8,
}

/// A signal id as CARLA's 32-byte, NUL-padded `sign_id`.
fn sign_id(out: &mut Vec<u8>, id: u32) {
    let mut text = [0u8; 32];
    let digits = id.to_string();
    text[..digits.len()].copy_from_slice(digits.as_bytes());
    out.extend_from_slice(&text);
}

/// CARLA's `rpc::ActorState::Active`.
const ACTOR_ACTIVE: u8 = 1;
/// CARLA's `rpc::ActorState::PendingKill`.
const ACTOR_PENDING_KILL: u8 = 3;

/// Appends one actor's 119-byte record (alive or dying; a vehicle's
/// control, speed limit and traffic-light state; a traffic light's state
/// and times; a sign's id).
pub fn actor_state(out: &mut Vec<u8>, actor: &CarlaActorState) {
    let start = out.len();
    out.extend_from_slice(&actor.id.to_le_bytes());
    out.push(if actor.dying {
        ACTOR_PENDING_KILL
    } else {
        ACTOR_ACTIVE
    });
    let t = &actor.transform;
    let floats = t
        .location
        .iter()
        .chain(&t.rotation)
        .chain(&actor.velocity)
        .chain(&actor.angular_velocity)
        .chain(&actor.acceleration);
    for v in floats {
        out.extend_from_slice(&v.to_le_bytes());
    }
    if let Some(c) = actor.vehicle {
        for v in [c.throttle, c.steer, c.brake] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&[
            u8::from(c.hand_brake),
            u8::from(c.reverse),
            u8::from(c.manual_gear_shift),
        ]);
        out.extend_from_slice(&c.gear.to_le_bytes());
        let v = &actor.signals;
        out.extend_from_slice(&v.speed_limit.to_le_bytes());
        out.push(v.light_state);
        out.push(u8::from(v.at_light));
        out.extend_from_slice(&v.light_id.to_le_bytes());
    } else if let Some(light) = &actor.light {
        sign_id(out, light.sign_id);
        for v in light.times.iter().chain([&light.elapsed]) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&light.pole.to_le_bytes());
        out.push(u8::from(light.frozen));
        out.push(light.state);
    } else if let Some(id) = actor.sign {
        sign_id(out, id);
    }
    out.resize(start + ACTOR_STATE_LEN, 0);
}

/// CARLA 0.9.16's `WeatherParameters`, in its msgpack order: cloudiness,
/// precipitation, precipitation_deposits, wind_intensity,
/// sun_azimuth_angle, sun_altitude_angle, fog_density, fog_distance,
/// fog_falloff, wetness, scattering_intensity, mie_scattering_scale,
/// rayleigh_scattering_scale, dust_storm.
pub type Weather = [f32; 14];

/// CARLA's `WeatherParameters.ClearNoon`, what a new world has.
pub const CLEAR_NOON: Weather = [
    5.0, 0.0, 0.0, 10.0, -1.0, 45.0, 2.0, 0.75, 0.1, 0.0, 1.0, 0.03, 0.0331, 0.0,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_ids_map_both_ways_and_stay_apart_from_actors() {
        assert_eq!(carla_id(3), Some(SENSOR_ID_BASE + 3));
        assert_eq!(simbus_id(SENSOR_ID_BASE + 3), Some(3));
        assert_eq!(simbus_id(42), None);
        assert_eq!(simbus_id(SENSOR_ID_BASE), None);
        assert_eq!(carla_id(u64::MAX), None);
        // Client-side sensors are sensors, but no simbus sensor is behind them.
        let lane_invasion = client_side_id(0).unwrap();
        assert!(is_sensor(lane_invasion) && is_sensor(SENSOR_ID_BASE + 3));
        assert!(!is_sensor(42) && !is_sensor(SENSOR_ID_BASE));
        assert_eq!(simbus_id(lane_invasion), None);
        assert_eq!(client_side_id(u32::MAX), None);
    }

    #[test]
    fn a_dying_actor_is_pending_kill_an_alive_one_active() {
        let mut out = Vec::new();
        actor_state(&mut out, &CarlaActorState::default());
        actor_state(
            &mut out,
            &CarlaActorState {
                dying: true,
                ..CarlaActorState::default()
            },
        );
        assert_eq!(out.len(), 2 * ACTOR_STATE_LEN);
        assert_eq!((out[4], out[ACTOR_STATE_LEN + 4]), (1, 3));
    }

    #[test]
    fn world_stream_ids_follow_each_other_below_the_sensors() {
        assert_eq!(world_stream_after(0), 1);
        assert_eq!(world_stream_after(1), 2);
        assert_eq!(world_stream_after(SENSOR_ID_BASE - 1), 1);
        assert!(is_world_stream(1) && is_world_stream(SENSOR_ID_BASE - 1));
        assert!(!is_world_stream(0) && !is_world_stream(SENSOR_ID_BASE + 1));
    }

    #[test]
    fn layouts_have_carla_sizes() {
        let mut out = Vec::new();
        sensor_header(
            &mut out,
            WORLD_STATE_SENSOR_TYPE,
            7,
            0.35,
            CarlaTransform::default(),
        );
        assert_eq!(out.len(), SENSOR_HEADER_LEN);
        episode_header(&mut out, 3, 1.0, 0.05);
        assert_eq!(out.len(), SENSOR_HEADER_LEN + EPISODE_HEADER_LEN);
        actor_state(
            &mut out,
            &CarlaActorState {
                id: 5,
                ..Default::default()
            },
        );
        assert_eq!(
            out.len(),
            SENSOR_HEADER_LEN + EPISODE_HEADER_LEN + ACTOR_STATE_LEN
        );
        assert_eq!(&out[84..88], &5u32.to_le_bytes());
        assert_eq!(out[88], 1);
    }

    #[test]
    fn depth_pixels_round_trip_to_a_sixteenth_of_a_millimetre() {
        for metres in [0.0, 0.001, 1.0, 7.25, 123.456, 999.9, 1000.0] {
            let back = depth_of_pixel(depth_pixel(metres));
            assert!(
                (back - metres).abs() < 1e-4,
                "{metres} m came back as {back}"
            );
        }
        assert_eq!(depth_pixel(5000.0), [255, 255, 255, 255]);
        assert_eq!(depth_pixel(-1.0), [0, 0, 0, 255]);
    }

    #[test]
    fn a_vehicles_control_sits_where_carla_reads_it() {
        let mut out = Vec::new();
        let control = CarlaVehicleControl {
            throttle: 0.5,
            steer: -0.25,
            brake: 0.0,
            hand_brake: true,
            reverse: false,
            manual_gear_shift: false,
            gear: 3,
        };
        actor_state(
            &mut out,
            &CarlaActorState {
                id: 9,
                vehicle: Some(control),
                ..Default::default()
            },
        );
        assert_eq!(out.len(), ACTOR_STATE_LEN);
        assert_eq!(&out[65..69], &0.5f32.to_le_bytes());
        assert_eq!(&out[69..73], &(-0.25f32).to_le_bytes());
        assert_eq!(out[77], 1);
        assert_eq!(&out[80..84], &3i32.to_le_bytes());
        // The speed limit the traffic manager reads, and a green light.
        assert_eq!(&out[84..88], &30f32.to_le_bytes());
        assert_eq!(out[88], 2);
    }

    #[test]
    fn a_lights_data_sits_where_carla_reads_it() {
        let mut out = Vec::new();
        let light = CarlaLight {
            sign_id: 17,
            times: [10.0, 3.0, 2.0],
            elapsed: 1.5,
            pole: 2,
            frozen: true,
            state: LightState::Yellow as u8,
        };
        actor_state(
            &mut out,
            &CarlaActorState {
                id: 9,
                light: Some(light),
                ..Default::default()
            },
        );
        assert_eq!(out.len(), ACTOR_STATE_LEN);
        assert_eq!(&out[65..68], b"17\0");
        assert!(out[67..97].iter().all(|&b| b == 0));
        assert_eq!(&out[97..101], &10f32.to_le_bytes());
        assert_eq!(&out[105..109], &2f32.to_le_bytes());
        assert_eq!(&out[109..113], &1.5f32.to_le_bytes());
        assert_eq!(&out[113..117], &2u32.to_le_bytes());
        assert_eq!((out[117], out[118]), (1, 1));
        // A vehicle at that light.
        let mut out = Vec::new();
        actor_state(
            &mut out,
            &CarlaActorState {
                vehicle: Some(CarlaVehicleControl::default()),
                signals: VehicleSignals {
                    light_state: 0,
                    at_light: true,
                    light_id: 9,
                    ..Default::default()
                },
                ..Default::default()
            },
        );
        assert_eq!((out[88], out[89]), (0, 1));
        assert_eq!(&out[90..94], &9u32.to_le_bytes());
    }

    #[test]
    fn tokens_name_the_stream_and_port() {
        let t = token(1, 2001);
        assert_eq!(&t[..8], &[1, 0, 0, 0, 0xd1, 0x07, 1, 0]);
    }
}
