//! CARLA's calls for its native ROS 2 (`sensor.enable_for_ros()`,
//! `disable_for_ros()`, `is_enabled_for_ros()`): each names the sensor by
//! its stream id (CARLA's sensor token's first four bytes: the sensor's
//! actor id here).

use rmpv::Value;

use super::Session;
use crate::commands;
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;

impl Session {
    /// The simbus sensor behind the stream id in `args` (`None` for a
    /// sensor CARLA's client computes itself: CARLA publishes nothing for
    /// those either), or the call's error for a stream no sensor has.
    fn ros_sensor(&self, method: &'static str, args: &[Value]) -> Result<Option<u64>, CallError> {
        let stream = args
            .first()
            .and_then(commands::actor_id)
            .ok_or(CallError::Shape {
                method,
                what: "no sensor stream id",
            })?;
        if !lock(&self.hub.registry).sensors.contains_key(&stream) {
            return Err(CallError::UnknownActor(stream));
        }
        Ok(crate::wire::simbus_id(stream))
    }

    pub(super) fn on_enable_sensor_for_ros(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        self.set_sensor_for_ros("enable_sensor_for_ros", args, true)
    }

    pub(super) fn on_disable_sensor_for_ros(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        self.set_sensor_for_ros("disable_sensor_for_ros", args, false)
    }

    /// `method` (enable or disable): the sensor in `args` published (`on`)
    /// or not.
    fn set_sensor_for_ros(
        &mut self,
        method: &'static str,
        args: &[Value],
        on: bool,
    ) -> Result<Answer, CallError> {
        if let Some(sensor) = self.ros_sensor(method, args)? {
            self.hub.ros2.enable(sensor, on);
        }
        Ok(Answer::Done)
    }

    pub(super) fn on_is_sensor_enabled_for_ros(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let enabled = self
            .ros_sensor("is_sensor_enabled_for_ros", args)?
            .is_some_and(|sensor| self.hub.ros2.is_enabled(sensor));
        Ok(Answer::Value(Value::Boolean(enabled)))
    }
}
