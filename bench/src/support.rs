//! Starting a server in its own process for a benchmark.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use shared_types::WorldSettings;
use sim_client::{Client, Ticker, WaitMode};
use simbus_process::ChildGuard;

/// Wall-clock nanoseconds (what `platform_timestamp` is measured in).
pub(crate) fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Claims the ticker of `client`'s world in synchronous mode, fixed step `dt`.
pub(crate) fn sync_ticker(client: &Client, dt: f64) -> anyhow::Result<Ticker> {
    let mut ticker = client.claim_ticker()?;
    ticker.apply_settings(WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(dt),
        ..client.get_settings()?
    })?;
    Ok(ticker)
}

/// A client of `world` and its ticker, both waiting as `mode` says, the
/// world in synchronous mode with a 0.01 s step and the frames from before
/// drained.
pub(crate) fn ticking_client(world: &str, mode: WaitMode) -> anyhow::Result<(Client, Ticker)> {
    let mut client = Client::connect(world, Duration::from_secs(10))?;
    client.set_wait_mode(mode);
    let mut ticker = sync_ticker(&client, 0.01)?;
    ticker.set_wait_mode(mode);
    // Drain the frames published before synchronous mode began.
    while client.wait_for_tick(Duration::from_millis(200)).is_ok() {}
    Ok((client, ticker))
}

/// The benchmarks' lidar: 64 channels x 1024 points, 100 m, +10° to −30°,
/// a whole turn every frame (no rotation rate), no noise.
pub(crate) fn lidar_64x1024() -> shared_types::Lidar {
    shared_types::Lidar {
        channels: 64,
        points: 1024,
        range: 100.0,
        upper_fov: 10.0,
        lower_fov: -30.0,
        rotation_hz: 0.0,
        noise: Default::default(),
    }
}

/// A binary of the workspace built beside this one (`target/<profile>/`),
/// or an error saying how to build it.
pub(crate) fn sibling(name: &str) -> anyhow::Result<std::path::PathBuf> {
    let exe = std::env::current_exe()?;
    let path = exe
        .parent()
        .context("the benchmark's directory")?
        .join(name);
    anyhow::ensure!(
        path.exists(),
        "{} is missing: build it with `cargo build --release` first",
        path.display()
    );
    Ok(path)
}

/// A `sim-server` child process (the real binary), stopped on drop.
pub(crate) struct BenchServer {
    pub world: String,
    _guard: ChildGuard,
}

impl BenchServer {
    /// The server's process id.
    pub(crate) fn pid(&self) -> u32 {
        self._guard.id()
    }

    /// Starts `sim-server --world <unique> <args>` and waits until it answers.
    pub(crate) fn start(tag: &str, args: &[&str]) -> anyhow::Result<Self> {
        Self::start_with_env(tag, args, &[])
    }

    /// [`BenchServer::start`] with `env` added to the server's environment.
    pub(crate) fn start_with_env(
        tag: &str,
        args: &[&str],
        env: &[(&str, &std::ffi::OsStr)],
    ) -> anyhow::Result<Self> {
        let world = format!("bench-{tag}-{}", std::process::id());
        let child = Command::new(sibling("sim-server")?)
            .args(["--world", &world])
            .args(args)
            .envs(env.iter().copied())
            .env("RUST_LOG", "error")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .spawn()
            .context("starting the benchmark server")?;
        let guard = ChildGuard::new(child, Duration::from_secs(5));
        Client::connect(&world, Duration::from_secs(20)).context("benchmark server")?;
        Ok(Self {
            world,
            _guard: guard,
        })
    }

    /// `sim-server --resume <journal>` for `world` (killed before), once it
    /// answers.
    pub(crate) fn resume(world: &str, journal: &str) -> anyhow::Result<Self> {
        let child = Command::new(sibling("sim-server")?)
            .args(["--resume", journal])
            .env("RUST_LOG", "error")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .spawn()
            .context("resuming the benchmark server")?;
        let guard = ChildGuard::new(child, Duration::from_secs(5));
        Client::connect(world, Duration::from_secs(60)).context("resumed benchmark server")?;
        Ok(Self {
            world: world.to_owned(),
            _guard: guard,
        })
    }

    /// Kills the server (SIGKILL: a crash) and reaps it.
    pub(crate) fn kill(mut self) -> anyhow::Result<()> {
        self._guard.kill()?;
        Ok(())
    }

    /// Stops the server (SIGTERM) and waits until it has exited.
    pub(crate) fn stop(mut self) -> anyhow::Result<()> {
        let status = self._guard.stop()?;
        anyhow::ensure!(status.success(), "the benchmark server ended with {status}");
        Ok(())
    }
}

/// Where a benchmark's processes run: all on one CPU, the benchmark and
/// its peers on two different CPUs, or wherever the scheduler puts them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Placement {
    /// Every process on CPU 0.
    Same,
    /// The measuring process on CPU 0, its peers (the server) on CPU 1.
    Split,
    /// No pinning.
    Unpinned,
}

impl Placement {
    /// The placements `all` stands for, in the order they are measured.
    pub(crate) const ALL: [Placement; 3] = [Placement::Same, Placement::Split, Placement::Unpinned];

    /// The placement's name in tables.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Placement::Same => "same CPU",
            Placement::Split => "two CPUs",
            Placement::Unpinned => "unpinned",
        }
    }

    /// Pins this process (every thread) and `peers` (every thread of
    /// each) as the placement says; unpinned undoes earlier pinning.
    pub(crate) fn apply(self, peers: &[u32]) -> anyhow::Result<()> {
        let all: Vec<usize> = (0..cpus_online()).collect();
        let (mine, theirs) = match self {
            Placement::Same => (vec![0], vec![0]),
            Placement::Split => {
                anyhow::ensure!(all.len() >= 2, "--placement split needs two CPUs");
                (vec![0], vec![1])
            }
            Placement::Unpinned => (all.clone(), all),
        };
        pin(std::process::id(), &mine)?;
        for &peer in peers {
            pin(peer, &theirs)?;
        }
        Ok(())
    }
}

/// CPUs this machine has online (not what this process may use: the
/// placement changes that).
pub(crate) fn cpus_online() -> usize {
    // SAFETY: sysconf reads a value and has no preconditions.
    let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
    usize::try_from(online).unwrap_or(1).max(1)
}

/// Sets the CPU affinity of every thread of process `pid`.
fn pin(pid: u32, cpus: &[usize]) -> anyhow::Result<()> {
    // SAFETY: cpu_set_t is plain data; zeroed is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &cpu in cpus {
        // SAFETY: `set` is a valid cpu_set_t and `cpu` is below CPU_SETSIZE.
        unsafe { libc::CPU_SET(cpu, &mut set) };
    }
    for task in std::fs::read_dir(format!("/proc/{pid}/task"))? {
        let Some(tid) = task?
            .file_name()
            .to_str()
            .and_then(|t| t.parse::<i32>().ok())
        else {
            continue;
        };
        // SAFETY: `set` outlives the call; the size is its own.
        let rc = unsafe { libc::sched_setaffinity(tid, std::mem::size_of_val(&set), &set) };
        anyhow::ensure!(
            rc == 0,
            "pinning thread {tid} of {pid}: {}",
            std::io::Error::last_os_error()
        );
    }
    Ok(())
}

/// Voluntary context switches (sleeps) of every thread of `pid` so far.
pub(crate) fn sleeps(pid: u32) -> u64 {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return 0;
    };
    tasks
        .filter_map(|t| t.ok())
        .filter_map(|t| std::fs::read_to_string(t.path().join("status")).ok())
        .filter_map(|status| {
            status
                .lines()
                .find_map(|l| l.strip_prefix("voluntary_ctxt_switches:"))
                .and_then(|v| v.trim().parse::<u64>().ok())
        })
        .sum()
}

/// The three load averages, as `/proc/loadavg` gives them.
pub(crate) fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

/// Busy and total jiffies of all cores, from `/proc/stat`.
fn cpu_jiffies() -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let fields: Vec<u64> = stat
        .lines()
        .next()?
        .split_whitespace()
        .skip(1)
        .filter_map(|f| f.parse().ok())
        .collect();
    let total: u64 = fields.iter().sum();
    // idle + iowait are the 4th and 5th fields.
    let idle = fields.get(3).copied().unwrap_or(0) + fields.get(4).copied().unwrap_or(0);
    Some((total - idle, total))
}

/// How busy the cores are with other work, sampled over `window` before a
/// benchmark starts: blocking wake-ups are slow on idle cores (a halted
/// virtual CPU) and fast on busy ones, so every blocking figure says which.
pub(crate) fn machine_state(window: Duration) -> String {
    let before = cpu_jiffies();
    std::thread::sleep(window);
    match (before, cpu_jiffies()) {
        (Some((b0, t0)), Some((b1, t1))) if t1 > t0 => {
            let busy = (b1 - b0) as f64 / (t1 - t0) as f64;
            let word = if busy < 0.15 { "idle" } else { "busy" };
            format!(
                "{word}: cores {:.0}% busy over the {:.1} s before the run, load average {}",
                busy * 100.0,
                window.as_secs_f64(),
                load_average()
            )
        }
        _ => format!("unknown: load average {}", load_average()),
    }
}

/// `n` processes spinning at the lowest priority for as long as this lives:
/// "the machine busy with other work".
pub(crate) struct BackgroundLoad {
    _burners: Vec<ChildGuard>,
}

impl BackgroundLoad {
    pub(crate) fn start(n: usize) -> anyhow::Result<Self> {
        let burners = (0..n)
            .map(|_| {
                let child = Command::new(std::env::current_exe()?)
                    .args(["peer", "--kind", "burn"])
                    .stdin(Stdio::null())
                    .stdout(Stdio::null())
                    .spawn()
                    .context("starting a background load process")?;
                Ok(ChildGuard::new(child, Duration::from_secs(1)))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self { _burners: burners })
    }
}

/// The `burn` peer: spins at nice 19 until it is killed.
pub(crate) fn burn() -> anyhow::Result<()> {
    // SAFETY: setpriority only changes this process's scheduling priority.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 19);
    }
    let mut x = 0u64;
    loop {
        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
    }
}

/// Starts this binary's hidden `peer --kind KIND --name NAME` and reads
/// its first line (its port, or "ready").
pub(crate) fn spawn_peer(kind: &str, name: &str) -> anyhow::Result<(ChildGuard, String)> {
    let mut child = Command::new(std::env::current_exe()?)
        .args(["peer", "--kind", kind, "--name", name])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("starting the benchmark peer")?;
    let stdout = child.stdout.take().context("peer stdout")?;
    let guard = ChildGuard::new(child, Duration::from_secs(2));
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line)?;
    Ok((guard, line.trim().to_owned()))
}

/// Seconds per frame of `frames` ticks (each tick waits for its frame).
pub(crate) fn ticked(client: &Client, frames: u64) -> anyhow::Result<f64> {
    let mut ticker = client.claim_ticker()?;
    let started = Instant::now();
    for _ in 0..frames {
        ticker.tick(Duration::from_secs(60))?;
    }
    let seconds = started.elapsed().as_secs_f64() / frames as f64;
    ticker.release()?;
    Ok(seconds)
}

/// The empty scene's world and the plan of one 0.01 s frame (one substep):
/// what a raw peer steps to stand for the simbus rows' server.
pub(crate) fn empty_world() -> (sim_server::world::World, sim_server::clock::SubstepPlan) {
    use sim_server::{clock::SubstepPlan, world::World, Scene};
    let world = World::new(&Scene::Empty.placements(0), 1);
    let settings = shared_types::WorldSettings {
        fixed_delta_seconds: Some(0.01),
        ..Default::default()
    };
    (world, SubstepPlan::new(10_000_000, &settings))
}
