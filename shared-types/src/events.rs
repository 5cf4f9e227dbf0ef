//! The event sensors: a collision sensor (every contact its parent starts)
//! and an obstacle detector (what lies ahead of its parent). They publish
//! only on frames where something happened; the capture's
//! [`SensorHeader::count`](crate::sensor::SensorHeader::count) says how many events it holds.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

/// The most collision events one capture holds (contacts its parent
/// started in one frame); more are dropped and counted in the log.
pub const MAX_COLLISION_EVENTS: usize = 64;

/// A collision sensor's parameters: it has none (CARLA's
/// `sensor.other.collision` has only `role_name`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Collision;

/// One contact the sensor's parent started, on the frame it started.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::CollisionEvent/1")]
pub struct CollisionEvent {
    /// The actor the parent ran into.
    pub other_actor: u64,
    /// The impulse the contact gave the parent over the step it started,
    /// N·s, world frame (X forward, Y up, Z right).
    pub normal_impulse: [f32; 3],
    /// Zero.
    pub reserved: u32,
}

/// An obstacle detector's parameters (CARLA's `sensor.other.obstacle`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// How far ahead it looks, metres.
    pub distance: f32,
    /// The radius of the sphere swept ahead, metres.
    pub hit_radius: f32,
    /// Whether only dynamic actors count (not the ground, ramps, buildings).
    pub only_dynamics: bool,
}

impl Default for Obstacle {
    /// CARLA's defaults: 5 m, radius 0.5 m, every actor.
    fn default() -> Self {
        Self {
            distance: 5.0,
            hit_radius: 0.5,
            only_dynamics: false,
        }
    }
}

impl Obstacle {
    /// Whether the parameters can build a detector: a distance in
    /// (0, 1000] m and a radius in (0, 100] m.
    pub fn valid(&self) -> bool {
        (self.distance > 0.0 && self.distance <= 1000.0)
            && (self.hit_radius > 0.0 && self.hit_radius <= 100.0)
    }
}

/// What an obstacle detector saw ahead this frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ObstacleDetection/1")]
pub struct ObstacleDetection {
    /// The nearest actor ahead.
    pub other_actor: u64,
    /// How far ahead it is (the swept sphere's travel), metres.
    pub distance: f32,
    /// Zero.
    pub reserved: u32,
}
