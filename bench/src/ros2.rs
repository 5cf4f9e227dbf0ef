//! `simbus-bench ros2`: `sim-client ros2` to a stock rclpy node (ROS 2
//! Kilted's wheels, Fast DDS), against rclpy → rclpy in the same run (the
//! DDS floor on this machine):
//!
//! - latency from a frame's publication (the tick's return) to the rclpy
//!   callback, for `/clock` and for an 800x600 RGB image, beside an rclpy
//!   publisher → subscriber pair of the same messages (stamped with the
//!   wall time they are published);
//! - `/clock` at full speed: ticks per second with a reliable rclpy reader,
//!   and how many frames it missed (none, the goal);
//! - four 800x600 cameras: frames per second ticked as fast as the world
//!   goes, and the share of images delivered, best effort (the default)
//!   and with `--lockstep` (reliable: a slow reader holds the world).

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Args;
use shared_types::{SensorKind, SensorSpec};
use sim_client::Client;
use simbus_process::ChildGuard;

use crate::stats::{header, Latencies};
use crate::support::{now_ns, sync_ticker, BenchServer};

/// The rclpy side.
const SCRIPT: &str = include_str!("ros2_bench.py");
/// Fast DDS's profile for the camera rows' reader: UDP on loopback with a
/// 4 MiB socket receive buffer (Linux's `net.core.rmem_max` here).
const FASTDDS_PROFILE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>udp_loopback</transport_id>
        <type>UDPv4</type>
        <receiveBufferSize>4194304</receiveBufferSize>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="simbus_bench" is_default_profile="true">
      <rtps>
        <useBuiltinTransports>false</useBuiltinTransports>
        <userTransports><transport_id>udp_loopback</transport_id></userTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"#;

#[derive(Debug, Args)]
pub(crate) struct Ros2Args {
    /// Messages timed per latency row.
    #[arg(long, default_value_t = 1000)]
    ticks: usize,
    /// Images timed per image row, and frames per camera row.
    #[arg(long, default_value_t = 200)]
    images: usize,
    /// A Python with rclpy [default: the test suite's venv,
    /// target/simbus-venv; `pip install -r tests/python/requirements.txt`].
    #[arg(long)]
    python: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// An rclpy process of the script, and its input (closed to end it).
struct Rclpy {
    guard: ChildGuard,
    stdin: Option<ChildStdin>,
    lines: std::io::Lines<BufReader<std::process::ChildStdout>>,
}

impl Rclpy {
    fn start(python: &Path, script: &Path, args: &[&str]) -> anyhow::Result<Self> {
        Self::start_with(python, script, args, None)
    }

    /// As [`Rclpy::start`], with Fast DDS's profile `profile` if given.
    fn start_with(
        python: &Path,
        script: &Path,
        args: &[&str],
        profile: Option<&Path>,
    ) -> anyhow::Result<Self> {
        let mut child: Child = Command::new(python)
            .envs(profile.map(|p| ("FASTDDS_DEFAULT_PROFILES_FILE", p)))
            .arg(script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("running {}", python.display()))?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().context("its output")?;
        Ok(Self {
            guard: ChildGuard::new(child, Duration::from_secs(2)),
            stdin,
            lines: BufReader::new(stdout).lines(),
        })
    }

    /// Waits for the line `said`.
    fn expect(&mut self, said: &str) -> anyhow::Result<()> {
        match self.lines.next() {
            Some(Ok(line)) if line == said => Ok(()),
            other => bail!("the rclpy side said {other:?}, not {said:?}"),
        }
    }

    /// Ends a subscriber: its samples, (topic index, stamp, wall ns).
    fn samples(mut self) -> anyhow::Result<Vec<(usize, u64, u64)>> {
        drop(self.stdin.take());
        let line = self.lines.next().context("the subscriber's samples")??;
        let answer: serde_json::Value = serde_json::from_str(&line)?;
        let samples = answer["samples"]
            .as_array()
            .context("no samples")?
            .iter()
            .filter_map(|s| {
                let s = s.as_array()?;
                Some((s[0].as_u64()? as usize, s[1].as_u64()?, s[2].as_u64()?))
            })
            .collect();
        let _ = self.guard.wait_timeout(Duration::from_secs(10));
        Ok(samples)
    }
}

/// One world with the adapter on it, its client and ticker.
struct World {
    _server: BenchServer,
    _adapter: Option<ChildGuard>,
    client: Client,
    ticker: sim_client::Ticker,
}

impl World {
    /// A world of `cameras` 800x600 cameras and, unless `adapter` is
    /// `None`, `sim-client ros2` on it (`Some(true)`: with `--lockstep`).
    fn start(
        domain: u16,
        cameras: usize,
        adapter: Option<bool>,
    ) -> anyhow::Result<(Self, Vec<u64>)> {
        let server = BenchServer::start("ros2", &["--scene", "empty"])?;
        let client = Client::connect(&server.world, Duration::from_secs(10))?;
        let ticker = sync_ticker(&client, 0.05)?;
        let mut ids = Vec::new();
        for i in 0..cameras {
            let at = [0.0, 1.5 + i as f32, 0.0];
            let spec = SensorSpec::camera_of(SensorKind::Rgb, at, (800, 600), 90.0, 1000.0)
                .context("a camera")?;
            ids.push(client.create_sensor(spec)?.id);
        }
        let Some(lockstep) = adapter else {
            return Ok((
                Self {
                    _server: server,
                    _adapter: None,
                    client,
                    ticker,
                },
                ids,
            ));
        };
        let sim_client = crate::support::sibling("sim-client")?;
        let domain = domain.to_string();
        let mut args = vec!["--world", server.world.as_str(), "ros2", "--json"];
        args.extend(["--domain-id", domain.as_str(), "--no-markers"]);
        if lockstep {
            args.push("--lockstep");
        }
        let mut child = Command::new(sim_client)
            .args(&args)
            .env("RUST_LOG", "error,rustdds=off,ros2_client=off")
            .stdout(Stdio::piped())
            .stdin(Stdio::null())
            .spawn()?;
        let stdout = child.stdout.take().context("the adapter's output")?;
        let adapter = ChildGuard::new(child, Duration::from_secs(2));
        let mut lines = BufReader::new(stdout).lines();
        let mut publishing = 0;
        while publishing < cameras || cameras == 0 {
            let line = lines.next().context("the adapter ended")??;
            if line.contains("\"publishing\"") {
                publishing += 1;
            }
            if cameras == 0 && line.contains("\"ready\"") {
                break;
            }
        }
        std::thread::spawn(move || lines.for_each(drop));
        Ok((
            Self {
                _server: server,
                _adapter: Some(adapter),
                client,
                ticker,
            },
            ids,
        ))
    }

    /// Ticks `n` frames, `gap` apart; each frame's time and the wall
    /// time its tick returned (the frame published).
    fn tick(&mut self, n: usize, gap: Duration) -> anyhow::Result<HashMap<u64, u64>> {
        let mut published = HashMap::new();
        for _ in 0..n {
            self.ticker.tick(Duration::from_secs(10))?;
            let at = now_ns();
            let frame = self.client.wait_for_tick(Duration::from_secs(10))?;
            published.insert(frame.timestamp().elapsed_ns, at);
            if !gap.is_zero() {
                std::thread::sleep(gap);
            }
        }
        Ok(published)
    }
}

/// The latencies of `samples` against when each stamp was published.
fn latencies(samples: &[(usize, u64, u64)], published: &HashMap<u64, u64>) -> Latencies {
    let mut l = Latencies::new();
    for &(_, stamp, got) in samples {
        if let Some(&at) = published.get(&stamp) {
            l.record(got.saturating_sub(at));
        }
    }
    l
}

/// The floor: rclpy to rclpy, `count` messages of `kind`, `period` apart
/// (both with Fast DDS's `profile`, if given).
fn floor(
    python: &Path,
    script: &Path,
    domain: u16,
    (kind, count, period): (&str, usize, f64),
    profile: Option<&Path>,
) -> anyhow::Result<Latencies> {
    let d = domain.to_string();
    let topic = format!("/bench_{kind}");
    let mut sub = Rclpy::start_with(python, script, &["sub", &d, kind, &topic], profile)?;
    let (count, period) = (count.to_string(), period.to_string());
    let publish = [
        "pub",
        d.as_str(),
        kind,
        topic.as_str(),
        count.as_str(),
        period.as_str(),
    ];
    let mut publisher = Rclpy::start_with(python, script, &publish, profile)?;
    sub.expect("ready")?;
    publisher.expect("done")?;
    let samples = sub.samples()?;
    let mut l = Latencies::new();
    for (_, stamp, got) in samples {
        l.record(got.saturating_sub(stamp));
    }
    Ok(l)
}

pub(crate) fn run(args: Ros2Args) -> anyhow::Result<()> {
    let target = crate::support::sibling("sim-client")?
        .parent()
        .and_then(Path::parent)
        .context("the target directory")?
        .to_path_buf();
    let python = args
        .python
        .clone()
        .unwrap_or_else(|| target.join("simbus-venv/bin/python"));
    let has_rclpy = Command::new(&python)
        .args(["-c", "import rclpy"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !has_rclpy {
        bail!(
            "{} has no rclpy: pip install -r tests/python/requirements.txt into it (or --python)",
            python.display()
        );
    }
    let script = std::env::temp_dir().join(format!("simbus-ros2-bench-{}.py", std::process::id()));
    std::fs::write(&script, SCRIPT)?;
    let result = measure(&args, &python, &script);
    let _ = std::fs::remove_file(&script);
    result
}

fn measure(args: &Ros2Args, python: &Path, script: &Path) -> anyhow::Result<()> {
    let load = crate::support::load_average();
    let domain = 90 + (std::process::id() % 10) as u16;
    let d = domain.to_string();
    let mut rows: Vec<(String, Latencies)> = Vec::new();

    // /clock: simbus, then the floor.
    let (mut world, _) = World::start(domain, 0, Some(false))?;
    let mut sub = Rclpy::start(python, script, &["sub", &d, "clock", "/clock"])?;
    sub.expect("ready")?;
    world.tick(50, Duration::from_millis(20))?; // the reverse match
    let published = world.tick(args.ticks, Duration::from_millis(2))?;
    rows.push((
        "/clock: simbus -> rclpy".into(),
        latencies(&sub.samples()?, &published),
    ));
    rows.push((
        "/clock: rclpy -> rclpy (floor)".into(),
        floor(python, script, domain, ("clock", args.ticks, 0.002), None)?,
    ));

    // /clock at full speed, a reliable reader: ticks/s, frames missed.
    let mut sub = Rclpy::start(python, script, &["sub", &d, "clock", "/clock"])?;
    sub.expect("ready")?;
    world.tick(50, Duration::from_millis(20))?;
    let fast = 5 * args.ticks;
    let started = Instant::now();
    let published = world.tick(fast, Duration::ZERO)?;
    let rate = fast as f64 / started.elapsed().as_secs_f64();
    let got: std::collections::HashSet<u64> = sub.samples()?.iter().map(|s| s.1).collect();
    let missed = published.keys().filter(|t| !got.contains(t)).count();
    drop(world);

    // An 800x600 image: simbus, read over UDP loopback with a 4 MiB
    // receive buffer (the profile below: with Linux's default 208 KiB
    // buffer most of a best-effort image's datagrams are dropped), then
    // the floor, a plain rclpy pair (Fast DDS to Fast DDS: shared memory).
    let profile =
        std::env::temp_dir().join(format!("simbus-ros2-bench-{}.xml", std::process::id()));
    std::fs::write(&profile, FASTDDS_PROFILE)?;
    let (mut world, ids) = World::start(domain, 1, Some(false))?;
    let topic = format!("/simbus/sensor_{}/image", ids[0]);
    let mut sub = Rclpy::start_with(
        python,
        script,
        &["sub", &d, "image", &topic],
        Some(&profile),
    )?;
    sub.expect("ready")?;
    world.tick(20, Duration::from_millis(50))?;
    let published = world.tick(args.images, Duration::from_millis(50))?;
    rows.push((
        "800x600 image: simbus -> rclpy".into(),
        latencies(&sub.samples()?, &published),
    ));
    drop(world);
    rows.push((
        "800x600 image: rclpy -> rclpy (floor)".into(),
        floor(
            python,
            script,
            domain,
            ("image", args.images, 0.05),
            Some(&profile),
        )?,
    ));

    // Four cameras, as fast as the world goes: the world alone (the
    // floor), then with the adapter, best effort and with --lockstep (a
    // reliable reader). The rclpy side reads them over UDP loopback with a
    // 4 MiB receive buffer (a Fast DDS profile: ROS's advice for large
    // messages; RustDDS has no shared memory transport).
    let (mut alone, _) = World::start(domain, 4, None)?;
    alone.tick(5, Duration::ZERO)?;
    let started = Instant::now();
    alone.tick(args.images, Duration::ZERO)?;
    let alone_fps = args.images as f64 / started.elapsed().as_secs_f64();
    drop(alone);
    let profile =
        std::env::temp_dir().join(format!("simbus-ros2-bench-{}.xml", std::process::id()));
    std::fs::write(&profile, FASTDDS_PROFILE)?;
    let mut cameras = Vec::new();
    for lockstep in [false, true] {
        let (mut world, ids) = World::start(domain, 4, Some(lockstep))?;
        let topics: Vec<String> = ids
            .iter()
            .map(|id| format!("/simbus/sensor_{id}/image"))
            .collect();
        let kind = if lockstep { "image_reliable" } else { "image" };
        let mut sub_args = vec!["sub", d.as_str(), kind];
        sub_args.extend(topics.iter().map(String::as_str));
        let mut sub = Rclpy::start_with(python, script, &sub_args, Some(&profile))?;
        sub.expect("ready")?;
        world.tick(20, Duration::from_millis(100))?;
        let started = Instant::now();
        let published = world.tick(args.images, Duration::ZERO)?;
        let fps = args.images as f64 / started.elapsed().as_secs_f64();
        let samples = sub.samples()?;
        let delivered = samples
            .iter()
            .filter(|s| published.contains_key(&s.1))
            .count();
        let share = delivered as f64 / (4 * args.images) as f64;
        cameras.push((lockstep, fps, share));
    }
    let _ = std::fs::remove_file(&profile);

    if args.json {
        let json = serde_json::json!({
            "load_before": load,
            "latency": rows.iter().map(|(n, l)| (n.clone(), l.json())).collect::<serde_json::Map<_, _>>(),
            "clock_full_speed": {"ticks_per_second": rate, "ticks": fast, "missed": missed},
            "four_cameras_world_alone_fps": alone_fps,
            "four_cameras": cameras.iter().map(|(lockstep, fps, share)| serde_json::json!({
                "lockstep": lockstep, "frames_per_second": fps, "delivered": share})).collect::<Vec<_>>(),
        });
        println!("{json}");
        return Ok(());
    }
    println!("load before: {load}");
    println!("{}", header("from publication to the rclpy callback"));
    for (name, l) in &rows {
        println!("{}  ({} messages)", l.row(name), l.len());
    }
    let ratio = |a: usize, b: usize| rows[a].1.quantile_us(0.5) / rows[b].1.quantile_us(0.5);
    println!(
        "p50 ratio to the floor: /clock {:.2}x, image {:.2}x",
        ratio(0, 1),
        ratio(2, 3)
    );
    println!("/clock at full speed: {rate:.0} ticks/s to a reliable rclpy reader, {missed} of {fast} missed");
    println!("four 800x600 cameras, the world alone (no adapter): {alone_fps:.1} frames/s");
    for (lockstep, fps, share) in cameras {
        println!(
            "four 800x600 cameras{}: {fps:.1} frames/s, {:.1} % of images delivered",
            if lockstep { " (--lockstep)" } else { "" },
            share * 100.0
        );
    }
    let _ = std::io::stdout().flush();
    Ok(())
}
