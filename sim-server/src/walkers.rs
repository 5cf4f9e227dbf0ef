//! Walkers (pedestrians): kinematic capsules moved by rapier's
//! `KinematicCharacterController`, so they stand on the ground, climb
//! kerbs, slide along walls and stop at other bodies; what each holds is
//! its `WalkerControl` (direction, speed, a jump). Gravity pulls a walker
//! that is off the ground; a body that is disabled does not walk.

use rapier3d::control::{CharacterAutostep, CharacterLength, KinematicCharacterController};
use rapier3d::prelude::*;

/// Upward speed of a jump, m/s (about 0.45 m high).
const JUMP_SPEED: f32 = 3.0;

/// A walker's size and the control it holds until told otherwise.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Walker {
    actor: u64,
    body: RigidBodyHandle,
    radius: f32,
    /// Half height, round ends included.
    half_height: f32,
    /// Unit horizontal direction, or zero to stand.
    direction: Vector,
    speed: f32,
    /// A jump asked for and not yet begun (it begins on the ground).
    jump: bool,
    /// Vertical speed while off the ground, m/s.
    vertical_speed: f32,
    grounded: bool,
}

impl Walker {
    /// Holds this control until the next one: `direction` in world axes
    /// (only its horizontal part counts), `speed` m/s.
    pub(crate) fn set_control(&mut self, direction: Vector, speed: f32, jump: bool) {
        let flat = Vector::new(direction.x, 0.0, direction.z);
        let length = flat.length();
        self.direction = if length > 1e-6 {
            flat / length
        } else {
            Vector::ZERO
        };
        self.speed = speed;
        self.jump |= jump;
    }

    /// The walker's capsule.
    pub(crate) fn shape(&self) -> Capsule {
        walker_shape(self.radius, self.half_height)
    }
}

/// The capsule of a walker of `radius` and `half_height` (ends included).
pub(crate) fn walker_shape(radius: f32, half_height: f32) -> Capsule {
    Capsule::new_y((half_height - radius).max(0.0), radius)
}

/// Every walker of a world.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct Walkers {
    list: Vec<Walker>,
}

impl Walkers {
    /// Adds a standing walker for actor `actor` whose capsule is `body`.
    pub(crate) fn add(&mut self, actor: u64, body: RigidBodyHandle, radius: f32, half_height: f32) {
        self.list.push(Walker {
            actor,
            body,
            radius,
            half_height,
            direction: Vector::ZERO,
            speed: 0.0,
            jump: false,
            vertical_speed: 0.0,
            grounded: false,
        });
    }

    /// Removes the walker of actor `actor`, if it is one.
    pub(crate) fn remove(&mut self, actor: u64) {
        self.list.retain(|walker| walker.actor != actor);
    }

    /// The walker of actor `actor`, if it is one.
    pub(crate) fn get_mut(&mut self, actor: u64) -> Option<&mut Walker> {
        self.list.iter_mut().find(|w| w.actor == actor)
    }

    /// Whether actor `actor` is a walker.
    #[cfg(test)]
    pub(crate) fn contains(&self, actor: u64) -> bool {
        self.list.iter().any(|w| w.actor == actor)
    }

    /// Moves every walker as its control says, for a physics step of `dt`
    /// seconds: where it may go is decided against the bodies as they are
    /// before the step, and the step carries it there.
    pub(crate) fn update(&mut self, physics: &mut PhysicsWorld, dt: f32) {
        let controller = character_controller();
        let gravity = physics.gravity.y;
        for walker in &mut self.list {
            let Some(body) = physics.bodies.get(walker.body) else {
                continue;
            };
            if !body.is_enabled() {
                continue;
            }
            let pose = *body.position();
            if walker.jump && walker.grounded {
                walker.vertical_speed = JUMP_SPEED;
                walker.grounded = false;
                walker.jump = false;
            }
            if !walker.grounded || walker.vertical_speed > 0.0 {
                walker.vertical_speed += gravity * body.gravity_scale() * dt;
            }
            // Pressed to the ground while on it, so the controller keeps it
            // there on a slope down.
            let fall = if walker.grounded && walker.vertical_speed <= 0.0 {
                gravity * body.gravity_scale() * dt * dt
            } else {
                walker.vertical_speed * dt
            };
            let desired = walker.direction * (walker.speed * dt) + Vector::Y * fall;
            let shape = walker.shape();
            let queries = physics.query_pipeline_with_filter(
                QueryFilter::default()
                    .exclude_rigid_body(walker.body)
                    .exclude_sensors(),
            );
            let movement = controller.move_shape(dt, &queries, &shape, &pose, desired, |_| {});
            walker.grounded = movement.grounded;
            if walker.grounded && walker.vertical_speed < 0.0 {
                walker.vertical_speed = 0.0;
            }
            let rotation = if walker.direction == Vector::ZERO || walker.speed == 0.0 {
                pose.rotation
            } else {
                // Facing where it walks: +X turned about Y.
                Rotation::from_rotation_y((-walker.direction.z).atan2(walker.direction.x))
            };
            let target = Pose::from_parts(pose.translation + movement.translation, rotation);
            if let Some(body) = physics.bodies.get_mut(walker.body) {
                body.set_next_kinematic_position(target);
            }
        }
    }
}

/// How every walker moves: steps up kerbs to 0.3 m, climbs slopes to 45°,
/// keeps to the ground within 0.2 m.
fn character_controller() -> KinematicCharacterController {
    KinematicCharacterController {
        autostep: Some(CharacterAutostep {
            max_height: CharacterLength::Absolute(0.3),
            min_width: CharacterLength::Absolute(0.1),
            include_dynamic_bodies: false,
        }),
        snap_to_ground: Some(CharacterLength::Absolute(0.2)),
        offset: CharacterLength::Absolute(0.01),
        ..KinematicCharacterController::default()
    }
}

#[cfg(test)]
mod tests;
