//! The traffic managers CARLA clients run (CARLA 0.9.16 runs them inside
//! the script's process), by port: what the gateway's registry holds.

use std::collections::HashMap;
use std::net::SocketAddr;

/// One running traffic manager: where its RPC server listens, and the
/// CARLA connection that registered it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct TrafficManager {
    pub(crate) host: String,
    pub(crate) port: u16,
    pub(crate) owner: SocketAddr,
}

/// The traffic managers running, by port.
pub(crate) type Registry = HashMap<u16, TrafficManager>;

/// Drops every traffic manager `owner` registered (its connection closed).
pub(crate) fn forget_owner(registry: &mut Registry, owner: SocketAddr) -> Vec<u16> {
    let gone: Vec<u16> = registry
        .iter()
        .filter(|(_, tm)| tm.owner == owner)
        .map(|(&port, _)| port)
        .collect();
    for port in &gone {
        registry.remove(port);
    }
    gone
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_closed_connection_takes_only_its_own_traffic_managers() {
        let a: SocketAddr = "127.0.0.1:1000".parse().unwrap();
        let b: SocketAddr = "127.0.0.1:2000".parse().unwrap();
        let tm = |port, owner| TrafficManager {
            host: "127.0.0.1".into(),
            port,
            owner,
        };
        let mut registry = Registry::new();
        registry.insert(8000, tm(8000, a));
        registry.insert(8001, tm(8001, b));
        registry.insert(8002, tm(8002, a));
        let mut gone = forget_owner(&mut registry, a);
        gone.sort_unstable();
        assert_eq!(gone, [8000, 8002]);
        assert_eq!(registry.keys().copied().collect::<Vec<_>>(), [8001]);
    }
}
