//! The Zenoh session of a bridge: its configuration (the user's file, or
//! peer mode without multicast scouting) with the endpoint, the lease and
//! a quick reconnect.

use zenoh::{Session, Wait as _};

use crate::error::{LinkError, ZenohError};
use crate::side::{Options, Role};

/// Checks `endpoint`, given with `flag`, has the form Zenoh needs:
/// `PROTOCOL/HOST:PORT` (`tcp/192.168.1.10:7447`, `tls/[::1]:7447`), with
/// optional `?metadata` / `#config` after it; refused saying so.
///
/// # Errors
///
/// Returns [`LinkError::BadEndpoint`] (naming `flag`) if `endpoint` is not
/// `PROTOCOL/HOST:PORT` with a port that fits 16 bits.
pub fn check_endpoint(flag: &'static str, endpoint: &str) -> Result<(), LinkError> {
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
        Err(LinkError::BadEndpoint {
            flag,
            endpoint: endpoint.to_owned(),
        })
    }
}

/// The session's configuration: the configuration file (or peer mode, no
/// multicast scouting: the endpoints are given), the endpoint, the lease,
/// and a retry of at most one second for a lost connection.
fn config(options: &Options, role: Role<'_>) -> Result<zenoh::Config, LinkError> {
    let refused = |e: zenoh::Error| LinkError::Config(ZenohError::from(e));
    let mut config = match &options.zenoh_config {
        Some(path) => zenoh::Config::from_file(path).map_err(|e| LinkError::ConfigFile {
            path: path.clone(),
            source: e.into(),
        })?,
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
        Role::Export(endpoint) => ("listen/endpoints", "--listen", endpoint),
        Role::Mirror(endpoint) => ("connect/endpoints", "--connect", endpoint),
    };
    check_endpoint(flag, endpoint)?;
    let endpoints = serde_json::Value::from(vec![endpoint]).to_string();
    // Zenoh's own error here is a parser's dump: say what it needs instead
    // (an unknown protocol, say, passes the check above).
    config
        .insert_json5(key, &endpoints)
        .map_err(|_| LinkError::UnacceptedEndpoint {
            flag,
            endpoint: endpoint.to_owned(),
        })?;
    config
        .insert_json5("transport/link/tx/lease", &options.lease_ms.to_string())
        .map_err(refused)?;
    if let Role::Mirror(_) = role {
        config
            .insert_json5(
                "connect/retry",
                r#"{"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}"#,
            )
            .map_err(refused)?;
    }
    Ok(config)
}

/// Opens the session. A bad endpoint or configuration is refused; an
/// address that cannot be bound fails with Zenoh's reason.
pub(crate) fn open(options: &Options, role: Role<'_>) -> Result<Session, LinkError> {
    let config = config(options, role)?;
    zenoh::open(config).wait().map_err(|e| match role {
        Role::Export(endpoint) => LinkError::Listen {
            endpoint: endpoint.to_owned(),
            source: e.into(),
        },
        Role::Mirror(endpoint) => LinkError::Connect {
            endpoint: endpoint.to_owned(),
            source: e.into(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::check_endpoint;
    use crate::error::ZenohError;

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

    #[test]
    fn zenoh_errors_are_shown_without_zenohs_source_location() {
        let located: zenoh::Error = "bad lease at /root/.cargo/registry/x/lib.rs:183.".into();
        assert_eq!(ZenohError::from(located).to_string(), "bad lease");
        let plain: zenoh::Error = "meet at noon".into();
        assert_eq!(ZenohError::from(plain).to_string(), "meet at noon");
    }
}
