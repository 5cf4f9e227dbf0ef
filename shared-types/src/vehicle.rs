//! The ray-cast vehicle a [`CommandKind::SpawnVehicle`] command builds: its
//! chassis, mass, wheels and forces, all derived from the command's
//! `params` (half extents and mass), so the server that builds it and a
//! client that describes it (the CARLA gateway's `get_physics_control`)
//! agree on every number.
//!
//! All-zero params build simbus's original vehicle (2 × 0.5 × 1 m,
//! 100 kg), so clients that never set them see no change.
//!
//! [`CommandKind::SpawnVehicle`]: crate::command::CommandKind::SpawnVehicle

/// The original vehicle's chassis half extents (simbus axes: X length,
/// Y height, Z width): 2 m long, 0.5 m high, 1 m wide.
pub const DEFAULT_VEHICLE_HALF_EXTENTS: [f32; 3] = [1.0, 0.25, 0.5];
/// The original vehicle's mass, kg (its chassis at 100 kg/m³).
pub const DEFAULT_VEHICLE_MASS: f32 = 100.0;
/// The smallest half extent a sized vehicle may have, metres.
pub const MIN_VEHICLE_HALF_EXTENT: f32 = 0.05;
/// The largest half extent a sized vehicle may have, metres (a 40 m bus).
pub const MAX_VEHICLE_HALF_EXTENT: f32 = 20.0;
/// The lightest vehicle, kg.
pub const MIN_VEHICLE_MASS: f32 = 1.0;
/// The heaviest vehicle, kg (a loaded articulated lorry is 40 t).
pub const MAX_VEHICLE_MASS: f32 = 100_000.0;

/// Standard gravity, m/s², for the suspension's headroom.
const GRAVITY: f32 = 9.81;
/// Suspension stiffness (rapier's, per unit of chassis mass).
pub const SUSPENSION_STIFFNESS: f32 = 40.0;
/// Suspension damping (rapier's, per unit of chassis mass).
pub const SUSPENSION_DAMPING: f32 = 4.0;
/// Tyre friction slip (rapier's).
pub const FRICTION_SLIP: f32 = 1.5;

/// Why a `SpawnVehicle` command's params build no vehicle.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VehicleSpecError {
    /// Some params are zero and others are not.
    #[error(
        "a vehicle's params are all zero (the default vehicle) or all given \
         (half extents and mass): got {0:?}"
    )]
    Partial([f32; 4]),
    /// A half extent is NaN, infinite or out of range.
    #[error(
        "a vehicle's half extent {value} m is out of range \
         ({MIN_VEHICLE_HALF_EXTENT}..={MAX_VEHICLE_HALF_EXTENT} m)"
    )]
    HalfExtent {
        /// The value given.
        value: f32,
    },
    /// The mass is NaN, infinite or out of range.
    #[error(
        "a vehicle's mass {value} kg is out of range ({MIN_VEHICLE_MASS}..={MAX_VEHICLE_MASS} kg)"
    )]
    Mass {
        /// The value given.
        value: f32,
    },
}

/// A ray-cast vehicle as simbus builds it. Vectors are in the chassis's
/// own axes (simbus's: X forward, Y up, Z right), metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleSpec {
    /// Chassis half extents (the bounding box reported for the vehicle).
    pub half_extents: [f32; 3],
    /// Chassis mass, kg.
    pub mass: f32,
    /// Wheel radius, m.
    pub wheel_radius: f32,
    /// Suspension rest length, m.
    pub suspension_rest_length: f32,
    /// Where each wheel's suspension is attached: front left, front right
    /// (steered), rear left, rear right (driven).
    pub wheels: [[f32; 3]; 4],
    /// Engine force on each driven (rear) wheel at full throttle, newtons.
    pub engine_force: f32,
    /// Braking force of each wheel at full brake, newtons: the four
    /// together stop the vehicle at [`FULL_BRAKE_DECELERATION`] (before
    /// the tyres slide), a brake of 0.1 at a tenth of it.
    pub brake: f32,
    /// Front-wheel angle at full steer, radians.
    pub max_steer: f32,
    /// The most force one wheel's suspension pushes with, newtons.
    pub max_suspension_force: f32,
}

impl Default for VehicleSpec {
    /// simbus's original vehicle (what all-zero params build).
    fn default() -> Self {
        let [x, y, z] = DEFAULT_VEHICLE_HALF_EXTENTS;
        let (x, y, z) = (x * 0.7, -y, z);
        Self {
            half_extents: DEFAULT_VEHICLE_HALF_EXTENTS,
            mass: DEFAULT_VEHICLE_MASS,
            wheel_radius: 0.3,
            suspension_rest_length: 0.3,
            wheels: [[x, y, z], [x, y, -z], [-x, y, z], [-x, y, -z]],
            engine_force: 300.0,
            brake: DEFAULT_VEHICLE_MASS * FULL_BRAKE_DECELERATION / 4.0,
            max_steer: 0.5,
            max_suspension_force: 6000.0,
        }
    }
}

impl VehicleSpec {
    /// The vehicle `SpawnVehicle` params build: all zero, the default one;
    /// else `[half length, half height, half width, mass]` (simbus axes,
    /// metres, kg), each checked.
    ///
    /// # Errors
    ///
    /// Returns [`VehicleSpecError::Partial`] if some params are zero and others
    /// are not, [`VehicleSpecError::HalfExtent`] if a half extent is NaN or
    /// outside [`MIN_VEHICLE_HALF_EXTENT`]`..=`[`MAX_VEHICLE_HALF_EXTENT`]
    /// metres, and [`VehicleSpecError::Mass`] if the mass is NaN or outside
    /// [`MIN_VEHICLE_MASS`]`..=`[`MAX_VEHICLE_MASS`] kg.
    pub fn from_params(params: [f32; 4]) -> Result<Self, VehicleSpecError> {
        if params == [0.0; 4] {
            return Ok(Self::default());
        }
        if params.contains(&0.0) {
            return Err(VehicleSpecError::Partial(params));
        }
        let [x, y, z, mass] = params;
        for value in [x, y, z] {
            if !(MIN_VEHICLE_HALF_EXTENT..=MAX_VEHICLE_HALF_EXTENT).contains(&value) {
                return Err(VehicleSpecError::HalfExtent { value });
            }
        }
        if !(MIN_VEHICLE_MASS..=MAX_VEHICLE_MASS).contains(&mass) {
            return Err(VehicleSpecError::Mass { value: mass });
        }
        Ok(Self::sized([x, y, z], mass))
    }

    /// A vehicle of these half extents and mass: wheels under the
    /// chassis's corners (the wheelbase ~62 % of the length), sized to
    /// its height; the chassis rests ~5 cm above the ground; the engine
    /// pushes it as hard as its mass class does.
    fn sized(half: [f32; 3], mass: f32) -> Self {
        let [hx, hy, hz] = half;
        let wheel_radius = (0.45 * hy).clamp(0.2, 0.55);
        let rest = 0.25;
        // The static sag of the suspension (4 wheels carry m·g).
        let sag = GRAVITY / (4.0 * SUSPENSION_STIFFNESS);
        let (x, z) = (0.62 * hx, (0.85 * hz).max(0.25));
        let y = -hy + wheel_radius + (rest - sag) - 0.05;
        Self {
            half_extents: half,
            mass,
            wheel_radius,
            suspension_rest_length: rest,
            wheels: [[x, y, z], [x, y, -z], [-x, y, z], [-x, y, -z]],
            engine_force: mass * full_throttle_acceleration(mass) / 2.0,
            brake: mass * FULL_BRAKE_DECELERATION / 4.0,
            max_steer: 0.5,
            max_suspension_force: (3.0 * mass * GRAVITY).max(6000.0),
        }
    }

    /// The params that build this vehicle.
    pub fn params(&self) -> [f32; 4] {
        let [x, y, z] = self.half_extents;
        [x, y, z, self.mass]
    }

    /// The chassis's density, kg/m³ (its collider is a box).
    pub fn density(&self) -> f32 {
        let [x, y, z] = self.half_extents;
        self.mass / (8.0 * x * y * z)
    }

    /// The wheelbase (front to rear axle), m.
    pub fn wheelbase(&self) -> f32 {
        self.wheels[0][0] - self.wheels[2][0]
    }
}

/// How hard a full brake decelerates a vehicle on level ground, m/s²
/// (a car's, about what CARLA's cars brake at).
pub const FULL_BRAKE_DECELERATION: f32 = 8.0;

/// The acceleration at full throttle on level ground, m/s², of a vehicle
/// of `mass` kg: its class's power to weight (bicycle, motorcycle, car,
/// van, truck or bus).
pub fn full_throttle_acceleration(mass: f32) -> f32 {
    match mass {
        m if m < 150.0 => 1.5,
        m if m < 500.0 => 5.0,
        m if m < 2_600.0 => 3.5,
        m if m < 5_000.0 => 2.5,
        _ => 1.2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_params_build_the_original_vehicle() {
        let spec = VehicleSpec::from_params([0.0; 4]).unwrap();
        assert_eq!(spec, VehicleSpec::default());
        assert_eq!(spec.engine_force, 300.0);
        assert!((spec.density() - 100.0).abs() < 1e-4);
    }

    #[test]
    fn a_sized_vehicle_has_its_size_mass_and_a_wheelbase_from_its_length() {
        let spec = VehicleSpec::from_params([2.4, 0.75, 1.08, 1800.0]).unwrap();
        assert_eq!(spec.half_extents, [2.4, 0.75, 1.08]);
        assert_eq!(spec.params(), [2.4, 0.75, 1.08, 1800.0]);
        assert!(
            (spec.wheelbase() - 2.976).abs() < 1e-3,
            "{}",
            spec.wheelbase()
        );
        // Two driven wheels push 1800 kg at 3.5 m/s².
        assert!((2.0 * spec.engine_force / spec.mass - 3.5).abs() < 1e-4);
        // Each wheel can carry far more than its share of the weight.
        assert!(spec.max_suspension_force > spec.mass * GRAVITY / 4.0);
    }

    #[test]
    fn bad_params_are_refused_by_name() {
        let cases: [([f32; 4], &str); 6] = [
            ([2.0, 0.7, 0.0, 1500.0], "all zero"),
            ([f32::NAN, 0.7, 1.0, 1500.0], "NaN"),
            ([2.0, -0.7, 1.0, 1500.0], "-0.7"),
            ([500.0, 0.7, 1.0, 1500.0], "500"),
            ([2.0, 0.7, 1.0, f32::INFINITY], "inf"),
            ([2.0, 0.7, 1.0, 1e9], "mass"),
        ];
        for (params, words) in cases {
            let e = VehicleSpec::from_params(params).unwrap_err().to_string();
            assert!(e.contains(words), "{params:?}: {e}");
        }
    }
}
