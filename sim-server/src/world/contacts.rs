//! Contacts that start during a step, as collisions between actors: what
//! the recorder records and what collision sensors report.
//!
//! rapier starts a contact when two shapes come within its prediction
//! distance, before they touch: a pair that starts without an impulse
//! (a car bouncing back from a wall and coming close again) is held as
//! pending and reported on the first step its contact pushes, or never if
//! it stops first. So a contact starts once per touch, with the impulse
//! of its first push.

use std::sync::Mutex;

use rapier3d::prelude::*;
use shared_types::ActorKind;
use simbus_recording::RecordedCollision;

use super::World;

/// One contact that started during a frame, between two actors (the
/// lower id first).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ContactStart {
    pub(crate) a: (u64, ActorKind),
    pub(crate) b: (u64, ActorKind),
    /// The solver's total normal impulse at the end of the step, N·s.
    pub(crate) impulse: f32,
    /// The impulse the contact gave `a` over that step, N·s, world frame
    /// (`b` got its opposite).
    pub(crate) impulse_on_a: Vector,
}

impl ContactStart {
    /// `actor`'s side of it: the other actor and the impulse `actor` got.
    pub(crate) fn seen_by(&self, actor: u64) -> Option<(u64, Vector)> {
        if self.a.0 == actor {
            Some((self.b.0, self.impulse_on_a))
        } else if self.b.0 == actor {
            Some((self.a.0, -self.impulse_on_a))
        } else {
            None
        }
    }

    /// As the recorder records it (frame and time left 0 for the caller).
    pub(crate) fn recorded(&self) -> RecordedCollision {
        RecordedCollision {
            frame: 0,
            elapsed_ns: 0,
            actor_a: self.a.0,
            actor_b: self.b.0,
            impulse: self.impulse,
            kind_a: self.a.1 as u32,
            kind_b: self.b.1 as u32,
            reserved: 0,
        }
    }
}

/// Whether `pair` is `(a, b)` in either order.
fn same_pair(
    pair: (ColliderHandle, ColliderHandle),
    (a, b): (ColliderHandle, ColliderHandle),
) -> bool {
    pair == (a, b) || pair == (b, a)
}

impl World {
    /// Adds the contacts between actors that pushed for the first time in
    /// the last physics step to `out`, with the impulses the solver
    /// applied; those that started without pushing wait in `pending`.
    pub(super) fn collect_contacts(
        &self,
        started: &ContactStarts,
        pending: &mut Vec<(ColliderHandle, ColliderHandle)>,
        out: &mut Vec<ContactStart>,
    ) {
        let stopped =
            std::mem::take(&mut *started.stopped.lock().unwrap_or_else(|e| e.into_inner()));
        pending.retain(|&p| !stopped.iter().any(|&s| same_pair(p, s)));
        let mut pairs = std::mem::take(pending);
        pairs.append(&mut started.pairs.lock().unwrap_or_else(|e| e.into_inner()));
        for (c1, c2) in pairs {
            let actor = |c: ColliderHandle| {
                let body = self.physics.colliders.get(c)?.parent()?;
                let id = self.physics.bodies.get(body)?.user_data as u64;
                let kind = self.actors.get(self.index_of(id)?)?.kind;
                Some((id, kind, c))
            };
            let (Some(a), Some(b)) = (actor(c1), actor(c2)) else {
                continue;
            };
            let (a, b) = if a.0 <= b.0 { (a, b) } else { (b, a) };
            let Some(pair) = self.physics.contact_pair(c1, c2) else {
                continue;
            };
            let impulse = pair.total_impulse_magnitude();
            if impulse <= 0.0 {
                pending.push((c1, c2));
                continue;
            }
            // The pair's normal points from its first collider to its
            // second: the impulse pushes the second along it.
            let impulse_on_a = if pair.collider1 == a.2 {
                -pair.total_impulse()
            } else {
                pair.total_impulse()
            };
            out.push(ContactStart {
                a: (a.0, a.1),
                b: (b.0, b.1),
                impulse,
                impulse_on_a,
            });
        }
    }
}

/// Collects the collider pairs whose contact started, or stopped, during
/// a step.
#[derive(Default)]
pub(super) struct ContactStarts {
    pairs: Mutex<Vec<(ColliderHandle, ColliderHandle)>>,
    stopped: Mutex<Vec<(ColliderHandle, ColliderHandle)>>,
}

impl EventHandler for ContactStarts {
    fn handle_collision_event(
        &self,
        _bodies: &RigidBodySet,
        _colliders: &ColliderSet,
        event: CollisionEvent,
        _contact_pair: Option<&ContactPair>,
    ) {
        let list = match event {
            CollisionEvent::Started(..) => &self.pairs,
            CollisionEvent::Stopped(..) => &self.stopped,
        };
        list.lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((event.collider1(), event.collider2()));
    }

    fn handle_contact_force_event(
        &self,
        _dt: Real,
        _bodies: &RigidBodySet,
        _colliders: &ColliderSet,
        _contact_pair: &ContactPair,
        _total_force_magnitude: Real,
    ) {
    }

    fn handle_soft_body_tear_event(&self, _soft_bodies: &SoftBodySet, _event: &SoftBodyTearEvent) {}
}
