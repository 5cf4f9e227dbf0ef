//! `sensors`: capture delivery latency from 8 B to 8 MiB over simbus and
//! over TCP loopback, the server's frame time with a 640x480 depth camera
//! and a 64x1024 lidar on the default scene, and with an 800x600 RGB
//! camera, then RGB + semantic + depth at one pose, on the default scene
//! and the town.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

use clap::Args;
use shared_types::{Collision, Obstacle, Radar, SensorKind, SensorSpec};
use sim_client::{Client, Ticker};

use crate::stats::{header, Latencies};
use crate::support::spawn_peer;
use crate::support::{now_ns, sync_ticker, BenchServer};

#[derive(Debug, Args)]
pub(crate) struct SensorsArgs {
    /// Captures measured per size.
    #[arg(long, default_value_t = 200)]
    samples: u64,
    /// Ticks measured per frame-time row.
    #[arg(long, default_value_t = 100)]
    frames: u64,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    json: bool,
    /// Also draw the delivery distributions, simbus, raw iceoryx2 and TCP per size
    /// (percentile plot, log µs), into this PNG.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<std::path::PathBuf>,
    /// The delivery rows' server renders on this many threads (`sim-server
    /// --render-threads`); default: one CPU fewer than the machine has, so
    /// the spinning reader keeps one. The frame-time rows render on every CPU.
    #[arg(long, value_name = "N")]
    render_threads: Option<usize>,
}

impl SensorsArgs {
    /// The delivery rows' render threads.
    fn delivery_render_threads(&self) -> usize {
        self.render_threads.unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).max(1))
        })
    }
}

/// Payload sizes and the depth image that has them (4 bytes per pixel).
const SIZES: [(&str, u32, u32); 4] = [
    ("8 B", 2, 1),
    ("64 KiB", 128, 128),
    ("1 MiB", 512, 512),
    ("8 MiB", 2048, 1024),
];

/// The TCP peer: for each 8-byte size request, sends its send time and that
/// many bytes.
pub(crate) fn tcp_blob_peer() -> anyhow::Result<()> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    println!("{}", listener.local_addr()?.port());
    let (mut stream, _) = listener.accept()?;
    stream.set_nodelay(true)?;
    let mut request = [0u8; 8];
    let mut blob = Vec::new();
    while stream.read_exact(&mut request).is_ok() {
        let size = u64::from_le_bytes(request) as usize;
        blob.resize(8 + size, 7);
        blob[..8].copy_from_slice(&now_ns().to_le_bytes());
        stream.write_all(&blob)?;
    }
    Ok(())
}

fn tcp_latency(bytes: usize, samples: u64) -> anyhow::Result<Latencies> {
    let (_peer, port) = spawn_peer("tcp-blob", "tcp")?;
    let mut stream = TcpStream::connect(("127.0.0.1", port.parse::<u16>()?))?;
    stream.set_nodelay(true)?;
    let mut buffer = vec![0u8; 8 + bytes];
    let mut latencies = Latencies::new();
    for i in 0..samples + samples / 10 {
        stream.write_all(&(bytes as u64).to_le_bytes())?;
        stream.read_exact(&mut buffer)?;
        let sent = u64::from_le_bytes(buffer[..8].try_into()?);
        if i >= samples / 10 {
            latencies.record(now_ns().saturating_sub(sent));
        }
    }
    Ok(latencies)
}

/// One delivery row: a capture size and its latencies.
struct DeliveryRow {
    label: &'static str,
    bytes: usize,
    simbus: Latencies,
    /// Raw iceoryx2 moving a blob of the same size (`blob::floor`).
    raw: Latencies,
    tcp: Latencies,
}

pub(crate) fn run(args: SensorsArgs) -> anyhow::Result<()> {
    let rows = delivery_rows(&args)?;

    // Frame time on the default scene with and without the sensors.
    let server = BenchServer::start("sensor-frames", &["--scene", "default"])?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let frames = frame_times(&args, &client, &mut ticker)?;
    ticker.release()?;
    drop((client, server));
    let cameras = [camera_rows(&args, "default")?, camera_rows(&args, "town")?];

    if let Some(path) = &args.plot {
        plot_delivery(path, &rows)?;
    }
    report(&args, &rows, &frames, &cameras);
    Ok(())
}

/// The frame-time rows of one scene's cameras: none, an 800x600 RGB
/// camera, then a semantic and a depth camera at its pose (one cast);
/// then a semantic lidar and radars, each alone.
struct CameraRows {
    scene: &'static str,
    rows: Vec<(&'static str, Latencies)>,
}

/// `frames` ticks of `ticker`, each timed: the row `label`.
fn timed_ticks(
    ticker: &mut Ticker,
    frames: u64,
    label: &'static str,
) -> anyhow::Result<(&'static str, Latencies)> {
    let timeout = Duration::from_secs(30);
    let mut latencies = Latencies::new();
    for _ in 0..frames {
        let start = Instant::now();
        ticker.tick(timeout)?;
        latencies.record(start.elapsed().as_nanos() as u64);
    }
    Ok((label, latencies))
}

fn camera_rows(args: &SensorsArgs, scene: &'static str) -> anyhow::Result<CameraRows> {
    let server = BenchServer::start("sensor-cameras", &["--scene", scene])?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let mut frame_time = |label| timed_ticks(&mut ticker, args.frames, label);
    frame_time("warm-up")?;
    let mut rows = vec![frame_time("no sensors")?];
    // On a road of either scene, looking along it, 15 degrees down.
    let at = [38.25, 2.0, 20.0];
    let camera = |kind| {
        let mut spec =
            SensorSpec::camera_of(kind, at, (800, 600), 90.0, 1000.0).expect("a camera kind");
        spec.rotation = simbus_pose::from_yaw_pitch_roll(90.0, -15.0, 0.0);
        client.spawn_sensor(spec)
    };
    let rgb = camera(SensorKind::Rgb)?;
    rows.push(frame_time("+ rgb 800x600")?);
    let semantic = camera(SensorKind::Semantic)?;
    let depth = camera(SensorKind::Depth)?;
    rows.push(frame_time("+ semantic + depth, same pose")?);
    for sensor in [rgb, semantic, depth] {
        client.destroy_sensor(sensor.id())?;
    }
    // The ranging sensors, each alone, at the cameras' place.
    let lidar = crate::support::lidar_64x1024();
    let semantic_lidar = client.spawn_sensor(SensorSpec::semantic_lidar(at, lidar))?;
    rows.push(frame_time("semantic lidar 64x1024 alone")?);
    client.destroy_sensor(semantic_lidar.id())?;
    // 1500 points a second: 15 rays a 0.01 s frame; 100 000: 1000.
    for (label, points_per_second) in [
        ("radar 1500 points/s alone", 1500),
        ("radar 100000 points/s alone", 100_000),
    ] {
        let radar = Radar {
            points_per_second,
            ..Radar::default()
        };
        let mut spec = SensorSpec::with_params(at, radar);
        spec.rotation = simbus_pose::from_yaw_pitch_roll(90.0, 0.0, 0.0);
        let radar = client.spawn_sensor(spec)?;
        rows.push(frame_time(label)?);
        client.destroy_sensor(radar.id())?;
    }
    ticker.release()?;
    Ok(CameraRows { scene, rows })
}

/// Delivery latency: capture published -> header and data readable, in
/// a reader process spinning on the sensor itself (not behind a tick
/// round trip), the ticker asleep between paced ticks; and over TCP.
fn delivery_rows(args: &SensorsArgs) -> anyhow::Result<Vec<DeliveryRow>> {
    let threads = args.delivery_render_threads().to_string();
    let server = BenchServer::start(
        "sensors",
        &["--scene", "empty", "--render-threads", threads.as_str()],
    )?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let mut rows = Vec::new();
    for (label, width, height) in SIZES {
        let sensor =
            client.spawn_sensor(SensorSpec::depth([0.0; 3], width, height, 90.0, 100.0))?;
        let (latencies, lost) = crate::fanout::row(
            &server.world,
            &mut ticker,
            1,
            "spin",
            sensor.id(),
            args.samples,
            Duration::from_millis(2),
        )?;
        anyhow::ensure!(lost == 0, "the reader lost {lost} captures");
        client.destroy_sensor(sensor.id())?;
        let bytes = (width * height * 4) as usize;
        rows.push(DeliveryRow {
            label,
            bytes,
            simbus: latencies,
            raw: crate::blob::floor(bytes, args.samples, Duration::from_millis(2))?,
            tcp: tcp_latency(bytes, args.samples)?,
        });
    }
    ticker.release()?;
    drop(client);
    drop(server);
    Ok(rows)
}

/// The tick round trip with no sensors, then with a GNSS receiver, a
/// collision sensor, an obstacle detector, a depth camera and a lidar
/// added one by one.
fn frame_times(
    args: &SensorsArgs,
    client: &Client,
    ticker: &mut Ticker,
) -> anyhow::Result<Vec<(&'static str, Latencies)>> {
    let mut frame_time = |label| timed_ticks(ticker, args.frames, label);
    // The first ticks pay for warming up (caches, the reader's port): not
    // a row.
    frame_time("warm-up")?;
    let mut frames = vec![frame_time("no sensors")?];
    let gnss = client.spawn_sensor(SensorSpec::gnss([0.0, 2.0, 0.0]))?;
    frames.push(frame_time("+ gnss")?);
    // The event sensors ride on the default scene's ramp (actor 2, which
    // the sphere rolls down): contacts are watched, a sphere is swept
    // every frame.
    let on = |spec: SensorSpec| client.spawn_sensor(spec.attached_to(2));
    let collision = on(SensorSpec::with_params([0.0; 3], Collision))?;
    frames.push(frame_time("+ collision")?);
    let obstacle = on(SensorSpec::with_params([0.0; 3], Obstacle::default()))?;
    frames.push(frame_time("+ obstacle")?);
    let depth = client.spawn_sensor(SensorSpec::depth([-4.0, 3.0, 0.0], 640, 480, 90.0, 100.0))?;
    frames.push(frame_time("+ depth 640x480")?);
    let lidar = client.spawn_sensor(SensorSpec::lidar(
        [0.0, 3.0, 0.0],
        64,
        1024,
        50.0,
        10.0,
        -30.0,
    ))?;
    frames.push(frame_time("+ lidar 64x1024")?);
    drop((gnss, collision, obstacle, depth, lidar));
    Ok(frames)
}

/// The delivery distributions, simbus, raw iceoryx2 and TCP per size, into
/// `path`.
fn plot_delivery(path: &std::path::Path, rows: &[DeliveryRow]) -> anyhow::Result<()> {
    let names: Vec<[String; 3]> = rows
        .iter()
        .map(|r| ["simbus", "raw iceoryx2", "TCP"].map(|by| format!("{by} {}", r.label)))
        .collect();
    let series: Vec<(&str, &Latencies)> = names
        .iter()
        .zip(rows)
        .flat_map(|([simbus, raw, tcp], r)| {
            [
                (simbus.as_str(), &r.simbus),
                (raw.as_str(), &r.raw),
                (tcp.as_str(), &r.tcp),
            ]
        })
        .collect();
    crate::plot::percentiles(
        path,
        "Sensor delivery: capture sent -> reader holds it",
        &series,
    )
}

/// Prints the tables (or, with --json, one object).
fn report(
    args: &SensorsArgs,
    rows: &[DeliveryRow],
    frames: &[(&'static str, Latencies)],
    cameras: &[CameraRows],
) {
    let p50 = |l: &Latencies| l.quantile_us(0.5);
    // Wall time per ray: what each sensor added to the frame, over its rays.
    let per_ray =
        |row: usize, rays: f64| (p50(&frames[row].1) - p50(&frames[row - 1].1)) * 1e3 / rays;
    let (depth_ns, lidar_ns) = (per_ray(4, 640.0 * 480.0), per_ray(5, 64.0 * 1024.0));
    // What one GNSS receiver, collision sensor and obstacle detector each
    // add to a frame (its reading or events, and its publication).
    let added_us = |row: usize| p50(&frames[row].1) - p50(&frames[row - 1].1);
    let (gnss_us, collision_us, obstacle_us) = (added_us(1), added_us(2), added_us(3));
    // What the cameras add to a frame: RGB alone, RGB + semantic + depth.
    let added_ms = |c: &CameraRows, row: usize| (p50(&c.rows[row].1) - p50(&c.rows[0].1)) / 1e3;
    if args.json {
        let delivery: Vec<_> = rows
            .iter()
            .map(|r| {
                serde_json::json!({"size": r.label, "bytes": r.bytes, "simbus": r.simbus.json(),
                    "raw_iceoryx2": r.raw.json(), "tcp": r.tcp.json(),
                    "tcp_over_simbus_p50": p50(&r.tcp) / p50(&r.simbus),
                    "simbus_over_raw_p50": p50(&r.simbus) / p50(&r.raw)})
            })
            .collect();
        let frame_json: Vec<_> = frames
            .iter()
            .map(|(label, l)| serde_json::json!({"sensors": label, "tick": l.json()}))
            .collect();
        let camera_json: Vec<_> = cameras
            .iter()
            .map(|c| {
                let rows: Vec<_> = c
                    .rows
                    .iter()
                    .map(|(label, l)| serde_json::json!({"sensors": label, "tick": l.json()}))
                    .collect();
                serde_json::json!({"scene": c.scene, "rows": rows,
                    "rgb_added_ms_p50": added_ms(c, 1),
                    "rgb_semantic_depth_added_ms_p50": added_ms(c, 2),
                    "semantic_lidar_added_ms_p50": added_ms(c, 3),
                    "radar_1500_added_ms_p50": added_ms(c, 4),
                    "radar_100000_added_ms_p50": added_ms(c, 5)})
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"delivery": delivery, "frame_time": frame_json,
                "delivery_render_threads": args.delivery_render_threads(),
                "wall_ns_per_ray": {"depth": depth_ns, "lidar": lidar_ns},
                "gnss_added_us_p50": gnss_us, "collision_added_us_p50": collision_us,
                "obstacle_added_us_p50": obstacle_us, "cameras": camera_json})
        );
        return;
    }
    println!(
        "sensor delivery: capture sent -> a reader process spinning on the sensor holds it, first and last element read ({} captures each; server --render-threads {})",
        args.samples,
        args.delivery_render_threads()
    );
    println!("raw iceoryx2: the same size written whole, then sent on a sensor's service type and settings (the floor)");
    println!(
        "{:<8} {:>14} {:>14} {:>11} {:>11} {:>11} {:>11} {:>10}",
        "size",
        "simbus p50 µs",
        "simbus p99 µs",
        "raw p50 µs",
        "raw p99 µs",
        "TCP p50 µs",
        "TCP p99 µs",
        "TCP/simbus"
    );
    for r in rows {
        println!(
            "{:<8} {:>14.1} {:>14.1} {:>11.1} {:>11.1} {:>11.1} {:>11.1} {:>9.1}x",
            r.label,
            p50(&r.simbus),
            r.simbus.quantile_us(0.99),
            p50(&r.raw),
            r.raw.quantile_us(0.99),
            p50(&r.tcp),
            r.tcp.quantile_us(0.99),
            p50(&r.tcp) / p50(&r.simbus)
        );
    }
    println!();
    println!("server frame time on the default scene (sync tick round trip, release build)");
    println!("{}", header("sensors"));
    for (label, latencies) in frames {
        println!("{}", latencies.row(label));
    }
    println!("wall time per ray at p50 (2 cores): depth {depth_ns:.1} ns, lidar {lidar_ns:.1} ns");
    println!("added to a frame at p50 (the difference of a row's median and the one above): a GNSS receiver {gnss_us:.1} µs, a collision sensor {collision_us:.1} µs, an obstacle detector {obstacle_us:.1} µs");
    for c in cameras {
        println!();
        println!(
            "server frame time on the {} scene with 800x600 cameras on a road",
            c.scene
        );
        println!("{}", header("sensors"));
        for (label, latencies) in &c.rows {
            println!("{}", latencies.row(label));
        }
        println!(
            "added at p50: an RGB camera {:.2} ms; RGB + semantic + depth at one pose (one cast) {:.2} ms; a semantic lidar 64x1024 {:.2} ms; a radar of 1500 points/s {:.3} ms, of 100000 {:.3} ms",
            added_ms(c, 1),
            added_ms(c, 2),
            added_ms(c, 3),
            added_ms(c, 4),
            added_ms(c, 5)
        );
    }
}
