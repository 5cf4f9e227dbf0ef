//! Four-wheeled ray-cast vehicles (rapier's `DynamicRayCastVehicleController`):
//! the control each holds until told otherwise (throttle, steer, brake,
//! hand brake) and how it turns into wheel forces every physics step.

use rapier3d::control::{DynamicRayCastVehicleController, WheelTuning};
use rapier3d::prelude::*;

/// A vehicle's controller and the control it holds until told otherwise.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub(crate) struct Vehicle {
    actor: u64,
    controller: DynamicRayCastVehicleController,
    throttle: f32,
    steer: f32,
    brake: f32,
    hand_brake: bool,
}

/// Chassis half extents of a spawned vehicle: 2 m long (X), 0.5 m high, 1 m wide.
pub(crate) const VEHICLE_HALF_EXTENTS: [f32; 3] = [1.0, 0.25, 0.5];
/// Engine force per driven (rear) wheel at full throttle, newtons.
const MAX_ENGINE_FORCE: f32 = 300.0;
/// Brake force per wheel at full brake.
const MAX_BRAKE: f32 = 40.0;
/// Front-wheel angle at full steer, radians.
const MAX_STEER: f32 = 0.5;

impl Vehicle {
    /// Holds this control until the next one.
    pub(crate) fn set_control(&mut self, throttle: f32, steer: f32, brake: f32, hand_brake: bool) {
        self.throttle = throttle;
        self.steer = steer;
        self.brake = brake;
        self.hand_brake = hand_brake;
    }
}

/// Every vehicle of a world.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct Vehicles {
    list: Vec<Vehicle>,
}

impl Vehicles {
    /// Adds a vehicle for actor `actor` whose chassis is `body`, with half
    /// extents `half`, standing still.
    pub(crate) fn add(&mut self, actor: u64, body: RigidBodyHandle, half: Vector) {
        self.list.push(Vehicle {
            actor,
            controller: vehicle_controller(body, half),
            throttle: 0.0,
            steer: 0.0,
            brake: 0.0,
            hand_brake: false,
        });
    }

    /// Removes the vehicle of actor `actor`, if it is one.
    pub(crate) fn remove(&mut self, actor: u64) {
        self.list.retain(|vehicle| vehicle.actor != actor);
    }

    /// Every vehicle's chassis body.
    pub(crate) fn chassis(&self) -> impl Iterator<Item = RigidBodyHandle> + '_ {
        self.list.iter().map(|v| v.controller.chassis)
    }

    /// The vehicle of actor `actor`, if it is one.
    pub(crate) fn get_mut(&mut self, actor: u64) -> Option<&mut Vehicle> {
        self.list.iter_mut().find(|v| v.actor == actor)
    }

    /// Applies each vehicle's control to its wheels and lets its controller
    /// push the chassis, for a physics step of `dt` seconds.
    pub(crate) fn update(&mut self, physics: &mut PhysicsWorld, dt: f32) {
        for vehicle in &mut self.list {
            let chassis = vehicle.controller.chassis;
            for (i, wheel) in vehicle.controller.wheels_mut().iter_mut().enumerate() {
                let front = i < 2;
                wheel.steering = if front {
                    vehicle.steer * MAX_STEER
                } else {
                    0.0
                };
                wheel.engine_force = if front {
                    0.0
                } else {
                    vehicle.throttle * MAX_ENGINE_FORCE
                };
                wheel.brake = if vehicle.hand_brake && !front {
                    MAX_BRAKE * 4.0
                } else {
                    vehicle.brake * MAX_BRAKE
                };
            }
            let queries = physics.broad_phase.as_query_pipeline_mut(
                physics.narrow_phase.query_dispatcher(),
                &mut physics.bodies,
                &mut physics.colliders,
                QueryFilter::exclude_dynamic().exclude_rigid_body(chassis),
            );
            vehicle.controller.update_vehicle(dt, queries);
        }
    }
}

/// A four-wheeled controller for the chassis `body` with half extents `half`.
fn vehicle_controller(body: RigidBodyHandle, half: Vector) -> DynamicRayCastVehicleController {
    let mut controller = DynamicRayCastVehicleController::new(body);
    let tuning = WheelTuning {
        suspension_stiffness: 40.0,
        suspension_damping: 4.0,
        friction_slip: 1.5,
        ..WheelTuning::default()
    };
    let (x, y, z) = (half.x * 0.7, -half.y, half.z);
    // Front wheels first (steered), then the driven rear wheels.
    for position in [
        Vector::new(x, y, z),
        Vector::new(x, y, -z),
        Vector::new(-x, y, z),
        Vector::new(-x, y, -z),
    ] {
        controller.add_wheel(position, -Vector::Y, Vector::Z, 0.3, 0.3, &tuning);
    }
    controller
}
