//! One CARLA connection: its own simbus client (and, once it turns
//! synchronous mode on, its own claim on the world's tick ownership), and
//! what each CARLA call it makes does to the world.
//!
//! A [`Session`] waits in one place, for the connection's next request
//! ([`Session::serve`]), and answers it through a table ([`call_of`]):
//! one `on_…` method per CARLA call, grouped by concern in the modules
//! below.

mod actors;
mod bones;
mod debug;
mod lights;
mod physics;
mod recorder;
mod ros2;
mod spawned;
pub(crate) mod traffic;
mod vehicle_state;
pub(crate) mod weather;
mod world;

use std::io::{BufReader, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use rmpv::Value;
use sim_client::{Client, Ticker};
use tracing::{debug, info, warn};

use crate::commands;
use crate::error::CallError;
use crate::rpc::{self, Answer, ReadError, Request};
use crate::stream::Hub;

/// The calls answered with `Response<void>` by CARLA (their errors have
/// another shape).
const VOID_CALLS: &[&str] = &[
    "load_new_episode",
    "set_actor_simulate_physics",
    "set_actor_collisions",
    "copy_opendrive_to_file",
    "apply_physics_control",
    "set_weather_parameters",
    "enable_actor_constant_velocity",
    "disable_actor_constant_velocity",
    "set_traffic_light_state",
    "set_traffic_light_green_time",
    "set_traffic_light_yellow_time",
    "set_traffic_light_red_time",
    "freeze_traffic_light",
    "reset_traffic_light_group",
    "freeze_all_traffic_lights",
    "reset_all_traffic_lights",
    "set_bones_transform",
    "blend_pose",
    "get_pose_from_animation",
    "set_vehicle_light_state",
    "open_vehicle_door",
    "close_vehicle_door",
    "apply_ackermann_control_to_vehicle",
    "apply_ackermann_controller_settings",
    "draw_debug_shape",
];

/// How long a call waits for the world's server to answer a (re)connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);
/// How long a CARLA ticker waits for its server to come back after it
/// exited (a resume: `sim-server --resume DIR`) before its call fails with
/// simbus's error; as short as a connection's wait, for the same reason.
pub(super) const RESTART_PATIENCE: Duration = CONNECT_TIMEOUT;
/// How long a client that stops reading its answers may block one.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

/// What answers one CARLA call: the session and the call's arguments.
type Call = fn(&mut Session, &[Value]) -> Result<Answer, CallError>;

/// The table of CARLA calls: the method answering `method`, if simbus
/// serves it (besides the calls on one actor, [`commands::rpc_op`]).
fn call_of(method: &str) -> Option<Call> {
    Some(match method {
        "version" => Session::on_version,
        "get_episode_info" => Session::on_get_episode_info,
        "get_sensor_token" => Session::on_get_sensor_token,
        "get_episode_settings" => Session::on_get_episode_settings,
        "set_episode_settings" => Session::on_set_episode_settings,
        "tick_cue" => Session::on_tick_cue,
        "get_map_info" => Session::on_get_map_info,
        "get_map_data" => Session::on_get_map_data,
        "get_available_maps" => Session::on_get_available_maps,
        "get_weather_parameters" => Session::on_get_weather_parameters,
        "set_weather_parameters" => Session::on_set_weather_parameters,
        "load_new_episode" => Session::on_load_new_episode,
        "copy_opendrive_to_file" => Session::on_copy_opendrive_to_file,
        "get_required_files" => Session::on_get_required_files,
        "request_file" => Session::on_request_file,
        "query_lights_state" => Session::on_empty_list,
        "get_vehicle_light_states" => Session::on_get_vehicle_light_states,
        "get_vehicle_light_state" => Session::on_get_vehicle_light_state,
        "set_vehicle_light_state" => Session::on_set_vehicle_light_state,
        "open_vehicle_door" | "close_vehicle_door" => Session::on_vehicle_door,
        "get_ackermann_controller_settings" => Session::on_get_ackermann_settings,
        "apply_ackermann_controller_settings" => Session::on_apply_ackermann_settings,
        "get_actors_by_id" => Session::on_get_actors_by_id,
        "draw_debug_shape" => Session::on_draw_debug_shape,
        "get_spectator" => Session::on_get_spectator,
        "get_actor_definitions" => Session::on_get_actor_definitions,
        "enable_sensor_for_ros" => Session::on_enable_sensor_for_ros,
        "disable_sensor_for_ros" => Session::on_disable_sensor_for_ros,
        "is_sensor_enabled_for_ros" => Session::on_is_sensor_enabled_for_ros,
        "get_actor_bounding_box" => Session::on_get_actor_bounding_box,
        "get_physics_control" => Session::on_get_physics_control,
        "apply_physics_control" => Session::on_apply_physics_control,
        "spawn_actor" => Session::on_spawn_actor,
        "spawn_actor_with_parent" => Session::on_spawn_actor_with_parent,
        "destroy_actor" => Session::on_destroy_actor,
        "apply_batch" => Session::on_apply_batch,
        "start_recorder" => Session::on_start_recorder,
        "stop_recorder" => Session::on_stop_recorder,
        "replay_file" => Session::on_replay_file,
        "stop_replayer" => Session::on_stop_replayer,
        "set_replayer_time_factor" => Session::on_set_replayer_time_factor,
        "show_recorder_file_info" => Session::on_show_recorder_file_info,
        "show_recorder_collisions" => Session::on_show_recorder_collisions,
        "show_recorder_actors_blocked" => Session::on_show_recorder_actors_blocked,
        "is_traffic_manager_running" => Session::on_is_traffic_manager_running,
        "get_traffic_manager_running" => Session::on_get_traffic_manager_running,
        "add_traffic_manager_running" => Session::on_add_traffic_manager_running,
        "destroy_traffic_manager" => Session::on_destroy_traffic_manager,
        "reset_all_traffic_lights" => Session::on_reset_all_traffic_lights,
        "freeze_all_traffic_lights" => Session::on_freeze_all_traffic_lights,
        "get_group_traffic_lights" => Session::on_get_group_traffic_lights,
        "get_light_boxes" => Session::on_get_light_boxes,
        "get_bones_transform" => Session::on_get_bones_transform,
        "set_bones_transform" | "blend_pose" | "get_pose_from_animation" => Session::on_pose,
        _ => return None,
    })
}

/// One CARLA connection.
pub(crate) struct Session {
    world: String,
    timeout: Duration,
    peer: SocketAddr,
    /// The gateway's address this connection reached.
    local: Option<SocketAddr>,
    streaming_port: u16,
    hub: Arc<Hub>,
    client: Option<Client>,
    /// The run `client`'s server continues
    /// ([`sim_client::Status::run_pid`]): CARLA's episode ids are built
    /// from it, so a server resumed from its journal keeps them.
    run_pid: u32,
    ticker: Option<Ticker>,
    /// The run `ticker` was claimed in: a server that comes back to it
    /// must continue that run (a resume), or the ticker gives it back.
    ticker_run: u32,
    /// The factor of the last `set_replayer_time_factor`, applied to every
    /// later `replay_file` (CARLA's replayer keeps it; 1 until set).
    replay_time_factor: f64,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("peer", &self.peer)
            .field("ticker", &self.ticker.is_some())
            .finish_non_exhaustive()
    }
}

impl Session {
    pub(crate) fn new(
        world: String,
        timeout: Duration,
        peer: SocketAddr,
        streaming_port: u16,
        hub: Arc<Hub>,
    ) -> Self {
        Self {
            world,
            timeout,
            peer,
            local: None,
            streaming_port,
            hub,
            client: None,
            run_pid: 0,
            ticker: None,
            ticker_run: 0,
            replay_time_factor: 1.0,
        }
    }

    /// Serves the connection until it closes or misbehaves. The session
    /// (and its tick ownership) ends with it.
    pub(crate) fn serve(mut self, socket: TcpStream) {
        let peer = self.peer;
        self.local = socket.local_addr().ok();
        let _ = socket.set_nodelay(true);
        // A client that stops reading its answers is dropped.
        let _ = socket.set_write_timeout(Some(WRITE_TIMEOUT));
        let Ok(mut writer) = socket.try_clone() else {
            return;
        };
        let mut reader = BufReader::new(socket);
        info!(%peer, "CARLA client connected");
        loop {
            // The one wait point: the connection's next request.
            let request = match rpc::read_request(&mut reader) {
                Ok(request) => request,
                Err(ReadError::Closed) => break,
                Err(e) => {
                    warn!(%peer, "dropping a CARLA client: {e}");
                    break;
                }
            };
            debug!(%peer, method = request.method, asynchronous = request.asynchronous, "CARLA call");
            let answer = self.on_request(&request);
            if writer
                .write_all(&rpc::response(request.id, answer))
                .is_err()
            {
                break;
            }
        }
        self.forget_traffic_managers();
        // Released before the others are told: a connection that a dead
        // client's ticker refused waits for this.
        self.ticker = None;
        self.hub.connection_ended();
        info!(%peer, "CARLA client gone");
    }

    /// Answers one request.
    pub(crate) fn on_request(&mut self, request: &Request) -> Answer {
        let method = request.method.as_str();
        let void = VOID_CALLS.contains(&method);
        let answer = self.call(method, &request.args);
        // A batch reports a dead server per command: look after every call.
        self.forget_a_dead_server();
        match answer {
            Ok(answer) => answer,
            Err(e) => {
                let message = e.to_string();
                debug!(peer = %self.peer, method, "refused: {message}");
                if method == "apply_batch" {
                    Answer::RpcError(message)
                } else {
                    Answer::Error { message, void }
                }
            }
        }
    }

    /// Dispatches one call through the table.
    fn call(&mut self, method: &str, args: &[Value]) -> Result<Answer, CallError> {
        if let Some(call) = call_of(method) {
            return call(self, args);
        }
        match commands::rpc_op(method, args) {
            Some(op) => self.on_actor_op(op?, VOID_CALLS.contains(&method)),
            None => Err(CallError::UnsupportedCall(method.to_string())),
        }
    }

    /// This connection's name as a ticker: `carla:<address>`.
    fn ticker_name(&self) -> String {
        format!("carla:{}", self.peer)
    }

    /// The simbus client, connected on first use and again after the
    /// server came back.
    fn client(&mut self) -> Result<&mut Client, CallError> {
        self.forget_a_dead_server();
        if self.client.is_none() {
            // A world with no server fails fast, well inside CARLA's
            // timeout; a server resumed from its journal within it is
            // served.
            let connect = self.timeout.min(CONNECT_TIMEOUT);
            let mut client = Client::connect(&self.world, connect).map_err(CallError::simbus)?;
            client.set_request_timeout(self.timeout);
            self.run_pid = client.status().map_err(CallError::simbus)?.run_pid;
            self.client = Some(client);
        }
        self.client.as_mut().ok_or(CallError::NoConnection)
    }

    /// The run of the server this session talks to (connecting first).
    fn run_pid(&mut self) -> Result<u32, CallError> {
        self.client()?;
        Ok(self.run_pid)
    }

    /// Forgets the connection once its server is gone (the next call
    /// connects again, to the server that came back on the world). The
    /// ticker stays: its next tick claims the world again from a server
    /// resumed from its journal ([`Ticker::set_follow_restarts`]).
    fn forget_a_dead_server(&mut self) {
        let gone = self
            .client
            .as_ref()
            .is_some_and(|c| !sim_client::process_alive(c.server_pid()));
        if gone {
            info!(peer = %self.peer, world = self.world, "the simbus server is gone; the next call connects again");
            self.client = None;
        }
    }
}

/// Argument 0 of `method`: an actor id.
fn actor_id_arg(args: &[Value], method: &'static str) -> Result<u32, CallError> {
    args.first()
        .and_then(commands::actor_id)
        .ok_or(CallError::Shape {
            method,
            what: "no actor id",
        })
}

impl Session {
    /// Argument 0 of `method`: an actor of `kind` in the last frame
    /// (`wrong` names one of another kind).
    fn actor_of_kind(
        &self,
        args: &[Value],
        method: &'static str,
        kind: shared_types::ActorKind,
        wrong: fn(u32) -> CallError,
    ) -> Result<u32, CallError> {
        let id = actor_id_arg(args, method)?;
        let found = crate::locks::lock(&self.hub.actors)
            .get(&id)
            .map(|a| shared_types::ActorKind::from_u32(a.kind));
        match found {
            Some(k) if k == Some(kind) => Ok(id),
            Some(_) => Err(wrong(id)),
            None => Err(CallError::UnknownActor(id)),
        }
    }
}

/// Argument `i` as an unsigned integer.
fn arg_u64(args: &[Value], i: usize, method: &'static str) -> Result<u64, CallError> {
    arg(args, i, method, "an integer", Value::as_u64)
}

/// Argument `i` as a string.
fn arg_str(args: &[Value], i: usize, method: &'static str) -> Result<String, CallError> {
    arg(args, i, method, "a string", |v| {
        v.as_str().map(str::to_string)
    })
}

/// Argument `i` as a number, whether sent as a float or an integer.
fn arg_f64(args: &[Value], i: usize, method: &'static str) -> Result<f64, CallError> {
    arg(args, i, method, "a number", commands::number)
}

/// Argument `i` as `read` takes it, or the error naming what was
/// `expected` there.
fn arg<T>(
    args: &[Value],
    i: usize,
    method: &'static str,
    expected: &'static str,
    read: impl FnOnce(&Value) -> Option<T>,
) -> Result<T, CallError> {
    args.get(i).and_then(read).ok_or(CallError::Argument {
        method,
        index: i,
        expected,
    })
}

/// Argument `i` as a boolean, `false` if absent or not one.
fn arg_flag(args: &[Value], i: usize) -> bool {
    args.get(i).and_then(Value::as_bool).unwrap_or(false)
}
