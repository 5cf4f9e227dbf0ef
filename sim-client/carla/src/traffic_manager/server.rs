//! The traffic manager's RPC server: what CARLA's client sends a traffic
//! manager it finds running (`TrafficManagerRemote` → `TrafficManagerClient`,
//! plain rpclib msgpack-RPC, every call waited for, 2 s timeout). Each
//! call is checked, then queued as a [`Change`] for the driver; bad input
//! is an rpclib error and changes nothing.

use std::io::{BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;

use rmpv::Value;
use tracing::{debug, info, warn};

use super::Shared;
use crate::rpc::{self, Answer, ReadError};
use simbus_traffic::{Change, GlobalChange, Turn, VehicleChange};

/// Accepts CARLA clients of the traffic manager until it shuts down.
pub(super) fn accept(listener: TcpListener, shared: Arc<Shared>) {
    for socket in listener.incoming() {
        if shared.is_stopped() {
            return;
        }
        let Ok(socket) = socket else {
            continue;
        };
        let shared = shared.clone();
        let spawned = std::thread::Builder::new()
            .name("carla-tm-client".into())
            .spawn(move || serve(socket, &shared));
        if let Err(e) = spawned {
            warn!("no thread for a traffic-manager client: {e}");
        }
    }
}

/// Serves one connection until it closes or sends garbage.
fn serve(socket: TcpStream, shared: &Shared) {
    let peer = socket.peer_addr().ok();
    let _ = socket.set_nodelay(true);
    let Ok(mut writer) = socket.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(socket);
    loop {
        let request = match rpc::read_plain_request(&mut reader) {
            Ok(request) => request,
            Err(ReadError::Closed) => return,
            Err(e) => {
                warn!(?peer, "dropping a traffic-manager client: {e}");
                return;
            }
        };
        let answer = match call(shared, &request.method, &request.args) {
            Ok(value) => Answer::Raw(value),
            Err(message) => {
                debug!(
                    ?peer,
                    method = request.method,
                    "traffic-manager call refused: {message}"
                );
                Answer::RpcError(message)
            }
        };
        if writer
            .write_all(&rpc::response(request.id, answer))
            .is_err()
        {
            return;
        }
    }
}

/// A refused call's message.
type Refusal = String;

/// Serves one call: its result, or why it was refused.
fn call(shared: &Shared, method: &str, args: &[Value]) -> Result<Value, Refusal> {
    let a = Args { method, args };
    let change = match method {
        "health_check_remote_TM" => return Ok(Value::Nil),
        "synchronous_tick" => return Ok(Value::Boolean(true)),
        "get_next_action" | "get_all_actions" => {
            a.id(0)?;
            return Ok(Value::Nil);
        }
        "shut_down" => {
            a.count(0)?;
            info!(
                port = shared.port,
                "a CARLA client shut the traffic manager down"
            );
            Change::ShutDown
        }
        "register_vehicle" => Change::Register(a.actors(0)?),
        "unregister_vehicle" => Change::Unregister(a.actors(0)?),
        "set_percentage_speed_difference" => a.vehicle(VehicleChange::SpeedDifference)?,
        "set_lane_offset" => a.vehicle(VehicleChange::LaneOffset)?,
        "set_desired_speed" => a.vehicle(VehicleChange::DesiredSpeed)?,
        "set_distance_to_leading_vehicle" => a.vehicle(VehicleChange::Distance)?,
        "set_percentage_running_light" => a.percentage(VehicleChange::RunningLight)?,
        "set_percentage_running_sign" => a.percentage(VehicleChange::RunningSign)?,
        "set_percentage_ignore_walkers" => a.percentage(VehicleChange::IgnoreWalkers)?,
        "set_percentage_ignore_vehicles" => a.percentage(VehicleChange::IgnoreVehicles)?,
        "set_percentage_keep_slow_lane_rule" | "keep_slow_lane_rule_percentage" => {
            a.percentage(VehicleChange::KeepRight)?
        }
        "set_percentage_random_left_lanechange" | "random_left_lanechange_percentage" => {
            a.percentage(VehicleChange::RandomLeft)?
        }
        "set_percentage_random_right_lanechange" | "random_right_lanechange_percentage" => {
            a.percentage(VehicleChange::RandomRight)?
        }
        "update_vehicle_lights" => {
            a.count(2)?;
            Change::Vehicle(a.actor(0)?, VehicleChange::UpdateLights(a.boolean(1)?))
        }
        "set_auto_lane_change" => {
            a.count(2)?;
            Change::Vehicle(a.actor(0)?, VehicleChange::AutoLaneChange(a.boolean(1)?))
        }
        "set_force_lane_change" => {
            // One lane each way: there is no lane to change to.
            a.count(2)?;
            a.actor(0)?;
            a.boolean(1)?;
            return Ok(Value::Nil);
        }
        "set_collision_detection" => {
            a.count(3)?;
            let other = a.actor(1)?;
            Change::Vehicle(
                a.actor(0)?,
                VehicleChange::CollisionDetection(other, a.boolean(2)?),
            )
        }
        "set_global_percentage_speed_difference" => a.global(GlobalChange::SpeedDifference)?,
        "set_global_lane_offset" => a.global(GlobalChange::LaneOffset)?,
        "set_global_distance_to_leading_vehicle" => a.global(GlobalChange::Distance)?,
        "set_hybrid_physics_radius" => a.global(GlobalChange::HybridRadius)?,
        "set_hybrid_physics_mode" => Change::Global(GlobalChange::HybridPhysics(a.flag()?)),
        "set_osm_mode" => Change::Global(GlobalChange::OsmMode(a.flag()?)),
        "set_respawn_dormant_vehicles" => Change::Global(GlobalChange::RespawnDormant(a.flag()?)),
        "set_synchronous_mode" => Change::Global(GlobalChange::Synchronous(a.flag()?)),
        "set_synchronous_mode_timeout_in_milisecond" => {
            a.count(1)?;
            a.number(0)?;
            return Ok(Value::Nil);
        }
        "set_boundaries_respawn_dormant_vehicles" | "set_max_boundaries" => {
            a.count(2)?;
            Change::Global(GlobalChange::RespawnBounds([a.number(0)?, a.number(1)?]))
        }
        "set_random_device_seed" => {
            a.count(1)?;
            let seed = args[0]
                .as_u64()
                .or_else(|| args[0].as_i64().map(|v| v as u64))
                .ok_or_else(|| a.wrong(0, "a seed (an integer)"))?;
            Change::Global(GlobalChange::Seed(seed))
        }
        "set_path" | "update_custom_path" => {
            let id = a.actor(0)?;
            Change::Vehicle(id, VehicleChange::Path(a.locations(1)?))
        }
        "remove_custom_path" => Change::Vehicle(a.id(0)?, VehicleChange::Path(Vec::new())),
        "set_imported_route" | "update_imported_route" => {
            let id = a.actor(0)?;
            Change::Vehicle(id, VehicleChange::Route(a.route(1)?))
        }
        "remove_imported_route" => Change::Vehicle(a.id(0)?, VehicleChange::Route(Vec::new())),
        _ => {
            // rpclib's own words for a name it does not bind.
            return Err(format!(
                "rpclib: server could not find function '{method}' with argument count {}.",
                args.len()
            ));
        }
    };
    shared.queue(change);
    Ok(Value::Nil)
}

/// A call's arguments, read with errors that name the call.
struct Args<'a> {
    method: &'a str,
    args: &'a [Value],
}

impl Args<'_> {
    fn wrong(&self, index: usize, expected: &str) -> Refusal {
        format!("{}: argument {index} is not {expected}", self.method)
    }

    fn count(&self, n: usize) -> Result<(), Refusal> {
        if self.args.len() == n {
            Ok(())
        } else {
            Err(format!(
                "{}: {} arguments, expected {n}",
                self.method,
                self.args.len()
            ))
        }
    }

    fn get(&self, index: usize) -> Result<&Value, Refusal> {
        self.args
            .get(index)
            .ok_or_else(|| format!("{}: argument {index} is missing", self.method))
    }

    /// An actor id given as such (`ActorId`).
    fn id(&self, index: usize) -> Result<u32, Refusal> {
        self.get(index)?
            .as_u64()
            .and_then(|v| u32::try_from(v).ok())
            .ok_or_else(|| self.wrong(index, "an actor id"))
    }

    /// An actor given as CARLA's `rpc::Actor` (`[id, parent, description,
    /// ...]`), or as its id.
    fn actor(&self, index: usize) -> Result<u32, Refusal> {
        let value = self.get(index)?;
        let id = match value {
            Value::Array(fields) => fields.first().and_then(Value::as_u64),
            v => v.as_u64(),
        };
        id.and_then(|v| u32::try_from(v).ok())
            .ok_or_else(|| self.wrong(index, "an actor"))
    }

    fn actors(&self, index: usize) -> Result<Vec<u32>, Refusal> {
        let Value::Array(list) = self.get(index)? else {
            return Err(self.wrong(index, "a list of actors"));
        };
        let inner = Args {
            method: self.method,
            args: list,
        };
        (0..list.len()).map(|i| inner.actor(i)).collect()
    }

    fn number(&self, index: usize) -> Result<f32, Refusal> {
        let value = self.get(index)?;
        let n = value
            .as_f64()
            .or_else(|| value.as_i64().map(|v| v as f64))
            .or_else(|| value.as_u64().map(|v| v as f64))
            .ok_or_else(|| self.wrong(index, "a number"))?;
        if n.is_finite() {
            Ok(n as f32)
        } else {
            Err(self.wrong(index, "a finite number"))
        }
    }

    fn boolean(&self, index: usize) -> Result<bool, Refusal> {
        self.get(index)?
            .as_bool()
            .ok_or_else(|| self.wrong(index, "a boolean"))
    }

    /// The one boolean of a global switch.
    fn flag(&self) -> Result<bool, Refusal> {
        self.count(1)?;
        self.boolean(0)
    }

    fn global(&self, change: impl Fn(f32) -> GlobalChange) -> Result<Change, Refusal> {
        self.count(1)?;
        Ok(Change::Global(change(self.number(0)?)))
    }

    fn vehicle(&self, change: impl Fn(f32) -> VehicleChange) -> Result<Change, Refusal> {
        self.count(2)?;
        Ok(Change::Vehicle(self.actor(0)?, change(self.number(1)?)))
    }

    /// A percentage in 0..=100 for one vehicle.
    fn percentage(&self, change: impl Fn(f32) -> VehicleChange) -> Result<Change, Refusal> {
        self.count(2)?;
        let pct = self.number(1)?;
        if !(0.0..=100.0).contains(&pct) {
            return Err(self.wrong(1, "a percentage (0 to 100)"));
        }
        Ok(Change::Vehicle(self.actor(0)?, change(pct)))
    }

    /// CARLA's `std::vector<geom::Location>`: `[[x, y, z], ...]`.
    fn locations(&self, index: usize) -> Result<Vec<[f32; 3]>, Refusal> {
        let Value::Array(points) = self.get(index)? else {
            return Err(self.wrong(index, "a list of locations"));
        };
        points
            .iter()
            .map(|p| {
                let Value::Array(xyz) = p else {
                    return Err(self.wrong(index, "a list of locations"));
                };
                let inner = Args {
                    method: self.method,
                    args: xyz,
                };
                if xyz.len() != 3 {
                    return Err(self.wrong(index, "a list of locations"));
                }
                Ok([inner.number(0)?, inner.number(1)?, inner.number(2)?])
            })
            .collect()
    }

    /// CARLA's `Route`: `RoadOption` bytes (msgpack bin, or integers).
    fn route(&self, index: usize) -> Result<Vec<Turn>, Refusal> {
        let bytes: Vec<u8> = match self.get(index)? {
            Value::Binary(bytes) => bytes.clone(),
            Value::Array(items) => items
                .iter()
                .map(|v| v.as_u64().and_then(|v| u8::try_from(v).ok()))
                .collect::<Option<_>>()
                .ok_or_else(|| self.wrong(index, "a route"))?,
            _ => return Err(self.wrong(index, "a route")),
        };
        Ok(bytes
            .into_iter()
            .filter_map(Turn::from_road_option)
            .collect())
    }
}
