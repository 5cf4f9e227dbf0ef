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

/// Zenoh's error as a reason for the user: without the source location
/// Zenoh appends (` at /root/.cargo/registry/…/lib.rs:183.`).
pub(super) fn reason(e: &zenoh::Error) -> String {
    let text = e.to_string();
    match text.rfind(" at ") {
        Some(at) if text[at..].contains(".rs:") => text[..at].to_owned(),
        _ => text,
    }
}

/// Checks `endpoint`, given with `flag`, has the form Zenoh needs:
/// `PROTOCOL/HOST:PORT` (`tcp/192.168.1.10:7447`, `tls/[::1]:7447`), with
/// optional `?metadata` / `#config` after it; refused (exit 2) saying so.
pub(super) fn check_endpoint(flag: &str, endpoint: &str) -> Result<(), Failure> {
    let address = endpoint.split(['?', '#']).next().unwrap_or_default();
    let well_formed = address.split_once('/').is_some_and(|(protocol, address)| {
        !protocol.is_empty()
            && protocol
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-')
            && address
                .rsplit_once(':')
                .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok())
    });
    if well_formed {
        Ok(())
    } else {
        Err(Failure::Refused(anyhow::anyhow!(
            "{flag} '{endpoint}' is not a Zenoh endpoint: give PROTOCOL/HOST:PORT, e.g. tcp/0.0.0.0:7447 \
             (listen on every address) or tcp/192.168.1.10:7447"
        )))
    }
}

/// The session's configuration: `--zenoh-config` (or peer mode, no
/// multicast scouting: the endpoints are given), the endpoint, the lease,
/// and a retry of at most one second for a lost connection.
pub(super) fn config(args: &ZenohArgs, role: Role<'_>) -> Result<zenoh::Config, Failure> {
    let refused = |e: zenoh::Error| Failure::Refused(anyhow::anyhow!("{}", reason(&e)));
    let mut config = match &args.zenoh_config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow::anyhow!("{}", reason(&e)))
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
    let (key, flag, endpoint) = match role {
        Role::Listen(endpoint) => ("listen/endpoints", "--listen", endpoint),
        Role::Connect(endpoint) => ("connect/endpoints", "--connect", endpoint),
    };
    check_endpoint(flag, endpoint)?;
    let endpoints = serde_json::to_string(&[endpoint])?;
    // Zenoh's own error here is a parser's dump: say what it needs instead
    // (an unknown protocol, say, passes the check above).
    config.insert_json5(key, &endpoints).map_err(|_| {
        Failure::Refused(anyhow::anyhow!(
            "{flag} '{endpoint}' is not an endpoint Zenoh accepts: give PROTOCOL/HOST:PORT, \
             e.g. tcp/0.0.0.0:7447 (protocols: tcp, udp, tls, quic, ws)"
        ))
    })?;
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
        Failure::Runtime(anyhow::anyhow!("{what}: {}", reason(&e)))
    })
}

#[cfg(test)]
mod tests {
    use super::check_endpoint;

    #[test]
    fn endpoints_need_a_protocol_a_host_and_a_port() {
        for good in [
            "tcp/127.0.0.1:7447",
            "tcp/0.0.0.0:0",
            "tls/[::1]:7447",
            "udp/host.example:7447#iface=eth0",
            "tcp/localhost:7447?prio=1",
        ] {
            assert!(check_endpoint("--listen", good).is_ok(), "{good}");
        }
        for bad in [
            "garbage",
            "",
            "tcp/",
            "tcp/127.0.0.1",
            "tcp/127.0.0.1:port",
            "tcp/127.0.0.1:70000",
            "/127.0.0.1:7447",
            "tcp/:7447",
            "127.0.0.1:7447",
        ] {
            assert!(check_endpoint("--listen", bad).is_err(), "{bad}");
        }
    }
}
