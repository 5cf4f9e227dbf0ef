//! Checking a world read from a file before rapier is given it.

use super::World;

impl World {
    /// Checks a world read from a file (a keyframe) before it is used.
    ///
    /// Every actor's body and every collider's parent exist, ids ascend below
    /// `next_id`, every vehicle's chassis is an actor's body, and every body is
    /// finite. Rapier trusts its own sets; a damaged keyframe must not reach
    /// it.
    ///
    /// # Errors
    ///
    /// Returns the first [`Inconsistency`] found:
    /// [`Inconsistency::IdsOutOfOrder`] if actor ids do not ascend within the
    /// world's id range, [`Inconsistency::NoBody`] if an actor has no body,
    /// [`Inconsistency::NotFinite`] if a pose or velocity is not finite,
    /// [`Inconsistency::ColliderWithoutBody`] if a collider's parent body is
    /// missing, [`Inconsistency::ChassisNotActor`] if a vehicle's chassis is no
    /// actor's body, and [`Inconsistency::BodiesAndActorsDiffer`] if there are
    /// bodies that are no actor's.
    pub fn check(&self) -> Result<(), Inconsistency> {
        let mut previous = None;
        for actor in &self.actors {
            if previous.is_some_and(|p| p >= actor.id)
                || actor.id >= self.next_id
                || actor.id < self.first_id
            {
                return Err(Inconsistency::IdsOutOfOrder(actor.id));
            }
            previous = Some(actor.id);
            let Some(body) = self.physics.bodies.get(actor.body) else {
                return Err(Inconsistency::NoBody(actor.id));
            };
            let p = body.position();
            let finite = p.translation.is_finite()
                && p.rotation.is_finite()
                && body.linvel().is_finite()
                && body.angvel().is_finite();
            if !finite {
                return Err(Inconsistency::NotFinite(actor.id));
            }
        }
        for (_, collider) in self.physics.colliders.iter() {
            if collider
                .parent()
                .is_some_and(|b| self.physics.bodies.get(b).is_none())
            {
                return Err(Inconsistency::ColliderWithoutBody);
            }
        }
        if !self
            .vehicles
            .chassis()
            .all(|body| self.actors.iter().any(|a| a.body == body))
        {
            return Err(Inconsistency::ChassisNotActor);
        }
        if self.physics.bodies.len() != self.actors.len() {
            return Err(Inconsistency::BodiesAndActorsDiffer);
        }
        Ok(())
    }
}

/// What makes a world read from a file unusable (see [`World::check`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Inconsistency {
    /// Actor ids do not ascend within the world's id range, at this id.
    #[error("actor ids out of order at {0}")]
    IdsOutOfOrder(u64),
    /// The actor has no rigid body.
    #[error("actor {0} has no body")]
    NoBody(u64),
    /// The actor's pose or velocity is not finite.
    #[error("actor {0} is not finite")]
    NotFinite(u64),
    /// A collider's parent body does not exist.
    #[error("a collider's body is missing")]
    ColliderWithoutBody,
    /// A vehicle's chassis is not the body of an actor.
    #[error("a vehicle's chassis is not an actor")]
    ChassisNotActor,
    /// There are bodies that are no actor's (or the other way round).
    #[error("bodies and actors differ")]
    BodiesAndActorsDiffer,
}
