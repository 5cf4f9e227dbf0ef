//! The native traffic manager's driving, one step at a time on the town:
//! it follows its lane, stops for a red light (or runs it when told to),
//! brakes for a walker on its way and keeps to its speed.

use std::collections::HashMap;

use shared_types::roads::{self, SignalKind};
use shared_types::scene::SceneName;
use shared_types::{ActorKind, ActorState, LightState};

use super::super::lanes::{LaneRef, Lanes};
use super::super::parameters::{Change, Parameters, VehicleChange};
use super::{Control, Planner};

const CAR: u32 = 7;

fn town() -> Lanes {
    Lanes::new(roads::network(SceneName::Town))
}

/// A car on `lane`, `progress` metres along it, at `speed` m/s.
fn car_on(lanes: &Lanes, lane: LaneRef, progress: f64, speed: f32) -> ActorState {
    let pose = lanes.point(lane, progress, 0.0);
    // simbus's axes: x east, y up, z south; a yaw about y.
    let half = (pose.hdg / 2.0) as f32;
    let (sin, cos) = half.sin_cos();
    let (hx, hy) = (pose.hdg.cos() as f32, pose.hdg.sin() as f32);
    ActorState {
        id: u64::from(CAR),
        kind: ActorKind::Vehicle as u32,
        position: [pose.x as f32, 0.7, -pose.y as f32],
        rotation: [0.0, sin, 0.0, cos],
        linear_velocity: [speed * hx, 0.0, -speed * hy],
        extent: [2.3, 0.7, 1.0],
        ..ActorState::default()
    }
}

fn walker_at(x: f64, y: f64) -> ActorState {
    ActorState {
        id: 99,
        kind: ActorKind::Walker as u32,
        position: [x as f32, 0.9, -y as f32],
        rotation: [0.0, 0.0, 0.0, 1.0],
        extent: [0.3, 0.9, 0.3],
        ..ActorState::default()
    }
}

/// The first light's approach lane and stop line.
fn light_approach(lanes: &Lanes) -> (LaneRef, f64, u32) {
    let network = roads::network(SceneName::Town);
    let light = network
        .signals
        .iter()
        .find(|s| s.kind == SignalKind::TrafficLight)
        .unwrap();
    let lane = LaneRef {
        road: light.road,
        lane: light.lane,
    };
    let stop = lanes.project_on(lane, light.stop.x, light.stop.y).unwrap();
    (lane, stop.progress, light.id)
}

fn step(
    lanes: &Lanes,
    planner: &mut Planner,
    actors: &[ActorState],
    lights: &HashMap<u32, LightState>,
    parameters: &Parameters,
) -> Control {
    let mut out = Vec::new();
    planner.step(lanes, actors, lights, (10.0, 0.05), parameters, &mut out);
    assert_eq!(out.len(), 1);
    out[0]
}

#[test]
fn a_car_cruises_along_its_lane_at_the_limit() {
    let lanes = town();
    let (lane, _, _) = light_approach(&lanes);
    let mut planner = Planner::default();
    planner.register(CAR, 0);
    let parameters = Parameters::default();
    let lights = HashMap::new();
    // Slow: throttle; at the limit (30 km/h): none; too fast: brake.
    let slow = step(
        &lanes,
        &mut planner,
        &[car_on(&lanes, lane, 5.0, 2.0)],
        &lights,
        &parameters,
    );
    assert!(slow.throttle > 0.5 && slow.brake == 0.0, "{slow:?}");
    assert!(slow.steer.abs() < 0.05, "straight on: {slow:?}");
    let fast = step(
        &lanes,
        &mut planner,
        &[car_on(&lanes, lane, 5.0, 14.0)],
        &lights,
        &parameters,
    );
    assert!(fast.throttle == 0.0 && fast.brake > 0.3, "{fast:?}");
}

#[test]
fn a_car_stops_at_a_red_light_unless_told_to_run_it() {
    let lanes = town();
    let (lane, stop, light) = light_approach(&lanes);
    let mut planner = Planner::default();
    planner.register(CAR, 0);
    let mut parameters = Parameters::default();
    let red = HashMap::from([(light, LightState::Red)]);
    let green = HashMap::from([(light, LightState::Green)]);
    // 12 m before the line at 8 m/s: braking.
    let car = car_on(&lanes, lane, stop - 12.0, 8.0);
    let at_red = step(&lanes, &mut planner, &[car], &red, &parameters);
    assert!(at_red.brake > 0.3 && at_red.throttle == 0.0, "{at_red:?}");
    let at_green = step(&lanes, &mut planner, &[car], &green, &parameters);
    assert_eq!(at_green.brake, 0.0, "{at_green:?}");
    // Standing a metre before the line (its front): held there on red.
    let standing = car_on(&lanes, lane, stop - 3.3, 0.0);
    let held = step(&lanes, &mut planner, &[standing], &red, &parameters);
    assert_eq!((held.throttle, held.brake), (0.0, 1.0));
    // ignore_lights_percentage(100): it drives on.
    parameters.apply(&Change::Vehicle(CAR, VehicleChange::RunningLight(100.0)));
    let runs = step(&lanes, &mut planner, &[standing], &red, &parameters);
    assert!(runs.throttle > 0.3 && runs.brake == 0.0, "{runs:?}");
}

#[test]
fn a_car_brakes_for_a_walker_on_its_way_unless_told_to_ignore_walkers() {
    let lanes = town();
    let (lane, stop, _) = light_approach(&lanes);
    let mut planner = Planner::default();
    planner.register(CAR, 0);
    let mut parameters = Parameters::default();
    let car = car_on(&lanes, lane, stop - 30.0, 8.0);
    let ahead = lanes.point(lane, stop - 20.0, 0.0);
    let walker = walker_at(ahead.x, ahead.y);
    let lights = HashMap::new();
    let brakes = step(&lanes, &mut planner, &[car, walker], &lights, &parameters);
    assert!(brakes.brake > 0.3, "{brakes:?}");
    // One on the sidewalk beside the lane is no reason to brake.
    let beside = lanes.point(lane, stop - 20.0, -3.5);
    let passes = step(
        &lanes,
        &mut planner,
        &[car, walker_at(beside.x, beside.y)],
        &lights,
        &parameters,
    );
    assert_eq!(passes.brake, 0.0, "{passes:?}");
    parameters.apply(&Change::Vehicle(CAR, VehicleChange::IgnoreWalkers(100.0)));
    let ignores = step(&lanes, &mut planner, &[car, walker], &lights, &parameters);
    assert_eq!(ignores.brake, 0.0, "{ignores:?}");
}

#[test]
fn a_car_steers_back_to_its_lane_and_its_randomness_is_its_seeds() {
    let lanes = town();
    let (lane, stop, _) = light_approach(&lanes);
    let lights = HashMap::new();
    let parameters = Parameters::default();
    // A metre left of the centre: it steers right (simbus: negative).
    let mut car = car_on(&lanes, lane, stop - 30.0, 5.0);
    let right = lanes.point(lane, stop - 30.0, 1.0);
    car.position = [right.x as f32, 0.7, -right.y as f32];
    let mut planner = Planner::default();
    planner.register(CAR, 0);
    let back = step(&lanes, &mut planner, &[car], &lights, &parameters);
    assert!(back.steer < -0.05, "{back:?}");
    // The way taken at the junction ahead: the same for the same seed.
    let ways = |seed| {
        let mut planner = Planner::default();
        planner.register(CAR, seed);
        let control = step(
            &lanes,
            &mut planner,
            &[car_on(&lanes, lane, stop - 2.0, 3.0)],
            &lights,
            &parameters,
        );
        (planner.vehicles.get(&CAR).unwrap().lanes.clone(), control)
    };
    assert_eq!(ways(5), ways(5));
    assert!(
        (0..20).any(|seed| ways(seed).0 != ways(5).0),
        "seeds pick other ways"
    );
}

#[test]
fn a_vehicle_gone_from_the_frame_is_no_longer_driven() {
    let lanes = town();
    let mut planner = Planner::default();
    planner.register(CAR, 0);
    let mut out = Vec::new();
    planner.step(
        &lanes,
        &[],
        &HashMap::new(),
        (0.0, 0.05),
        &Parameters::default(),
        &mut out,
    );
    assert!(out.is_empty() && planner.is_empty());
}
