//! `simbus-bench carla`: CARLA 0.9.16's own Python client through
//! `sim-client carla-gateway`, next to the native client, in one run: the
//! `world.tick()` round trip, `wait_for_tick` latency (publish → returned),
//! 640x480 depth and 800x600 RGB frames per second through
//! `camera.listen`, and the traffic manager driving 30 and 100 vehicles
//! (and 100 vehicles with 100 AI walkers) on simbus's town, the gateway's
//! native one beside CARLA's own (in the script's process), with the time
//! of `get_map()` + `generate_waypoints`.

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Args;
use shared_types::{Radar, SensorKind, SensorSpec};
use sim_client::{Client, Ticker};
use simbus_process::ChildGuard;

use crate::carla_traffic::{traffic, Traffic, TrafficRow};
use crate::stats::{header, Latencies};
use crate::support::{now_ns, sync_ticker, BenchServer};

/// The CARLA client's side, run with the venv's Python.
pub(crate) const SCRIPT: &str = include_str!("carla_bench.py");
/// The client library the gateway speaks to.
const CARLA: &str = "carla==0.9.16";

#[derive(Debug, Args)]
pub(crate) struct CarlaArgs {
    /// Tick round trips and frames waited for, per row.
    #[arg(long, default_value_t = 2000)]
    ticks: usize,
    /// Depth frames per row.
    #[arg(long, default_value_t = 100)]
    frames: usize,
    /// A Python with `carla==0.9.16` [default: the test suite's venv
    /// (target/simbus-venv), else one made here in target/simbus-bench-venv].
    #[arg(long)]
    python: Option<PathBuf>,
    /// Ticks timed per traffic-manager row.
    #[arg(long, default_value_t = 500)]
    pub(crate) traffic_ticks: usize,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: CarlaArgs) -> anyhow::Result<()> {
    let sim_client = crate::support::sibling("sim-client")?;
    let bin = sim_client.parent().context("the benchmark's directory")?;
    let python = match args.python.clone() {
        Some(python) => python,
        None => venv(bin)?,
    };
    let script = std::env::temp_dir().join(format!("simbus-carla-bench-{}.py", std::process::id()));
    std::fs::write(&script, SCRIPT)?;
    let result = measure(&args, &sim_client, &python, &script);
    let _ = std::fs::remove_file(&script);
    result
}

/// The venv: the test suite's if it has `carla`, else one of our own.
fn venv(bin: &Path) -> anyhow::Result<PathBuf> {
    let target = bin.parent().context("the target directory")?;
    for dir in ["simbus-venv", "simbus-bench-venv"] {
        let python = target.join(dir).join("bin").join("python");
        let has_carla = Command::new(&python)
            .args(["-c", "import carla"])
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if has_carla {
            return Ok(python);
        }
    }
    let venv = target.join("simbus-bench-venv");
    eprintln!("creating {} with {CARLA}", venv.display());
    let made = Command::new("python3")
        .arg("-m")
        .arg("venv")
        .arg(&venv)
        .status()?;
    let python = venv.join("bin").join("python");
    let installed = made.success()
        && Command::new(&python)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
                CARLA,
            ])
            .status()?
            .success();
    if !installed {
        bail!("could not install {CARLA} into {}", venv.display());
    }
    Ok(python)
}

/// A free TCP port on loopback.
pub(crate) fn free_port() -> anyhow::Result<u16> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// A Python side: `script` run with the venv's `python` against `target`
/// (the CARLA client: the gateway's port; simbus's package: the world).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ScriptSide<'a> {
    pub(crate) python: &'a Path,
    pub(crate) script: &'a Path,
    pub(crate) target: &'a str,
}

/// Runs `side`'s script as `script MODE TARGET ARGS..` and returns its
/// JSON answer (its last line); `started` runs while it works (with a
/// channel that yields its output lines).
pub(crate) fn script_side(
    side: ScriptSide<'_>,
    mode: &str,
    args: &[&str],
    started: impl FnOnce(&mpsc::Receiver<String>) -> anyhow::Result<()>,
) -> anyhow::Result<serde_json::Value> {
    let ScriptSide {
        python,
        script,
        target,
    } = side;
    let mut child = Command::new(python)
        .arg(script)
        .args([mode, target])
        .args(args)
        .stdout(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .with_context(|| format!("running {}", python.display()))?;
    let stdout = child.stdout.take().context("the script's output")?;
    let mut guard = ChildGuard::new(child, Duration::from_secs(2));
    let (lines, output) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    started(&output)?;
    let mut last = None;
    while let Ok(line) = output.recv_timeout(Duration::from_secs(600)) {
        last = Some(line);
    }
    let status = guard.wait_timeout(Duration::from_secs(10))?;
    if !status.is_some_and(|s| s.success()) {
        bail!(
            "the {mode} run of {} failed (its error is above)",
            script.display()
        );
    }
    let last = last.with_context(|| format!("{} printed nothing", script.display()))?;
    Ok(serde_json::from_str(&last)?)
}

/// The nanosecond samples under `key` of a script's answer.
pub(crate) fn latencies(answer: &serde_json::Value, key: &str) -> anyhow::Result<Latencies> {
    let mut l = Latencies::new();
    for v in answer[key].as_array().context("no samples")? {
        l.record(v.as_u64().unwrap_or(0));
    }
    Ok(l)
}

/// Starts `sim-client carla-gateway` for `world` on `port` (and its
/// sensor streams on `streams`), with `extra` flags, once it says it
/// listens.
pub(crate) fn start_gateway(
    sim_client: &Path,
    world: &str,
    port: u16,
    streams: u16,
    extra: &[&str],
) -> anyhow::Result<ChildGuard> {
    let mut child: Child = Command::new(sim_client)
        .args(["--world", world, "--timeout", "30", "carla-gateway"])
        .args([
            "--port",
            &port.to_string(),
            "--streaming-port",
            &streams.to_string(),
        ])
        .args(extra)
        .env("RUST_LOG", "error")
        .stdout(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .context("starting the gateway")?;
    let stdout = child.stdout.take().context("the gateway's output")?;
    let guard = ChildGuard::new(child, Duration::from_secs(2));
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line)?;
    if !line.starts_with("carla-gateway:") {
        bail!("the gateway did not start: {line}");
    }
    Ok(guard)
}

/// A server of `scene` and a gateway in front of it with `extra` flags
/// (both stopped when dropped), and the gateway's RPC port.
pub(crate) fn gateway_on(
    name: &str,
    scene: &str,
    sim_client: &Path,
    extra: &[&str],
) -> anyhow::Result<(BenchServer, ChildGuard, String)> {
    let server = BenchServer::start(name, &["--scene", scene])?;
    let (port, streams) = (free_port()?, free_port()?);
    let gateway = start_gateway(sim_client, &server.world, port, streams, extra)?;
    Ok((server, gateway, port.to_string()))
}

/// What one run measured.
struct Measured {
    /// /proc/loadavg before the run.
    load: String,
    native_tick: Latencies,
    carla_tick: Latencies,
    /// CARLA's bare version RPC: the floor under its tick.
    carla_rpc: Latencies,
    native_wait: Latencies,
    carla_wait: Latencies,
    /// Each sensor's frames per second, natively and through `listen`.
    listen: Vec<(ListenCase, f64, f64)>,
    traffic: Traffic,
}

fn measure(
    args: &CarlaArgs,
    sim_client: &Path,
    python: &Path,
    script: &Path,
) -> anyhow::Result<()> {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let (server, _gateway, port) = gateway_on("carla", "empty", sim_client, &[])?;
    let carla = ScriptSide {
        python,
        script,
        target: &port,
    };
    let timeout = Duration::from_secs(30);
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let (native_tick, carla_tick, carla_rpc) =
        tick_round_trips(args.ticks, &client, carla, timeout)?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let (native_wait, carla_wait) =
        wait_for_tick(args.ticks, &server.world, &mut ticker, carla, timeout)?;
    ticker.release()?;
    let listen = ListenCase::all()
        .into_iter()
        .map(|case| {
            let (native, carla) = sensor_fps(args.frames, &client, carla, &case)?;
            Ok((case, native, carla))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let traffic = traffic(args, sim_client, python, script)?;
    report(
        args,
        &Measured {
            load,
            native_tick,
            carla_tick,
            carla_rpc,
            native_wait,
            carla_wait,
            listen,
            traffic,
        },
    );
    Ok(())
}

/// Tick round trip, `ticks` of each: native, then the CARLA client (and
/// its bare RPC).
pub(crate) fn tick_round_trips(
    ticks: usize,
    client: &Client,
    carla: ScriptSide<'_>,
    timeout: Duration,
) -> anyhow::Result<(Latencies, Latencies, Latencies)> {
    let native_tick = native_ticks(client, ticks, sim_client::WaitMode::Block, timeout)?;
    let answer = script_side(carla, "tick", &[&ticks.to_string()], |_| Ok(()))?;
    let carla_tick = latencies(&answer, "ns")?;
    let carla_rpc = latencies(&answer, "floor_ns")?;
    Ok((native_tick, carla_tick, carla_rpc))
}

/// `ticks` tick round trips of the native client waiting as `mode` says
/// (after a tenth as many to warm up).
pub(crate) fn native_ticks(
    client: &Client,
    ticks: usize,
    mode: sim_client::WaitMode,
    timeout: Duration,
) -> anyhow::Result<Latencies> {
    let mut ticker = sync_ticker(client, 0.01)?;
    ticker.set_wait_mode(mode);
    let mut native_tick = Latencies::new();
    native_tick.time(ticks as u64, || {
        ticker.tick(timeout)?;
        Ok(())
    })?;
    ticker.release()?;
    Ok(native_tick)
}

/// wait_for_tick: `ticker` steps every 2 ms; a native waiter and `side`
/// (the CARLA client, or any script whose `wait` mode says "ready" once it
/// saw a frame) measure publish -> returned for the same `ticks` frames.
pub(crate) fn wait_for_tick(
    ticks: usize,
    world: &str,
    ticker: &mut Ticker,
    side: ScriptSide<'_>,
    timeout: Duration,
) -> anyhow::Result<(Latencies, Latencies)> {
    let world = world.to_owned();
    let samples = ticks;
    let native_waiter = std::thread::spawn(move || -> anyhow::Result<Latencies> {
        let mut client = Client::connect(&world, Duration::from_secs(10))?;
        let mut l = Latencies::new();
        client.wait_for_tick(Duration::from_secs(30))?;
        while (l.len() as usize) < samples {
            let snapshot = client.wait_for_tick(Duration::from_secs(30))?;
            let published = (snapshot.timestamp().platform_timestamp * 1e9) as u64;
            l.record(now_ns().saturating_sub(published));
        }
        Ok(l)
    });
    let side_wait = script_side(side, "wait", &[&ticks.to_string()], |lines| {
        // Tick until the client saw a frame and said so, then on.
        loop {
            ticker.tick(timeout)?;
            if lines.try_recv().is_ok_and(|l| l == "ready") {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        for _ in 0..ticks + ticks / 2 {
            ticker.tick(timeout)?;
            std::thread::sleep(Duration::from_millis(2));
        }
        Ok(())
    })?;
    let side_wait = latencies(&side_wait, "ns")?;
    let native_wait = native_waiter
        .join()
        .map_err(|_| anyhow::anyhow!("the native waiter panicked"))??;
    Ok((native_wait, side_wait))
}

/// A sensor measured natively and through CARLA's `listen`: its native
/// spec and its CARLA blueprint with the attributes that make the same
/// sensor.
pub(crate) struct ListenCase {
    /// What it is, as the report names it.
    pub(crate) label: &'static str,
    /// The report's JSON key.
    key: &'static str,
    spec: SensorSpec,
    blueprint: &'static str,
    attributes: &'static [&'static str],
}

impl ListenCase {
    /// A depth camera of 640x480.
    pub(crate) fn depth() -> Self {
        let spec =
            SensorSpec::camera_of(SensorKind::Depth, [0.0, 2.0, 0.0], (640, 480), 90.0, 1000.0)
                .expect("a camera kind");
        Self {
            label: "depth 640x480",
            key: "depth_640x480_fps",
            spec,
            blueprint: "sensor.camera.depth",
            attributes: &["image_size_x=640", "image_size_y=480"],
        }
    }

    /// Every sensor the report has: depth and RGB cameras, a semantic
    /// lidar of 64 channels x 1024 points (a whole turn every 0.01 s
    /// frame), a radar of 1500 points/s.
    fn all() -> Vec<Self> {
        let rgb = SensorSpec::camera_of(SensorKind::Rgb, [0.0, 2.0, 0.0], (800, 600), 90.0, 1000.0)
            .expect("a camera kind");
        let lidar = crate::support::lidar_64x1024();
        vec![
            Self::depth(),
            Self {
                label: "rgb 800x600",
                key: "rgb_800x600_fps",
                spec: rgb,
                blueprint: "sensor.camera.rgb",
                attributes: &["image_size_x=800", "image_size_y=600"],
            },
            Self {
                label: "semantic lidar 64x1024",
                key: "semantic_lidar_64x1024_fps",
                spec: SensorSpec::semantic_lidar([0.0, 2.0, 0.0], lidar),
                blueprint: "sensor.lidar.ray_cast_semantic",
                // 64 x 1024 points a turn, a turn every 0.01 s.
                attributes: &[
                    "channels=64",
                    "points_per_second=6553600",
                    "rotation_frequency=100",
                    "range=100",
                    "upper_fov=10",
                    "lower_fov=-30",
                ],
            },
            Self {
                label: "radar 1500 points/s",
                key: "radar_1500_fps",
                spec: SensorSpec::with_params([0.0, 2.0, 0.0], Radar::default()),
                blueprint: "sensor.other.radar",
                attributes: &[],
            },
        ]
    }
}

/// A sensor's frames per second, `frames` of each: a native subscriber
/// ticking (the ticker released before the script's turn), then `listen`
/// on the CARLA client.
pub(crate) fn sensor_fps(
    frames: usize,
    client: &Client,
    carla: ScriptSide<'_>,
    case: &ListenCase,
) -> anyhow::Result<(f64, f64)> {
    let timeout = Duration::from_secs(30);
    let mut ticker = sync_ticker(client, 0.01)?;
    let mut sensor = client.spawn_sensor(case.spec)?;
    for _ in 0..5 {
        ticker.tick(timeout)?;
        sensor.recv(timeout)?;
    }
    let start = Instant::now();
    for _ in 0..frames {
        let frame = ticker.tick(timeout)?;
        let capture = sensor.recv(timeout)?;
        anyhow::ensure!(
            capture.header().frame == frame,
            "a capture of another frame"
        );
    }
    let native_fps = frames as f64 / start.elapsed().as_secs_f64();
    client.destroy_sensor(sensor.id())?;
    ticker.release()?;
    let mut args = vec![frames.to_string(), case.blueprint.to_string()];
    args.extend(case.attributes.iter().map(|a| a.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let answer = script_side(carla, "sensor", &args, |_| Ok(()))?;
    let carla_fps = answer["fps"].as_f64().context("no fps")?;
    Ok((native_fps, carla_fps))
}

/// Prints the table (or, with --json, one object).
fn report(args: &CarlaArgs, m: &Measured) {
    let Measured {
        load,
        native_tick,
        carla_tick,
        carla_rpc,
        native_wait,
        carla_wait,
        listen,
        traffic,
    } = m;
    let map_ms = traffic.map.quantile_us(0.5) / 1e3;
    let p50 = |l: &Latencies| l.quantile_us(0.5);
    if args.json {
        let listen_json: serde_json::Map<String, serde_json::Value> = listen
            .iter()
            .map(|(case, native, carla)| {
                let row = serde_json::json!({"native": native, "carla": carla,
                    "native_over_carla": native / carla});
                (case.key.to_string(), row)
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "load_before": load.trim(),
                "tick_round_trip": {"native": native_tick.json(), "carla": carla_tick.json(),
                    "carla_over_native_p50": p50(carla_tick) / p50(native_tick),
                    "carla_version_rpc": carla_rpc.json(),
                    "carla_over_version_rpc_p50": p50(carla_tick) / p50(carla_rpc)},
                "wait_for_tick": {"native": native_wait.json(), "carla": carla_wait.json(),
                    "carla_over_native_p50": p50(carla_wait) / p50(native_wait)},
                "listen": listen_json,
                "traffic_manager": traffic.rows.iter().map(TrafficRow::json).collect::<Vec<_>>(),
                "get_map_generate_waypoints_ms_p50": map_ms,
                "waypoints": traffic.waypoints,
            })
        );
        return;
    }
    println!(
        "CARLA 0.9.16's Python client through the gateway vs the native client, one run (load average before: {})",
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
    println!("{}", header("what"));
    println!("{}", native_tick.row("tick round trip, native"));
    println!("{}", carla_tick.row("tick round trip, CARLA"));
    println!("{}", carla_rpc.row("version RPC, CARLA (floor)"));
    println!("{}", native_wait.row("wait_for_tick, native"));
    println!("{}", carla_wait.row("wait_for_tick, CARLA"));
    println!(
        "CARLA/native p50: tick {:.1}x, wait_for_tick {:.1}x; CARLA tick / CARLA's bare RPC: {:.2}x",
        p50(carla_tick) / p50(native_tick),
        p50(carla_wait) / p50(native_wait),
        p50(carla_tick) / p50(carla_rpc)
    );
    for (case, native, carla) in listen {
        println!(
            "{}, tick + its capture each frame: native {native:.1} fps, CARLA listen {carla:.1} fps ({:.2}x)",
            case.label,
            native / carla
        );
    }
    println!(
        "Traffic managers on the town, synchronous, 0.05 s steps, ticks through CARLA's client:"
    );
    for row in &traffic.rows {
        println!("  {}", row.line());
    }
    println!(
        "get_map() + generate_waypoints(2.0) on the town: {map_ms:.0} ms (p50 of 5; {} waypoints)",
        traffic.waypoints
    );
}
