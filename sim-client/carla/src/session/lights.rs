//! CARLA's calls on the traffic lights as a whole: freezing and resetting
//! them all, a light's group, the boxes of its head. (The calls on one
//! light — its state, times, freezing and resetting its group — are
//! commands on the actor, `commands::rpc_op`.)

use rmpv::Value;
use shared_types::ActorKind;

use super::Session;
use crate::commands::{BatchCommand, Op};
use crate::convert;
use crate::error::CallError;
use crate::locks::lock;
use crate::records::located_box;
use crate::rpc::Answer;

impl Session {
    /// CARLA's `world.freeze_all_traffic_lights(frozen)` (and what its
    /// `TrafficLight.freeze` sends): every group holds where it is, or
    /// goes on.
    pub(super) fn on_freeze_all_traffic_lights(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let frozen = args
            .first()
            .and_then(Value::as_bool)
            .ok_or(CallError::Shape {
                method: "freeze_all_traffic_lights",
                what: "no bool",
            })?;
        self.on_all_lights(Op::FreezeLights(frozen))
    }

    /// CARLA's `world.reset_all_traffic_lights()` (what the traffic
    /// manager's `set_random_device_seed` sends): every group's cycle
    /// starts again.
    pub(super) fn on_reset_all_traffic_lights(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        self.on_all_lights(Op::ResetLights)
    }

    /// `op` on every light (actor 0).
    fn on_all_lights(&mut self, op: Op) -> Result<Answer, CallError> {
        let results = self.run_batch(vec![Ok(BatchCommand::Actor(0, op))]);
        results.into_iter().next().unwrap_or(Ok(0))?;
        Ok(Answer::Done)
    }

    /// The id of the traffic light argument `method` names.
    fn light_arg(&self, args: &[Value], method: &'static str) -> Result<u32, CallError> {
        self.actor_of_kind(
            args,
            method,
            ActorKind::TrafficLight,
            CallError::NotATrafficLight,
        )
    }

    /// CARLA's `TrafficLight.get_group_traffic_lights()`: the lights of
    /// its junction, itself included, in pole order.
    pub(super) fn on_get_group_traffic_lights(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let id = self.light_arg(args, "get_group_traffic_lights")?;
        let group = lock(&self.hub.signals)
            .group(id)
            .unwrap_or_else(|| vec![id]);
        Ok(Answer::Value(Value::Array(
            group.into_iter().map(Value::from).collect(),
        )))
    }

    /// CARLA's `TrafficLight.get_light_boxes()`: its head's box, in the
    /// world (simbus's light is one head).
    pub(super) fn on_get_light_boxes(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let id = self.light_arg(args, "get_light_boxes")?;
        let Some(light) = lock(&self.hub.actors).get(&id).copied() else {
            return Err(CallError::UnknownActor(id));
        };
        let t = convert::transform(light.position, light.rotation);
        Ok(Answer::Value(Value::Array(vec![located_box(
            id,
            t.location,
            light.extent,
            t.rotation,
        )])))
    }
}
