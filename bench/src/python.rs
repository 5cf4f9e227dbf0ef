//! `simbus-bench python`: simbus's own Python package (`sim-client/python`,
//! built here as a release wheel and installed into a venv) next to the
//! Rust client and to CARLA's client through `sim-client carla-gateway`,
//! in one run against one server: the tick round trip, wait_for_frame
//! latency (publish -> returned), an 8 B and an 8 MiB depth capture to a
//! numpy array (tick returned -> array in hand), and 640x480 depth frames
//! per second with a tick each.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context};
use clap::Args;
use shared_types::SensorSpec;
use sim_client::{Client, Ticker};

use crate::carla::{self, latencies, script_side, ScriptSide};
use crate::stats::{header, Latencies};
use crate::support::{cpus_online, load_average, sibling, sync_ticker, BenchServer, Placement};

/// The package's side, run with the venv's Python.
const SCRIPT: &str = include_str!("python_bench.py");
/// The package's manifest, from the repository's root.
const MANIFEST: &str = "sim-client/python/Cargo.toml";
/// The test suite's exact pins, from the repository's root.
const REQUIREMENTS: &str = "tests/python/requirements.txt";
/// What the venv needs from those pins: CARLA's client, numpy, maturin.
const PACKAGES: [&str; 3] = ["carla", "numpy", "maturin"];
/// The capture sizes: depth images, 4 bytes a pixel.
const CAPTURES: [(&str, u32, u32); 2] = [("8 B", 2, 1), ("8 MiB", 2048, 1024)];

#[derive(Debug, Args)]
pub(crate) struct PythonArgs {
    /// Tick round trips and frames waited for, per row.
    #[arg(long, default_value_t = 2000)]
    ticks: usize,
    /// Depth 640x480 frames per row.
    #[arg(long, default_value_t = 1000)]
    frames: usize,
    /// Captures per size and row.
    #[arg(long, default_value_t = 500)]
    captures: usize,
    /// A Python with the pins of carla, numpy and maturin from
    /// tests/python/requirements.txt; simbus's wheel is installed into it
    /// [default: target/simbus-bench-venv, made and filled when missing].
    #[arg(long)]
    python: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: PythonArgs) -> anyhow::Result<()> {
    let root = repository()?;
    let sim_client = sibling("sim-client")?;
    let target = sim_client
        .parent()
        .and_then(Path::parent)
        .context("the target directory")?;
    let pins = pins(&root)?;
    let python = match args.python.clone() {
        Some(python) => {
            let missing = missing_pins(&python, &pins)?;
            ensure!(
                missing.is_empty(),
                "{} lacks {} (leave out --python to use a venv made here)",
                python.display(),
                missing.join(" ")
            );
            python
        }
        None => venv(&target.join("simbus-bench-venv"), &pins)?,
    };
    let work = std::env::temp_dir().join(format!("simbus-python-bench-{}", std::process::id()));
    std::fs::create_dir_all(&work)?;
    let lock = target.join("simbus-wheel.lock");
    let result = install_wheel(&root, &python, &lock, &work.join("wheel")).and_then(|()| {
        let scripts = [work.join("python_bench.py"), work.join("carla_bench.py")];
        std::fs::write(&scripts[0], SCRIPT)?;
        std::fs::write(&scripts[1], carla::SCRIPT)?;
        let measured = measure(&args, &sim_client, &python, &scripts)?;
        report(&args, &measured);
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&work);
    result
}

/// The checkout this benchmark was built from: above `target/<profile>/`
/// when it runs from there, else where it was compiled.
fn repository() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let beside = exe.ancestors().nth(3).map(Path::to_path_buf);
    let compiled = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf);
    beside
        .into_iter()
        .chain(compiled)
        .find(|root| root.join(MANIFEST).exists())
        .with_context(|| format!("no checkout with {MANIFEST} around {}", exe.display()))
}

/// The pins (`name==version`) of [`PACKAGES`] in the test suite's
/// requirements.
fn pins(root: &Path) -> anyhow::Result<Vec<String>> {
    let path = root.join(REQUIREMENTS);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    PACKAGES
        .iter()
        .map(|package| {
            text.lines()
                .map(str::trim)
                .find(|line| {
                    line.split_once("==")
                        .is_some_and(|(name, _)| name == *package)
                })
                .map(str::to_owned)
                .with_context(|| format!("{} pins no version of {package}", path.display()))
        })
        .collect()
}

/// The pins `python` does not have installed at their versions.
fn missing_pins(python: &Path, pins: &[String]) -> anyhow::Result<Vec<String>> {
    const CHECK: &str = "import importlib.metadata as m, sys\n\
        def has(pin):\n    name, version = pin.split('==')\n    try:\n        return m.version(name) == version\n    except m.PackageNotFoundError:\n        return False\n\
        print(' '.join(p for p in sys.argv[1:] if not has(p)))";
    let output = Command::new(python)
        .args(["-c", CHECK])
        .args(pins)
        .stderr(Stdio::inherit())
        .output()
        .with_context(|| format!("running {}", python.display()))?;
    ensure!(
        output.status.success(),
        "{} could not list its packages",
        python.display()
    );
    Ok(String::from_utf8_lossy(&output.stdout)
        .split_whitespace()
        .map(str::to_owned)
        .collect())
}

/// The venv at `dir` with `pins` installed: made when missing, filled when
/// a pin is.
fn venv(dir: &Path, pins: &[String]) -> anyhow::Result<PathBuf> {
    let python = dir.join("bin").join("python");
    if !python.exists() {
        eprintln!("creating {}", dir.display());
        let made = Command::new("python3")
            .args(["-m", "venv"])
            .arg(dir)
            .stdout(std::io::stderr())
            .status()
            .context("running python3 -m venv")?;
        ensure!(made.success(), "could not create {}", dir.display());
    }
    let missing = missing_pins(&python, pins)?;
    if !missing.is_empty() {
        eprintln!("installing {} into {}", missing.join(" "), dir.display());
        let installed = Command::new(&python)
            .args(["-m", "pip", "install", "--quiet"])
            .args(&missing)
            .stdout(std::io::stderr())
            .status()?;
        ensure!(
            installed.success(),
            "could not install {} into {}",
            missing.join(" "),
            dir.display()
        );
    }
    Ok(python)
}

/// Holds an exclusive `flock(2)` on a file while it lives.
struct Locked {
    _file: std::fs::File,
}

impl Locked {
    fn new(path: &Path) -> anyhow::Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(path)
            .with_context(|| format!("lock file {}", path.display()))?;
        // SAFETY: flock(2) on a file descriptor this process owns; closing
        // the file releases it.
        let locked = unsafe { libc::flock(std::os::fd::AsRawFd::as_raw_fd(&file), libc::LOCK_EX) };
        ensure!(
            locked == 0,
            "locking {}: {}",
            path.display(),
            std::io::Error::last_os_error()
        );
        Ok(Self { _file: file })
    }
}

/// Builds simbus's wheel from `root` (release) into `out` with `python`'s
/// maturin and installs it into `python`, replacing any older one. Holds
/// `lock` (the test suite's, `target/simbus-wheel.lock`) meanwhile: every
/// build of the package passes through `target/maturin/`.
fn install_wheel(root: &Path, python: &Path, lock: &Path, out: &Path) -> anyhow::Result<()> {
    let _lock = Locked::new(lock)?;
    eprintln!("building simbus's wheel (release) from {}", root.display());
    let built = Command::new(python)
        .args(["-m", "maturin", "build", "--release", "--quiet"])
        .arg("--manifest-path")
        .arg(root.join(MANIFEST))
        .arg("--out")
        .arg(out)
        .arg("--interpreter")
        .arg(python)
        .stdout(std::io::stderr())
        .status()
        .context("running maturin")?;
    ensure!(built.success(), "maturin could not build the wheel");
    let wheel = std::fs::read_dir(out)?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .find(|path| path.extension().is_some_and(|e| e == "whl"))
        .with_context(|| format!("maturin left no wheel in {}", out.display()))?;
    let installed = Command::new(python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--force-reinstall",
            "--no-deps",
        ])
        .arg(&wheel)
        .stdout(std::io::stderr())
        .status()?;
    ensure!(installed.success(), "could not install {}", wheel.display());
    Ok(())
}

/// Latencies of one row, per client.
struct Row {
    rust: Latencies,
    python: Latencies,
    carla: Latencies,
}

/// What one run measured.
struct Measured {
    /// The load average before the run.
    load: String,
    tick: Row,
    /// The tick round trip in the package's default wait mode (hybrid):
    /// Rust native, Python native.
    hybrid_tick: [Latencies; 2],
    /// CARLA's bare version RPC: the floor under its tick.
    carla_rpc: Latencies,
    wait: Row,
    /// Per size in [`CAPTURES`].
    captures: Vec<Row>,
    /// Depth 640x480 frames per second: Rust, Python, CARLA.
    fps: [f64; 3],
}

fn measure(
    args: &PythonArgs,
    sim_client: &Path,
    python: &Path,
    scripts: &[PathBuf; 2],
) -> anyhow::Result<Measured> {
    let load = load_average();
    let server = BenchServer::start("python", &["--scene", "empty"])?;
    let (port, streams) = (carla::free_port()?, carla::free_port()?);
    let _gateway = carla::start_gateway(sim_client, &server.world, port, streams, &[])?;
    let port = port.to_string();
    let package = ScriptSide {
        python,
        script: &scripts[0],
        target: &server.world,
    };
    let gateway = ScriptSide {
        python,
        script: &scripts[1],
        target: &port,
    };
    let timeout = Duration::from_secs(30);
    let client = Client::connect(&server.world, Duration::from_secs(10))?;

    // The tick rows under one placement (this process and the Python
    // side it starts on CPU 0, the server on CPU 1): unpinned, each row's
    // wake-ups cost what the scheduler's pick costs, not what the client
    // does (the performance chapter's "placement decides").
    let split = cpus_online() >= 2;
    if split {
        Placement::Split.apply(&[server.pid()])?;
    }
    let (rust_tick, carla_tick, carla_rpc) =
        carla::tick_round_trips(args.ticks, &client, gateway, timeout)?;
    let ticks = args.ticks.to_string();
    let python_tick = latencies(&script_side(package, "tick", &[&ticks], |_| Ok(()))?, "ns")?;
    let hybrid_tick = [
        carla::native_ticks(&client, args.ticks, sim_client::WaitMode::Hybrid, timeout)?,
        latencies(
            &script_side(package, "tick", &[&ticks, "hybrid"], |_| Ok(()))?,
            "ns",
        )?,
    ];

    if split {
        Placement::Unpinned.apply(&[server.pid()])?;
    }
    let mut ticker = sync_ticker(&client, 0.01)?;
    let (rust_wait, python_wait) =
        carla::wait_for_tick(args.ticks, &server.world, &mut ticker, package, timeout)?;
    let (_, carla_wait) =
        carla::wait_for_tick(args.ticks, &server.world, &mut ticker, gateway, timeout)?;

    let (captures, fps) = capture_rows(args, &client, ticker, [package, gateway], timeout)?;
    Ok(Measured {
        load,
        tick: Row {
            rust: rust_tick,
            python: python_tick,
            carla: carla_tick,
        },
        hybrid_tick,
        carla_rpc,
        wait: Row {
            rust: rust_wait,
            python: python_wait,
            carla: carla_wait,
        },
        captures,
        fps,
    })
}

/// The capture rows, per size in [`CAPTURES`], and depth 640x480 frames
/// per second (Rust, Python, CARLA): the Rust client first, ticking with
/// `ticker` (released after), then the `sides` (the package, the gateway).
fn capture_rows(
    args: &PythonArgs,
    client: &Client,
    mut ticker: Ticker,
    sides: [ScriptSide<'_>; 2],
    timeout: Duration,
) -> anyhow::Result<(Vec<Row>, [f64; 3])> {
    let [package, gateway] = sides;
    let rust_captures = CAPTURES
        .iter()
        .map(|&(_, width, height)| {
            rust_capture(client, &mut ticker, (width, height), args.captures, timeout)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    ticker.release()?;
    let (rust_fps, carla_fps) =
        carla::sensor_fps(args.frames, client, gateway, &carla::ListenCase::depth())?;

    let mut captures = Vec::new();
    let n = args.captures.to_string();
    for ((_, width, height), rust) in CAPTURES.into_iter().zip(rust_captures) {
        let size = [n.as_str(), &width.to_string(), &height.to_string()];
        let python = latencies(&script_side(package, "capture", &size, |_| Ok(()))?, "ns")?;
        let carla = latencies(&script_side(gateway, "capture", &size, |_| Ok(()))?, "ns")?;
        captures.push(Row {
            rust,
            python,
            carla,
        });
    }
    let frames = args.frames.to_string();
    let python_fps = script_side(package, "depth", &[&frames], |_| Ok(()))?["fps"]
        .as_f64()
        .context("no fps")?;
    Ok((captures, [rust_fps, python_fps, carla_fps]))
}

/// Tick returned -> a `width` x `height` depth capture in hand (its first
/// and last value read), `n` times after `n / 10` to warm up.
fn rust_capture(
    client: &Client,
    ticker: &mut Ticker,
    (width, height): (u32, u32),
    n: usize,
    timeout: Duration,
) -> anyhow::Result<Latencies> {
    let mut sensor = client.spawn_sensor(SensorSpec::depth(
        [0.0, 2.0, 0.0],
        width,
        height,
        90.0,
        100.0,
    ))?;
    let mut l = Latencies::new();
    for i in 0..n + n / 10 {
        let frame = ticker.tick(timeout)?;
        let start = Instant::now();
        let capture = sensor.recv(timeout)?;
        let depth = capture.depth().context("a depth capture without depth")?;
        std::hint::black_box((depth.first().copied(), depth.last().copied()));
        let elapsed = start.elapsed();
        if capture.header().frame != frame || depth.len() != (width * height) as usize {
            bail!(
                "asked for frame {frame}, {width}x{height}: got frame {} with {} values",
                capture.header().frame,
                depth.len()
            );
        }
        if i >= n / 10 {
            l.record(elapsed.as_nanos() as u64);
        }
    }
    client.destroy_sensor(sensor.id())?;
    Ok(l)
}

/// One goal of the issue: a ratio and the bound it must keep.
struct Goal {
    what: &'static str,
    value: f64,
    /// Whether the bound is an upper one (else a lower one).
    at_most: bool,
    bound: f64,
}

impl Goal {
    fn met(&self) -> bool {
        if self.at_most {
            self.value <= self.bound
        } else {
            self.value >= self.bound
        }
    }

    /// `<= 2x`, `>= 500x`.
    fn wanted(&self) -> String {
        format!("{} {}x", if self.at_most { "<=" } else { ">=" }, self.bound)
    }
}

fn goals(m: &Measured) -> [Goal; 5] {
    let p50 = |l: &Latencies| l.quantile_us(0.5);
    let [small, big] = [&m.captures[0], &m.captures[1]];
    [
        Goal {
            what: "Python / Rust tick p50, block",
            value: p50(&m.tick.python) / p50(&m.tick.rust),
            at_most: true,
            bound: 2.0,
        },
        Goal {
            what: "Python / Rust tick p50, hybrid",
            value: p50(&m.hybrid_tick[1]) / p50(&m.hybrid_tick[0]),
            at_most: true,
            bound: 2.0,
        },
        Goal {
            what: "Python 8 MiB / 8 B capture p50",
            value: p50(&big.python) / p50(&small.python),
            at_most: true,
            bound: 3.0,
        },
        Goal {
            what: "gateway / Python 8 MiB capture p50",
            value: p50(&big.carla) / p50(&big.python),
            at_most: false,
            bound: 500.0,
        },
        Goal {
            what: "Python / Rust depth 640x480 fps",
            value: m.fps[1] / m.fps[0],
            at_most: false,
            bound: 0.8,
        },
    ]
}

/// Prints the table (or, with --json, one object).
fn report(args: &PythonArgs, m: &Measured) {
    let goals = goals(m);
    if args.json {
        let row = |r: &Row| serde_json::json!({"rust": r.rust.json(), "python": r.python.json(), "carla": r.carla.json()});
        let captures: Vec<_> = CAPTURES
            .iter()
            .zip(&m.captures)
            .map(|((label, width, height), r)| {
                serde_json::json!({"size": label, "width": width, "height": height, "latency": row(r)})
            })
            .collect();
        let goals: Vec<_> = goals
            .iter()
            .map(|g| serde_json::json!({"what": g.what, "value": g.value, "goal": g.wanted(), "met": g.met()}))
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "load_before": m.load,
                "tick_round_trip": row(&m.tick),
                "tick_round_trip_hybrid": {"rust": m.hybrid_tick[0].json(), "python": m.hybrid_tick[1].json()},
                "carla_version_rpc": m.carla_rpc.json(),
                "wait_for_frame": row(&m.wait),
                "capture_to_numpy": captures,
                "depth_640x480_fps": {"rust": m.fps[0], "python": m.fps[1], "carla": m.fps[2]},
                "goals": goals,
            })
        );
        return;
    }
    println!(
        "simbus's Python package (release wheel) vs the Rust client and CARLA's client through the gateway, one run, one server, every wait blocking unless a row says; the tick rows with this process and the Python side on CPU 0, the server on CPU 1 (load average before: {})",
        m.load
    );
    let rows = |title: &str, r: &Row, carla: &str| {
        println!("{}", header(title));
        println!("{}", r.rust.row("  Rust native"));
        println!("{}", r.python.row("  Python native"));
        println!("{}", r.carla.row(carla));
    };
    rows("tick round trip", &m.tick, "  CARLA world.tick");
    println!("{}", m.carla_rpc.row("  CARLA version RPC (floor)"));
    println!("{}", header("tick round trip, hybrid"));
    println!("{}", m.hybrid_tick[0].row("  Rust native"));
    println!("{}", m.hybrid_tick[1].row("  Python native"));
    println!("  (both poll 100 µs, then sleep: the package's default wait mode)");
    rows("wait_for_frame", &m.wait, "  CARLA wait_for_tick");
    println!("  (frame published -> the wait returned; the ticker steps every 2 ms)");
    for ((label, width, height), r) in CAPTURES.iter().zip(&m.captures) {
        rows(
            &format!("{label} capture to numpy"),
            r,
            "  CARLA camera.listen",
        );
        println!("  (depth {width}x{height}: tick returned -> the array in hand)");
    }
    let [rust, python, carla] = m.fps;
    println!(
        "depth 640x480, tick + capture each frame: Rust native {rust:.1} fps, Python native {python:.1} fps, CARLA gateway {carla:.1} fps"
    );
    println!("goals:");
    for g in &goals {
        println!(
            "  {:<36} {:>9.2}x  (goal {}: {})",
            g.what,
            g.value,
            g.wanted(),
            if g.met() { "met" } else { "NOT met" }
        );
    }
}
