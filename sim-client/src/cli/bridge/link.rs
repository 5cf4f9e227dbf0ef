//! The Zenoh session of a bridge: its configuration (the user's file, or
//! peer mode without multicast scouting) with the endpoint, the lease and
//! a quick reconnect.

use anyhow::Context as _;
use zenoh::{Session, Wait as _};

use super::ZenohArgs;
use crate::Failure;

/// Which side of the link this bridge is.
#[derive(Debug, Clone, Copy)]
pub(super) enum Role<'a> {
    /// Exporting: listen on the endpoint.
    Listen(&'a str),
    /// Mirroring: connect to the endpoint.
    Connect(&'a str),
}

/// The session's configuration: `--zenoh-config` (or peer mode, no
/// multicast scouting: the endpoints are given), the endpoint, the lease,
/// and a retry of at most one second for a lost connection.
pub(super) fn config(args: &ZenohArgs, role: Role<'_>) -> Result<zenoh::Config, Failure> {
    let refused = |e: zenoh::Error| Failure::Refused(anyhow::anyhow!("{e}"));
    let mut config = match &args.zenoh_config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .with_context(|| format!("--zenoh-config {}", path.display()))
            .map_err(Failure::Refused)?,
        None => {
            let mut config = zenoh::Config::default();
            config.insert_json5("mode", "\"peer\"").map_err(refused)?;
            config
                .insert_json5("scouting/multicast/enabled", "false")
                .map_err(refused)?;
            config
        }
    };
    let (key, endpoint) = match role {
        Role::Listen(endpoint) => ("listen/endpoints", endpoint),
        Role::Connect(endpoint) => ("connect/endpoints", endpoint),
    };
    let endpoints = serde_json::to_string(&[endpoint])?;
    config
        .insert_json5(key, &endpoints)
        .map_err(|e| Failure::Refused(anyhow::anyhow!("endpoint '{endpoint}': {e}")))?;
    config
        .insert_json5("transport/link/tx/lease", &args.lease_ms.to_string())
        .map_err(refused)?;
    if let Role::Connect(_) = role {
        config
            .insert_json5(
                "connect/retry",
                r#"{"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}"#,
            )
            .map_err(refused)?;
    }
    Ok(config)
}

/// Opens the session. A bad endpoint or an address that cannot be bound is
/// refused with Zenoh's reason.
pub(super) fn open(args: &ZenohArgs, role: Role<'_>) -> Result<Session, Failure> {
    let config = config(args, role)?;
    zenoh::open(config).wait().map_err(|e| {
        let what = match role {
            Role::Listen(endpoint) => format!("cannot listen on {endpoint}"),
            Role::Connect(endpoint) => format!("cannot open a Zenoh session towards {endpoint}"),
        };
        Failure::Runtime(anyhow::anyhow!("{what}: {e}"))
    })
}
