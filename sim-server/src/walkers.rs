//! Walkers (pedestrians): kinematic capsules that stand on the ground,
//! step up kerbs, slide along walls and stop at other bodies, walkers
//! excepted (rapier's `KinematicCharacterController` across, rays to the
//! ground); what each holds is its `WalkerControl` (direction, speed, a
//! jump). Gravity pulls a walker that is off the ground; a body that is
//! disabled does not walk.

use rapier3d::control::{CharacterLength, KinematicCharacterController};
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
    ///
    /// Across, rapier's character controller moves its capsule raised by
    /// [`STEP`] (so kerbs and the ground never catch it, and walls and
    /// bodies stop it or it slides along them); up and down, rays from
    /// that height find the ground under it, which it stands on, steps up
    /// or down to, or falls to. Rays meet a large flat ground exactly,
    /// where a capsule's casts touching it do not.
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
            let pull = gravity * body.gravity_scale();
            let queries = physics.query_pipeline_with_filter(
                // Walkers pass through each other, as CARLA's AI walkers
                // do (their collisions off; the crowd keeps them apart).
                QueryFilter::exclude_kinematic().exclude_sensors(),
            );
            let raised = Pose::from_parts(pose.translation + Vector::Y * STEP, pose.rotation);
            let across = walker.direction * (walker.speed * dt);
            let moved = if across == Vector::ZERO {
                Vector::ZERO
            } else {
                let shape = walker.shape();
                let m = controller.move_shape(dt, &queries, &shape, &raised, across, |_| {});
                Vector::new(m.translation.x, 0.0, m.translation.z)
            };
            let mut at = pose.translation + moved;
            let feet = at.y - walker.half_height;
            if walker.jump && walker.grounded {
                walker.vertical_speed = JUMP_SPEED;
                walker.grounded = false;
                walker.jump = false;
            }
            let airborne = !walker.grounded || walker.vertical_speed > 0.0;
            if airborne {
                walker.vertical_speed += pull * dt;
            }
            let drop = if airborne {
                (-walker.vertical_speed * dt).max(0.0)
            } else {
                SNAP
            };
            let ground = ground_under(&queries, at, feet, walker.radius, drop);
            match ground {
                // Rising: a jump.
                _ if walker.vertical_speed > 0.0 => {
                    at.y += walker.vertical_speed * dt;
                }
                // (A tenth of a millimetre's slack: standing is not
                // taken for falling by a float's rounding.)
                Some(ground)
                    if feet + walker.vertical_speed.min(0.0) * dt <= ground + GAP + 1e-4 =>
                {
                    at.y = ground + walker.half_height + GAP;
                    walker.vertical_speed = 0.0;
                    walker.grounded = true;
                }
                // No ground within this step's fall: falling.
                _ => {
                    if !airborne {
                        // Walked off an edge: it falls from here on.
                        walker.vertical_speed = pull * dt;
                    }
                    at.y += walker.vertical_speed * dt;
                    walker.grounded = false;
                }
            }
            let rotation = if walker.direction == Vector::ZERO || walker.speed == 0.0 {
                pose.rotation
            } else {
                // Facing where it walks: +X turned about Y.
                Rotation::from_rotation_y((-walker.direction.z).atan2(walker.direction.x))
            };
            if let Some(body) = physics.bodies.get_mut(walker.body) {
                body.set_next_kinematic_position(Pose::from_parts(at, rotation));
            }
        }
    }
}

/// How high a walker steps up (a kerb) without stopping, metres.
const STEP: f32 = 0.3;
/// How far below its feet a walker on the ground keeps to it (a kerb down,
/// a slope), metres.
const SNAP: f32 = 0.3;
/// A walker's feet stand this far above the ground, metres.
const GAP: f32 = 0.01;

/// The height of the highest surface under a walker of `radius` at `at`
/// (its axis and four points around it), from [`STEP`] above its `feet`
/// down to `drop` below them; `None` when there is none.
fn ground_under(
    queries: &QueryPipeline,
    at: Vector,
    feet: f32,
    radius: f32,
    drop: f32,
) -> Option<f32> {
    let top = feet + STEP;
    let reach = STEP + drop + GAP;
    let r = radius * 0.7;
    [(0.0, 0.0), (r, 0.0), (-r, 0.0), (0.0, r), (0.0, -r)]
        .into_iter()
        .filter_map(|(dx, dz)| {
            let ray = Ray::new(Vector::new(at.x + dx, top, at.z + dz), -Vector::Y);
            queries
                .cast_ray(&ray, reach, true)
                .map(|(_, toi)| top - toi)
        })
        .reduce(f32::max)
}

/// How every walker moves across: slides along what it meets, climbs
/// slopes to 45°, keeps a 1 cm gap.
fn character_controller() -> KinematicCharacterController {
    KinematicCharacterController {
        autostep: None,
        snap_to_ground: None,
        offset: CharacterLength::Absolute(0.01),
        ..KinematicCharacterController::default()
    }
}

#[cfg(test)]
mod tests;
