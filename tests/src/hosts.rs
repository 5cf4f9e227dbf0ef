//! Two hosts on one machine, for the tests of what crosses machines: two
//! network namespaces joined by a veth pair, each with its own iceoryx2
//! root, so their shared memory cannot meet and their only link is the
//! veth. Creating them needs root (`ip netns`); they are removed on drop,
//! whatever the test did.

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

use crate::{PrivateRoot, Proc};

/// One host: a network namespace with one end of the veth pair and its own
/// iceoryx2 root.
#[derive(Debug)]
pub struct Host {
    namespace: String,
    interface: String,
    address: String,
    /// Its iceoryx2 root.
    pub root: PrivateRoot,
}

/// Runs `ip args`, panicking with its output when it fails.
fn ip(args: &[&str]) {
    let output = Command::new("ip")
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("running `ip {}`: {e} (iproute2 is needed)", args.join(" ")));
    assert!(
        output.status.success(),
        "`ip {}` failed ({}): {}\nthe two-host tests create network namespaces: run them as root",
        args.join(" "),
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
}

impl Host {
    /// Its address on the veth link.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// Its network namespace.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// `program args` started in this host (its namespace and root).
    pub fn spawn(&self, program: &str, args: &[&str]) -> Proc {
        Proc::spawn_wrapped(
            &["ip", "netns", "exec", &self.namespace],
            program,
            args,
            &self.root.env(),
        )
    }

    /// `sim-client --world W --timeout T args` started in this host.
    pub fn client(&self, world: &str, timeout: &str, args: &[&str]) -> Proc {
        let mut all = vec!["--world", world, "--timeout", timeout];
        all.extend_from_slice(args);
        self.spawn("sim-client", &all)
    }

    /// Takes this host's end of the link down (`false`) or up.
    pub fn set_link(&self, up: bool) {
        ip(&[
            "-n",
            &self.namespace,
            "link",
            "set",
            &self.interface,
            if up { "up" } else { "down" },
        ]);
    }
}

/// Two hosts joined by a veth pair (`a` at .1, `b` at .2 of a /24 no other
/// test uses). Removed on drop.
#[derive(Debug)]
pub struct TwoHosts {
    /// The first host.
    pub a: Host,
    /// The second host.
    pub b: Host,
}

/// A world served on host `a`, exported over the veth and mirrored on `b`.
#[derive(Debug)]
pub struct Mirrored {
    /// `sim-server` on `a`.
    pub server: Proc,
    /// `sim-client bridge zenoh --listen` on `a`, exporting.
    pub exporter: Proc,
    /// `sim-client bridge zenoh --connect` on `b`, mirroring.
    pub mirror: Proc,
}

impl TwoHosts {
    /// Serves `world` on `a` (`sim-server --world W <server_args>`), exports
    /// it on `a`'s address (port 7447) and mirrors it on `b` (with
    /// `mirror_args` added), once both say so.
    pub fn mirrored(&self, world: &str, server_args: &[&str], mirror_args: &[&str]) -> Mirrored {
        const READY: std::time::Duration = std::time::Duration::from_secs(30);
        let endpoint = format!("tcp/{}:7447", self.a.address());
        let mut args = vec!["--world", world];
        args.extend_from_slice(server_args);
        let server = self.a.spawn("sim-server", &args);
        let exporter = self
            .a
            .client(world, "20", &["bridge", "zenoh", "--listen", &endpoint]);
        exporter.wait_line("exporting world", READY);
        let mut args = vec!["bridge", "zenoh", "--connect", &endpoint];
        args.extend_from_slice(mirror_args);
        let mirror = self.b.client(world, "20", &args);
        mirror.wait_line("mirroring world", READY);
        Mirrored {
            server,
            exporter,
            mirror,
        }
    }

    /// Creates both namespaces, the veth pair between them and their roots.
    pub fn new(tag: &str) -> Self {
        static COUNTER: AtomicU32 = AtomicU32::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let pid = std::process::id();
        let id = format!("{}{n}", pid % 100_000);
        let subnet = format!("10.{}.{}", 100 + (pid / 250 + n) % 150, pid % 250);
        let hosts = Self {
            a: Host {
                namespace: format!("sb{id}a"),
                interface: format!("sbv{id}a"),
                address: format!("{subnet}.1"),
                root: PrivateRoot::new(&format!("{tag}a")),
            },
            b: Host {
                namespace: format!("sb{id}b"),
                interface: format!("sbv{id}b"),
                address: format!("{subnet}.2"),
                root: PrivateRoot::new(&format!("{tag}b")),
            },
        };
        // From here on, drop removes whatever was made.
        for host in [&hosts.a, &hosts.b] {
            ip(&["netns", "add", &host.namespace]);
            ip(&["-n", &host.namespace, "link", "set", "lo", "up"]);
        }
        ip(&[
            "link",
            "add",
            &hosts.a.interface,
            "netns",
            &hosts.a.namespace,
            "type",
            "veth",
            "peer",
            "name",
            &hosts.b.interface,
            "netns",
            &hosts.b.namespace,
        ]);
        for host in [&hosts.a, &hosts.b] {
            ip(&[
                "-n",
                &host.namespace,
                "addr",
                "add",
                &format!("{}/24", host.address),
                "dev",
                &host.interface,
            ]);
            host.set_link(true);
        }
        hosts
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        // Deleting a namespace deletes its end of the veth, and the pair with it.
        for host in [&self.a, &self.b] {
            let _ = Command::new("ip")
                .args(["netns", "delete", &host.namespace])
                .output();
        }
    }
}
