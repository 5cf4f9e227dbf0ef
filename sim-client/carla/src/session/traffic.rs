//! The traffic manager's registry: CARLA 0.9.16's client runs the traffic
//! manager inside the script's process and asks the server which port has
//! one (`is_traffic_manager_running`, `get_traffic_manager_running`),
//! registers the one it starts (`add_traffic_manager_running`) and drops
//! it (`destroy_traffic_manager`). The gateway keeps that map, one per
//! gateway, and drops an entry when the connection that registered it
//! closes: a dead entry would make the next script connect to a traffic
//! manager that is gone (CARLA's client waits for it, then fails).

use rmpv::Value;
use tracing::info;

use super::{arg, arg_u64, Session};
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;
use crate::traffic_managers::{forget_owner, TrafficManager};

/// A port argument: an integer in 0..=65535.
fn arg_port(args: &[Value], i: usize, method: &'static str) -> Result<u16, CallError> {
    let port = arg_u64(args, i, method)?;
    u16::try_from(port).map_err(|_| CallError::Argument {
        method,
        index: i,
        expected: "a port (0..=65535)",
    })
}

impl Session {
    /// Whether a traffic manager runs on the port.
    pub(super) fn on_is_traffic_manager_running(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let port = arg_port(args, 0, "is_traffic_manager_running")?;
        // A script's own, or the gateway's (started for the asking).
        let running = lock(&self.hub.traffic_managers).contains_key(&port)
            || self.hub.natives.ensure(&self.hub, port);
        Ok(Answer::Value(Value::Boolean(running)))
    }

    /// Where the traffic manager of the port listens: `(host, port)`, or
    /// `("", 0)` if none runs there (CARLA's answer).
    pub(super) fn on_get_traffic_manager_running(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let port = arg_port(args, 0, "get_traffic_manager_running")?;
        let client_side = lock(&self.hub.traffic_managers)
            .get(&port)
            .map(|tm| (tm.host.clone(), tm.port));
        let native = || {
            // The gateway's: at the address this client reached it on.
            let host = self.local.map(|a| a.ip().to_string()).unwrap_or_default();
            self.hub.natives.is_running(port).then_some((host, port))
        };
        let (host, port) = client_side.or_else(native).unwrap_or((String::new(), 0));
        Ok(Answer::Value(Value::Array(vec![
            Value::from(host),
            Value::from(port),
        ])))
    }

    /// Registers the traffic manager a script started: `true`, or `false`
    /// if the port has one already (CARLA's answer).
    pub(super) fn on_add_traffic_manager_running(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "add_traffic_manager_running";
        let (host, port) = arg(args, 0, METHOD, "a (host, port) pair", |v| {
            match v.as_array().map(Vec::as_slice) {
                Some([host, port]) => Some((
                    host.as_str()?.to_string(),
                    u16::try_from(port.as_u64()?).ok()?,
                )),
                _ => None,
            }
        })?;
        let mut registry = lock(&self.hub.traffic_managers);
        if registry.contains_key(&port) || self.hub.natives.is_running(port) {
            return Ok(Answer::Value(Value::Boolean(false)));
        }
        info!(peer = %self.peer, "a traffic manager runs in the CARLA client, at {host}:{port}");
        registry.insert(
            port,
            TrafficManager {
                host,
                port,
                owner: self.peer,
            },
        );
        Ok(Answer::Value(Value::Boolean(true)))
    }

    /// Drops the traffic manager of the port: whether one was there.
    pub(super) fn on_destroy_traffic_manager(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let port = arg_port(args, 0, "destroy_traffic_manager")?;
        let removed = lock(&self.hub.traffic_managers).remove(&port).is_some();
        Ok(Answer::Value(Value::Boolean(removed)))
    }

    /// `SetAutopilot` on actor `id`: nothing for the server to do (the
    /// traffic manager runs in CARLA's client), but the actor must exist:
    /// in the last frame, or just spawned through the gateway.
    pub(super) fn autopilot_target(&self, id: u32) -> Result<u32, CallError> {
        let known = lock(&self.hub.actors).contains_key(&id)
            || lock(&self.hub.registry).descriptions.contains_key(&id);
        if known {
            Ok(id)
        } else {
            Err(CallError::UnknownActor(id))
        }
    }

    /// The connection closed: the traffic managers it ran are gone.
    pub(super) fn forget_traffic_managers(&self) {
        let gone = forget_owner(&mut lock(&self.hub.traffic_managers), self.peer);
        for port in gone {
            info!(peer = %self.peer, "the traffic manager on port {port} left with its client");
        }
    }
}
