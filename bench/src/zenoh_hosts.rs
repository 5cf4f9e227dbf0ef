//! The processes of `simbus-bench zenoh`: a host (an iceoryx2 root, and
//! a network namespace or none), a server with its exporting bridge and a
//! mirror on another host, and the measuring client's samples.

use std::time::{Duration, Instant};

use anyhow::Context as _;
use simbus_tests::{PrivateRoot, Proc};

use crate::stats::Latencies;

/// How a setup's processes run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Launch<'a> {
    /// Arguments added to the server's.
    pub server_args: &'a [&'a str],
    /// The bridges' `--poll-us`.
    pub poll_us: u64,
    /// With a directory, each process keeps the stamps of the ticks it
    /// serves and writes them on exit to `server`, `exporter` and
    /// `mirror` there.
    pub stamps: Option<&'a std::path::Path>,
}

/// A server with an exporting bridge, and a mirror (or none).
pub(crate) struct Setup {
    pub(crate) world: String,
    /// Runs a process on the server's host.
    pub(crate) server_host: Host,
    /// Runs a process on the mirror's host.
    pub(crate) mirror_host: Host,
    procs: Vec<Proc>,
}

/// Where a process runs: a root, and a network namespace or none.
#[derive(Clone, Default)]
pub(crate) struct Host {
    env: Vec<(String, std::ffi::OsString)>,
    namespace: Option<String>,
}

impl Host {
    pub(crate) fn of_root(root: &PrivateRoot, namespace: Option<&str>) -> Self {
        Self {
            env: root
                .env()
                .iter()
                .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                .collect(),
            namespace: namespace.map(str::to_owned),
        }
    }

    pub(crate) fn spawn(&self, program: &str, args: &[&str]) -> Proc {
        let env: Vec<(&str, &std::ffi::OsStr)> = self
            .env
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_os_str()))
            .collect();
        match &self.namespace {
            Some(ns) => Proc::spawn_wrapped(&["ip", "netns", "exec", ns], program, args, &env),
            None => Proc::spawn_env(program, args, &env),
        }
    }

    /// This host, with `key=value` added to its processes' environment.
    pub(crate) fn with_env(&self, key: &str, value: &std::path::Path) -> Self {
        let mut host = self.clone();
        host.env
            .push((key.to_owned(), value.as_os_str().to_owned()));
        host
    }

    /// Runs the measuring client here and parses its line.
    pub(crate) fn measure(&self, world: &str, args: &[&str]) -> anyhow::Result<serde_json::Value> {
        let mut all = vec!["zenoh-peer", "--world", world];
        all.extend_from_slice(args);
        let done = self
            .spawn("simbus-bench", &all)
            .finish(Duration::from_secs(600));
        anyhow::ensure!(done.status.success(), "{done}");
        let line = done.stdout.last().context("the peer printed nothing")?;
        Ok(serde_json::from_str(line)?)
    }
}

pub(crate) fn wait_line(proc: &Proc, needle: &str) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        if proc
            .line(Duration::from_millis(200))
            .is_some_and(|l| l.contains(needle))
        {
            return Ok(());
        }
    }
    anyhow::bail!("no '{needle}' line; stderr:\n{}", proc.stderr())
}

impl Setup {
    /// Server and exporter on `server_host`, a mirror on `mirror_host`
    /// (none when both are the same), run as `launch` says.
    pub(crate) fn start(
        tag: &str,
        server_host: Host,
        mirror_host: Option<Host>,
        address: &str,
        launch: Launch<'_>,
    ) -> anyhow::Result<Self> {
        let stamped = |host: &Host, name: &str| match launch.stamps {
            Some(dir) => host.with_env(simbus_transport::stamps::SIMBUS_STAMPS, &dir.join(name)),
            None => host.clone(),
        };
        static PORTS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = PORTS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let world = format!("bench-zenoh-{tag}-{}", std::process::id());
        let endpoint = format!(
            "tcp/{address}:{}",
            17_000 + (std::process::id() % 1000) * 20 + n
        );
        let mut args = vec!["--world", &world, "--sync", "--delta-seconds", "0.01"];
        args.extend_from_slice(launch.server_args);
        let poll_us = launch.poll_us.to_string();
        let server = stamped(&server_host, "server").spawn("sim-server", &args);
        let bridge = |host: &Host, flag: &str| {
            host.spawn(
                "sim-client",
                &[
                    "--world",
                    &world,
                    "--timeout",
                    "30",
                    "bridge",
                    "zenoh",
                    flag,
                    &endpoint,
                    "--poll-us",
                    &poll_us,
                ],
            )
        };
        let exporter = bridge(&stamped(&server_host, "exporter"), "--listen");
        wait_line(&exporter, "exporting world")?;
        let mut procs = vec![server, exporter];
        if let Some(host) = &mirror_host {
            let mirror = bridge(&stamped(host, "mirror"), "--connect");
            wait_line(&mirror, "mirroring world")?;
            procs.push(mirror);
        }
        Ok(Self {
            world,
            mirror_host: mirror_host.unwrap_or_else(|| server_host.clone()),
            server_host,
            procs,
        })
    }

    /// Interrupts the mirror, the exporter and the server, in that order,
    /// and waits for each to exit (so each writes its stamps).
    pub(crate) fn stop(mut self) -> anyhow::Result<()> {
        while let Some(proc) = self.procs.pop() {
            simbus_process::send_signal(proc.pid(), libc::SIGINT)?;
            let done = proc.finish(Duration::from_secs(20));
            anyhow::ensure!(done.status.success(), "{done}");
        }
        Ok(())
    }
}

pub(crate) fn latencies(json: &serde_json::Value, key: &str) -> Latencies {
    let mut latencies = Latencies::new();
    add_latencies(json, key, &mut latencies);
    latencies
}

/// Records the samples (ns) of the peer's `key` in `latencies`.
pub(crate) fn add_latencies(json: &serde_json::Value, key: &str, latencies: &mut Latencies) {
    for sample in json[key].as_array().into_iter().flatten() {
        latencies.record(sample.as_u64().unwrap_or(0));
    }
}
