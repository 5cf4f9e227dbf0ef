//! Four-wheeled ray-cast vehicles (rapier's `DynamicRayCastVehicleController`):
//! the control each holds until told otherwise (throttle, steer, brake,
//! hand brake) and how it turns into wheel forces every physics step.

use rapier3d::control::{DynamicRayCastVehicleController, WheelTuning};
use rapier3d::prelude::*;
use shared_types::{VehicleSpec, FRICTION_SLIP, SUSPENSION_DAMPING, SUSPENSION_STIFFNESS};

mod ackermann;
pub(crate) use ackermann::Ackermann;

/// A vehicle's controller and the control it holds until told otherwise.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Vehicle {
    actor: u64,
    controller: DynamicRayCastVehicleController,
    /// The throttle, negative in the reverse gear.
    throttle: f32,
    steer: f32,
    brake: f32,
    hand_brake: bool,
    /// Engine force per driven (rear) wheel at full throttle, newtons
    /// (absent from keyframes of before sized vehicles: the original's).
    #[serde(default = "original_engine_force")]
    max_engine_force: f32,
    /// Braking force per wheel at full brake, newtons.
    #[serde(default = "original_brake")]
    max_brake: f32,
    /// Front-wheel angle at full steer, radians.
    #[serde(default = "original_steer")]
    max_steer: f32,
}

fn original_engine_force() -> f32 {
    VehicleSpec::default().engine_force
}

fn original_brake() -> f32 {
    VehicleSpec::default().brake
}

fn original_steer() -> f32 {
    VehicleSpec::default().max_steer
}

impl Vehicle {
    /// Holds this control until the next one (`reverse`: the throttle
    /// drives the vehicle backwards).
    pub(crate) fn set_control(
        &mut self,
        throttle: f32,
        steer: f32,
        brake: f32,
        hand_brake: bool,
        reverse: bool,
    ) {
        self.throttle = if reverse { -throttle } else { throttle };
        self.steer = steer;
        self.brake = brake;
        self.hand_brake = hand_brake;
    }
}

/// Every vehicle of a world.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct Vehicles {
    list: Vec<Vehicle>,
}

impl Vehicles {
    /// Adds a vehicle for actor `actor` whose chassis is `body`, built as
    /// `spec` says, standing still.
    pub(crate) fn add(&mut self, actor: u64, body: RigidBodyHandle, spec: &VehicleSpec) {
        self.list.push(Vehicle {
            actor,
            controller: vehicle_controller(body, spec),
            throttle: 0.0,
            steer: 0.0,
            brake: 0.0,
            hand_brake: false,
            max_engine_force: spec.engine_force,
            max_brake: spec.brake,
            max_steer: spec.max_steer,
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

    /// The steering angle vehicle `actor`'s control holds, radians.
    pub(crate) fn steering(&self, actor: u64) -> f32 {
        self.list
            .iter()
            .find(|v| v.actor == actor)
            .map_or(0.0, |v| v.steer * v.max_steer)
    }

    /// Applies each vehicle's control to its wheels — the one its
    /// Ackermann target in `ackermann` gives it this step, if it has one —
    /// and lets its controller push the chassis, for a physics step of
    /// `dt` seconds.
    pub(crate) fn update(
        &mut self,
        physics: &mut PhysicsWorld,
        dt: f32,
        ackermann: &mut [Ackermann],
    ) {
        for vehicle in &mut self.list {
            let chassis = vehicle.controller.chassis;
            if let (Some(target), Some(body)) = (
                ackermann.iter_mut().find(|a| a.actor == vehicle.actor),
                physics.bodies.get(chassis),
            ) {
                let forward = body.rotation() * Vector::X;
                let mass = body.mass().max(1e-3);
                let drive = target.drive(
                    body.linvel().dot(forward),
                    vehicle.max_steer,
                    2.0 * vehicle.max_engine_force / mass,
                    4.0 * vehicle.max_brake / mass,
                    dt,
                );
                vehicle.set_control(
                    drive.throttle,
                    drive.steer,
                    drive.brake,
                    false,
                    drive.reverse,
                );
                if let Some(body) = physics.bodies.get_mut(chassis) {
                    body.wake_up(true);
                }
            }
            // A chassis asleep is at rest: its suspension's impulses would
            // change its velocity without moving it (a parked car read
            // +0.59 m/s upwards for ever). A new control wakes it.
            if physics.bodies.get(chassis).is_none_or(|b| b.is_sleeping()) {
                continue;
            }
            for (i, wheel) in vehicle.controller.wheels_mut().iter_mut().enumerate() {
                let front = i < 2;
                wheel.steering = if front {
                    vehicle.steer * vehicle.max_steer
                } else {
                    0.0
                };
                wheel.engine_force = if front {
                    0.0
                } else {
                    vehicle.throttle * vehicle.max_engine_force
                };
                // Rapier's brake is the impulse one step may take off a
                // wheel: the force times the step.
                let force = if vehicle.hand_brake && !front {
                    // The rear wheels locked: as hard as the tyres hold.
                    vehicle.max_brake * 4.0
                } else {
                    vehicle.brake * vehicle.max_brake
                };
                wheel.brake = force * dt;
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

/// A four-wheeled controller for the chassis `body`, built as `spec` says.
fn vehicle_controller(
    body: RigidBodyHandle,
    spec: &VehicleSpec,
) -> DynamicRayCastVehicleController {
    let mut controller = DynamicRayCastVehicleController::new(body);
    let tuning = WheelTuning {
        suspension_stiffness: SUSPENSION_STIFFNESS,
        suspension_damping: SUSPENSION_DAMPING,
        friction_slip: FRICTION_SLIP,
        max_suspension_force: spec.max_suspension_force,
        ..WheelTuning::default()
    };
    // Front wheels first (steered), then the driven rear wheels.
    for position in spec.wheels {
        controller.add_wheel(
            Vector::from_array(position),
            -Vector::Y,
            Vector::Z,
            spec.suspension_rest_length,
            spec.wheel_radius,
            &tuning,
        );
    }
    controller
}
