//! CARLA 0.9.16's vehicle and walker blueprints: ids, attributes, sizes.
//!
//! The ids and attribute names are those of CARLA's blueprint library
//! (`Docs/bp_library.md`, `Docs/catalogue_vehicles.md`). Bounding boxes are
//! the extents CARLA reports for each model (`actor.bounding_box.extent`,
//! half sizes in metres, as measured on CARLA 0.9.14–0.9.15 and published
//! by its users; CARLA's docs carry no table of them). Masses are plausible
//! kerb weights for each model, two-wheelers with their rider (CARLA's
//! models carry their own, not published). `generation`, `special_type`,
//! `has_dynamic_doors`, `has_lights` and the recommended colours follow
//! CARLA's catalogue where it says, and are plausible guesses where not
//! (`object_type` is left empty).

/// What a vehicle is, for its `base_type` attribute and its power.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Class {
    Car,
    Truck,
    Van,
    Bus,
    Motorcycle,
    Bicycle,
}

impl Class {
    /// CARLA's `base_type` value.
    pub(crate) fn base_type(self) -> &'static str {
        match self {
            Self::Car => "car",
            Self::Truck => "truck",
            Self::Van => "van",
            Self::Bus => "bus",
            Self::Motorcycle => "motorcycle",
            Self::Bicycle => "bicycle",
        }
    }

    /// CARLA's `number_of_wheels`. simbus builds every vehicle with four
    /// wheels: two-wheelers are approximated.
    pub(crate) fn number_of_wheels(self) -> u8 {
        match self {
            Self::Motorcycle | Self::Bicycle => 2,
            _ => 4,
        }
    }
}

/// One vehicle of CARLA's catalogue.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Vehicle {
    /// The blueprint id.
    pub(crate) id: &'static str,
    pub(crate) class: Class,
    /// CARLA's `generation` (1 or 2).
    pub(crate) generation: u8,
    /// CARLA's bounding-box extent (x forward, y right, z up), metres.
    pub(crate) extent: [f32; 3],
    /// Mass, kg.
    pub(crate) mass: f32,
    /// CARLA's `special_type`: `""`, `electric`, `emergency`, `taxi`.
    pub(crate) special_type: &'static str,
    /// Whether its doors open (`has_dynamic_doors`).
    pub(crate) doors: bool,
    /// Whether it has lights (`has_lights`).
    pub(crate) lights: bool,
    /// Recommended colours ("R,G,B"); empty: no `color` attribute.
    pub(crate) colors: &'static [&'static str],
    /// Recommended driver ids; empty: no `driver_id` attribute.
    pub(crate) drivers: &'static [&'static str],
}

/// The colours most cars are offered in.
const PAINT: &[&str] = &[
    "17,37,103",
    "0,0,0",
    "255,255,255",
    "186,0,0",
    "112,112,112",
    "31,69,40",
];
/// Service liveries: one colour.
const WHITE: &[&str] = &["255,255,255"];
const RED: &[&str] = &["186,0,0"];
const YELLOW: &[&str] = &["255,186,0"];
/// The riders a two-wheeler is offered with.
const RIDERS: &[&str] = &["0", "1", "2"];

/// A vehicle row: id, class, generation, extent, mass, special type,
/// doors, lights, colours, drivers.
#[allow(clippy::too_many_arguments)]
const fn v(
    id: &'static str,
    class: Class,
    generation: u8,
    extent: [f32; 3],
    mass: f32,
    special_type: &'static str,
    doors: bool,
    colors: &'static [&'static str],
    drivers: &'static [&'static str],
) -> Vehicle {
    Vehicle {
        id,
        class,
        generation,
        extent,
        mass,
        special_type,
        doors,
        // Generation 2 models came with working lights.
        lights: generation >= 2,
        colors,
        drivers,
    }
}

use Class::{Bicycle, Bus, Car, Motorcycle, Truck, Van};

/// Every `vehicle.*` blueprint of CARLA 0.9.16.
#[rustfmt::skip]
pub(crate) const VEHICLES: &[Vehicle] = &[
    v("vehicle.audi.a2", Car, 1, [1.8527, 0.8943, 0.7745], 1100.0, "", false, PAINT, &[]),
    v("vehicle.audi.etron", Car, 1, [2.4279, 1.0164, 0.8247], 2500.0, "electric", false, PAINT, &[]),
    v("vehicle.audi.tt", Car, 1, [2.0906, 0.9971, 0.6926], 1300.0, "", false, PAINT, &[]),
    v("vehicle.bh.crossbike", Bicycle, 1, [0.7547, 0.4330, 0.8062], 90.0, "", false, PAINT, RIDERS),
    v("vehicle.bmw.grandtourer", Car, 1, [2.3055, 1.1209, 0.8336], 1600.0, "", false, PAINT, &[]),
    v("vehicle.carlamotors.carlacola", Truck, 2, [2.6019, 1.3135, 1.2337], 7500.0, "", false, RED, &[]),
    v("vehicle.carlamotors.european_hgv", Truck, 2, [3.9679, 1.4455, 1.7310], 12000.0, "", false, PAINT, &[]),
    v("vehicle.carlamotors.firetruck", Truck, 2, [4.2340, 1.4455, 1.9137], 14000.0, "emergency", false, RED, &[]),
    v("vehicle.chevrolet.impala", Car, 1, [2.6787, 1.0166, 0.7053], 1700.0, "", false, PAINT, &[]),
    v("vehicle.citroen.c3", Car, 1, [1.9938, 0.9254, 0.8086], 1100.0, "", false, PAINT, &[]),
    v("vehicle.diamondback.century", Bicycle, 1, [0.8281, 0.2912, 0.8099], 90.0, "", false, PAINT, RIDERS),
    v("vehicle.dodge.charger_2020", Car, 2, [2.5039, 0.9408, 0.7674], 1900.0, "", true, PAINT, &[]),
    v("vehicle.dodge.charger_police", Car, 1, [2.4871, 1.0192, 0.7711], 1900.0, "emergency", false, WHITE, &[]),
    v("vehicle.dodge.charger_police_2020", Car, 2, [2.6188, 0.9649, 0.8192], 2000.0, "emergency", true, WHITE, &[]),
    v("vehicle.ford.ambulance", Van, 2, [3.1828, 1.1756, 1.2157], 4000.0, "emergency", true, WHITE, &[]),
    v("vehicle.ford.crown", Car, 2, [2.6828, 0.9004, 0.7875], 1800.0, "taxi", true, YELLOW, &[]),
    v("vehicle.ford.mustang", Car, 1, [2.3588, 0.9474, 0.6505], 1700.0, "", false, PAINT, &[]),
    v("vehicle.gazelle.omafiets", Bicycle, 1, [0.9217, 0.3295, 0.8879], 95.0, "", false, PAINT, RIDERS),
    v("vehicle.harley-davidson.low_rider", Motorcycle, 1, [1.1751, 0.3831, 0.8247], 380.0, "", false, PAINT, RIDERS),
    v("vehicle.jeep.wrangler_rubicon", Car, 1, [1.9331, 0.9526, 0.9390], 2000.0, "", false, PAINT, &[]),
    v("vehicle.kawasaki.ninja", Motorcycle, 1, [1.0218, 0.3985, 0.7616], 280.0, "", false, PAINT, RIDERS),
    v("vehicle.lincoln.mkz_2017", Car, 1, [2.4508, 1.0642, 0.7554], 1700.0, "", false, PAINT, &[]),
    v("vehicle.lincoln.mkz_2020", Car, 2, [2.4462, 0.9184, 0.7451], 1750.0, "", true, PAINT, &["0"]),
    v("vehicle.mercedes.coupe", Car, 1, [2.5134, 1.0758, 0.8253], 1600.0, "", false, PAINT, &[]),
    v("vehicle.mercedes.coupe_2020", Car, 2, [2.3368, 0.9059, 0.7210], 1700.0, "", true, PAINT, &[]),
    v("vehicle.mercedes.sprinter", Van, 2, [2.9576, 0.9942, 1.2803], 2800.0, "", true, WHITE, &[]),
    v("vehicle.micro.microlino", Car, 1, [1.1036, 0.7405, 0.6880], 513.0, "electric", false, PAINT, &[]),
    v("vehicle.mini.cooper_s", Car, 1, [1.9029, 0.9851, 0.7375], 1200.0, "", false, PAINT, &[]),
    v("vehicle.mini.cooper_s_2021", Car, 2, [2.2763, 1.0485, 0.8836], 1300.0, "", true, PAINT, &[]),
    v("vehicle.mitsubishi.fusorosa", Bus, 2, [5.1363, 1.9721, 2.1264], 10000.0, "", false, WHITE, &[]),
    v("vehicle.nissan.micra", Car, 1, [1.8167, 0.9226, 0.7506], 1000.0, "", false, PAINT, &[]),
    v("vehicle.nissan.patrol", Car, 1, [2.3023, 0.9658, 0.9274], 2500.0, "", false, PAINT, &[]),
    v("vehicle.nissan.patrol_2021", Car, 2, [2.7829, 1.0750, 1.0226], 2700.0, "", true, PAINT, &[]),
    v("vehicle.seat.leon", Car, 1, [2.0964, 0.9081, 0.7369], 1300.0, "", false, PAINT, &[]),
    v("vehicle.tesla.cybertruck", Truck, 1, [3.1368, 1.1948, 1.0491], 3100.0, "electric", false, &[], &[]),
    v("vehicle.tesla.model3", Car, 1, [2.3959, 1.0817, 0.7438], 1850.0, "electric", false, PAINT, &[]),
    v("vehicle.toyota.prius", Car, 1, [2.2568, 1.0034, 0.7624], 1400.0, "", false, PAINT, &[]),
    v("vehicle.vespa.zx125", Motorcycle, 1, [0.9086, 0.4330, 0.7950], 200.0, "", false, PAINT, RIDERS),
    v("vehicle.volkswagen.t2", Van, 1, [2.2402, 1.0347, 1.0189], 1500.0, "", false, PAINT, &[]),
    v("vehicle.volkswagen.t2_2021", Van, 2, [2.2211, 0.8873, 0.9936], 2000.0, "", true, PAINT, &[]),
    v("vehicle.yamaha.yzf", Motorcycle, 1, [1.0954, 0.4330, 0.7652], 270.0, "", false, PAINT, RIDERS),
];

/// The catalogue vehicle `id`, if it is one.
pub(crate) fn vehicle(id: &str) -> Option<&'static Vehicle> {
    VEHICLES.iter().find(|v| v.id == id)
}

/// How many `walker.pedestrian.*` blueprints CARLA 0.9.16 has (0001..).
pub(crate) const WALKERS: u32 = 51;

/// One walker of CARLA's catalogue.
#[derive(Debug, Clone)]
pub(crate) struct Walker {
    pub(crate) id: String,
    pub(crate) gender: &'static str,
    pub(crate) age: &'static str,
    pub(crate) generation: u8,
    /// Recommended speeds, m/s: still, walking, running.
    pub(crate) speeds: [&'static str; 3],
    /// Whether it may use a wheelchair (`can_use_wheelchair`).
    pub(crate) wheelchair: bool,
    /// Its bounding box's half extents in CARLA's axes (x, y, z up), m:
    /// CARLA's adults' 0.1875 × 0.1875 × 0.9375; a child's and a
    /// teenager's height scaled (simbus's approximation: CARLA publishes
    /// no table).
    pub(crate) extent: [f32; 3],
}

/// The catalogue walker `id` (`walker.pedestrian.NNNN`), if it is one.
pub(crate) fn walker_of(id: &str) -> Option<Walker> {
    let n: u32 = id.strip_prefix("walker.pedestrian.")?.parse().ok()?;
    (1..=WALKERS)
        .contains(&n)
        .then(|| walker(n))
        .filter(|w| w.id == id)
}

/// Walker `n` (1..=[`WALKERS`]). CARLA's children are 0009–0011 and
/// 0048–0049 (their bounding boxes are a child's), its teenagers 0012–0014;
/// genders alternate (CARLA publishes no table); 0001–0014 are generation 1.
pub(crate) fn walker(n: u32) -> Walker {
    let age = match n {
        9..=11 | 48 | 49 => "child",
        12..=14 => "teenager",
        _ => "adult",
    };
    Walker {
        id: format!("walker.pedestrian.{n:04}"),
        gender: if n % 2 == 1 { "female" } else { "male" },
        age,
        generation: if n <= 14 { 1 } else { 2 },
        speeds: match age {
            "child" => ["0.0", "0.9", "1.8"],
            _ => ["0.0", "1.4", "2.5"],
        },
        wheelchair: age == "adult",
        extent: match age {
            "child" => [0.1875, 0.1875, 0.6],
            "teenager" => [0.1875, 0.1875, 0.85],
            _ => [0.1875, 0.1875, 0.9375],
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_unique_vehicles_and_sizes_and_masses_are_positive() {
        let mut ids: Vec<&str> = VEHICLES.iter().map(|v| v.id).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), VEHICLES.len());
        assert!(VEHICLES.len() >= 40);
        for v in VEHICLES {
            assert!(
                v.id.starts_with("vehicle.") && v.id.split('.').count() == 3,
                "{}",
                v.id
            );
            assert!(v.extent.iter().all(|e| *e > 0.05 && *e < 10.0), "{}", v.id);
            assert!(v.mass > 50.0 && v.mass < 40_000.0, "{}", v.id);
            assert!((1..=2).contains(&v.generation), "{}", v.id);
        }
        assert_eq!(walker(1).id, "walker.pedestrian.0001");
        assert_eq!(walker(WALKERS).id, "walker.pedestrian.0051");
    }
}
