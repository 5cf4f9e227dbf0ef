//! CARLA 0.9.16's binary stream layouts, as its client library reads them:
//! the stream token, the 48-byte sensor header every stream message starts
//! with, and the world state (episode header and one 119-byte record per
//! actor). All little-endian and packed. The RPC side is msgpack (built in
//! the gateway with `rmpv`).
//!
//! Sources: CARLA's `LibCarla/source/carla/streaming/detail/Token.h`,
//! `sensor/s11n/SensorHeaderSerializer.h`, `sensor/s11n/EpisodeStateSerializer.h`,
//! `sensor/data/ActorDynamicState.h`, checked against the 0.9.16 wheel.

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
/// The stream id of the world state.
pub const WORLD_STREAM_ID: u32 = 1;
/// The version the gateway reports (`client.get_server_version()`).
pub const CARLA_VERSION: &str = "0.9.16";

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
}

/// Appends one actor's 119-byte record (alive; no vehicle, walker or
/// traffic state).
pub fn actor_state(out: &mut Vec<u8>, actor: &CarlaActorState) {
    let start = out.len();
    out.extend_from_slice(&actor.id.to_le_bytes());
    out.push(1); // ActorState::Active
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
    out.resize(start + ACTOR_STATE_LEN, 0);
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn tokens_name_the_stream_and_port() {
        let t = token(1, 2001);
        assert_eq!(&t[..8], &[1, 0, 0, 0, 0xd1, 0x07, 1, 0]);
    }
}
