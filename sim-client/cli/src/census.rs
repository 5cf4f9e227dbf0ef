//! Who holds what in a world, from iceoryx2's own records: every service of
//! the world and the nodes attached to it, and the shared memory the
//! server's process maps. What `sim-client top` shows.

use std::collections::BTreeMap;

use iceoryx2::node::{NodeState, NodeView};
use iceoryx2::service::Service as _;
use serde::Serialize;
use shared_types::ServiceNames;
use simbus_transport::Bus;

use sim_client::Client;

/// One process, its nodes and the world's services it has ports on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub(crate) struct Holder {
    /// Its process.
    pub(crate) pid: u32,
    /// The process's name (`/proc/PID/comm`), empty if unreadable.
    pub(crate) process: String,
    /// Its nodes' names (a client's, its ticker's `sim-client-tick`, a
    /// participant's `lockstep:<name>`, a reader's `sensor-<id>-reader`).
    pub(crate) nodes: Vec<String>,
    /// The services, named after the world's prefix (`frames`, `tick`,
    /// `lockstep`, `sensor/3`, …), sorted.
    pub(crate) services: Vec<String>,
}

/// Every process with a node attached to one of the client's world's
/// services, the server's included. Nodes iceoryx2 cannot place (dead, no
/// permission) are left out.
pub(crate) fn holders(client: &Client) -> Result<Vec<Holder>, String> {
    let prefix = format!("{}/", ServiceNames::new(client.world()).prefix());
    let mut by_pid: BTreeMap<u32, (Vec<String>, Vec<String>)> = BTreeMap::new();
    // The configuration every node of this process uses: loaded by
    // `environment::prepare` when the client connected.
    simbus_transport::environment::prepare()
        .map_err(|e| format!("listing the services of world '{}': {e}", client.world()))?;
    Bus::list(iceoryx2::config::Config::global_config(), |service| {
        let name = service.static_details.name().to_string();
        if let (Some(short), Some(dynamic)) =
            (name.strip_prefix(&prefix), service.dynamic_details.as_ref())
        {
            for node in &dynamic.nodes {
                if let NodeState::Alive(view) = node {
                    let pid = view
                        .id()
                        .pid::<Bus>()
                        .map_or(0, |p| u32::try_from(p.value()).unwrap_or(0));
                    let node_name = view
                        .details()
                        .as_ref()
                        .map_or_else(String::new, |d| d.name().to_string());
                    let (nodes, services) = by_pid.entry(pid).or_default();
                    if !node_name.is_empty() {
                        nodes.push(node_name);
                    }
                    services.push(short.to_owned());
                }
            }
        }
        iceoryx2::prelude::CallbackProgression::Continue
    })
    .map_err(|e| format!("listing the services of world '{}': {e:?}", client.world()))?;
    Ok(by_pid
        .into_iter()
        .map(|(pid, (mut nodes, mut services))| {
            for list in [&mut nodes, &mut services] {
                list.sort();
                list.dedup();
            }
            let process = std::fs::read_to_string(format!("/proc/{pid}/comm"))
                .map(|comm| comm.trim().to_owned())
                .unwrap_or_default();
            Holder {
                pid,
                process,
                nodes,
                services,
            }
        })
        .collect())
}

/// Shared memory a process maps: distinct `/dev/shm` files, their total
/// size and how much of it is resident (allocated pages).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub(crate) struct SharedMemory {
    /// Distinct files.
    pub(crate) files: usize,
    /// Their summed size.
    pub(crate) bytes: u64,
    /// Their summed allocated pages, in bytes.
    pub(crate) resident_bytes: u64,
}

/// The shared memory process `pid` maps (Linux: `/proc/PID/maps`).
pub(crate) fn shared_memory_of(pid: u32) -> std::io::Result<SharedMemory> {
    use std::os::unix::fs::MetadataExt;
    let maps = std::fs::read_to_string(format!("/proc/{pid}/maps"))?;
    let mut files: Vec<&str> = maps
        .lines()
        .filter_map(|line| line.split_whitespace().nth(5))
        .filter(|path| path.starts_with("/dev/shm/"))
        .collect();
    files.sort_unstable();
    files.dedup();
    let mut usage = SharedMemory::default();
    for path in files {
        // A file removed since the map was read no longer counts.
        if let Ok(meta) = std::fs::metadata(path) {
            usage.files += 1;
            usage.bytes += meta.len();
            usage.resident_bytes += meta.blocks() * 512;
        }
    }
    Ok(usage)
}
