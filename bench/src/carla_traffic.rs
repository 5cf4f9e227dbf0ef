//! `simbus-bench carla`'s traffic-manager rows: ticks per second through
//! CARLA's client with the gateway's traffic manager and with CARLA's own
//! (in the script), 30 and 100 vehicles, and 100 vehicles with 100 AI
//! walkers, each on a server of the town and a gateway of its own.

use std::path::Path;

use crate::carla::{free_port, gateway_on, latencies, script_side, CarlaArgs, ScriptSide};
use crate::stats::Latencies;

/// The traffic manager's rows, and `get_map()` + `generate_waypoints(2.0)`
/// on the town.
pub(crate) struct Traffic {
    pub(crate) rows: Vec<TrafficRow>,
    pub(crate) map: Latencies,
    pub(crate) waypoints: u64,
}

/// Ticks per second through CARLA's client with one traffic manager.
pub(crate) struct TrafficRow {
    /// "native" (the gateway's) or "CARLA's" (in the script).
    manager: &'static str,
    vehicles: u64,
    walkers: u64,
    /// `None`: it deadlocked (after that many timed ticks).
    ticks_per_s: Option<f64>,
    deadlocked_after: Option<u64>,
}

/// The traffic manager's rows, each on a server of the town and a gateway
/// of its own: the native one and CARLA's, with 30 and 100 vehicles, and
/// 100 vehicles with 100 walkers.
pub(crate) fn traffic(
    args: &CarlaArgs,
    sim_client: &Path,
    python: &Path,
    script: &Path,
) -> anyhow::Result<Traffic> {
    let ticks = args.traffic_ticks.to_string();
    let mut rows = Vec::new();
    for (manager, flags) in [
        ("native", &[][..]),
        ("CARLA's", &["--client-traffic-manager"][..]),
    ] {
        for (vehicles, walkers) in [("30", "0"), ("100", "0"), ("100", "100")] {
            let (_server, _gateway, port) = gateway_on("carla-town", "town", sim_client, flags)?;
            let carla = ScriptSide {
                python,
                script,
                target: &port,
            };
            let tm_port = free_port()?.to_string();
            let answer = script_side(
                carla,
                "traffic",
                &[&ticks, vehicles, &tm_port, walkers],
                |_| Ok(()),
            )?;
            rows.push(TrafficRow {
                manager,
                vehicles: answer["vehicles"].as_u64().unwrap_or(0),
                walkers: answer["walkers"].as_u64().unwrap_or(0),
                ticks_per_s: answer["ticks_per_s"].as_f64(),
                deadlocked_after: answer["deadlocked_after"].as_u64(),
            });
        }
    }
    let (_server, _gateway, port) = gateway_on("carla-town", "town", sim_client, &[])?;
    let carla = ScriptSide {
        python,
        script,
        target: &port,
    };
    let answer = script_side(carla, "map", &["5"], |_| Ok(()))?;
    Ok(Traffic {
        rows,
        map: latencies(&answer, "ns")?,
        waypoints: answer["waypoints"].as_u64().unwrap_or(0),
    })
}

impl TrafficRow {
    pub(crate) fn json(&self) -> serde_json::Value {
        serde_json::json!({"manager": self.manager, "vehicles": self.vehicles,
            "walkers": self.walkers, "ticks_per_s": self.ticks_per_s,
            "deadlocked_after": self.deadlocked_after})
    }

    pub(crate) fn line(&self) -> String {
        let what = format!(
            "{} traffic manager, {} vehicles, {} walkers",
            self.manager, self.vehicles, self.walkers
        );
        match (self.ticks_per_s, self.deadlocked_after) {
            (Some(rate), _) => format!("{what}: {rate:.0} ticks/s"),
            (None, after) => format!(
                "{what}: deadlocked after {} timed ticks (CARLA's #9172)",
                after.unwrap_or(0)
            ),
        }
    }
}
