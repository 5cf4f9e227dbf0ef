//! `sim-client sensor spawn | list | watch`.

use std::time::Duration;

use anyhow::anyhow;
use clap::{Args, Subcommand};
use shared_types::{SensorKind, SensorSpec, WorldName};
use sim_client::{Capture, Client, SensorError};

use crate::Failure;

/// Sensors: depth camera, lidar and IMU, read in place from shared memory.
#[derive(Debug, Args)]
pub struct SensorArgs {
    #[command(subcommand)]
    command: SensorCommand,
}

#[derive(Debug, Subcommand)]
enum SensorCommand {
    /// Spawn a sensor and print its id.
    Spawn(SpawnArgs),
    /// List the world's sensors.
    List(ListArgs),
    /// One line per capture of a sensor.
    Watch(WatchArgs),
    /// Write captures as pictures: depth as PNG, lidar as PLY and a top-down PNG.
    Save(SaveArgs),
    /// Remove a sensor.
    Destroy {
        /// The sensor id.
        id: u64,
    },
}

#[derive(Debug, Args)]
struct SpawnArgs {
    /// depth (640x480, 90° fov, 100 m), lidar (32 x 512, 50 m, +10°..-30°) or imu.
    kind: String,
    /// Actor to ride on (default: fixed in the world).
    #[arg(long, value_name = "ID", default_value_t = 0)]
    attach: u64,
    /// Position relative to the actor (or the world), x,y,z.
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,2,0",
        allow_hyphen_values = true
    )]
    at: String,
    /// Capture period in simulation seconds (0: every frame).
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    sensor_tick: f64,
    /// Depth: image width and height.
    #[arg(long, value_name = "W,H", default_value = "640,480")]
    size: String,
    /// Lidar: turns per simulated second; each capture covers hz × dt of a
    /// turn (0: a full turn every capture).
    #[arg(long, value_name = "HZ", default_value_t = 0.0)]
    rotation_frequency: f32,
    /// Print {"id": N, ...}.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct ListArgs {
    /// One JSON object per sensor.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
struct WatchArgs {
    /// The sensor id.
    id: u64,
    /// Stop after N captures.
    #[arg(long, value_name = "N")]
    captures: Option<u64>,
    /// One JSON object per capture (frame, bytes, ...).
    #[arg(long)]
    json: bool,
    /// Join the lockstep: in synchronous mode the server waits for this
    /// reader every frame, so it never misses a capture however slow it is.
    #[arg(long)]
    lockstep: bool,
}

#[derive(Debug, Args)]
struct SaveArgs {
    /// The sensor id.
    id: u64,
    /// How many captures to save.
    #[arg(long, value_name = "N", default_value_t = 1)]
    frames: u64,
    /// Directory to write into (created if missing).
    #[arg(long, value_name = "DIR")]
    out: std::path::PathBuf,
}

fn numbers<const N: usize>(text: &str, flag: &str) -> Result<[f32; N], Failure> {
    let values: Vec<f32> = text
        .split(',')
        .map(|p| p.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            Failure::Refused(anyhow!(
                "{flag} takes {N} comma-separated numbers, got '{text}'"
            ))
        })?;
    values.try_into().map_err(|_| {
        Failure::Refused(anyhow!(
            "{flag} takes {N} comma-separated numbers, got '{text}'"
        ))
    })
}

fn failure(e: SensorError) -> Failure {
    match e {
        SensorError::Refused(_) => Failure::Refused(e.into()),
        e => Failure::Runtime(e.into()),
    }
}

pub fn run(world: &WorldName, timeout: Duration, args: SensorArgs) -> Result<(), Failure> {
    let mut client = Client::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    match args.command {
        SensorCommand::Spawn(a) => spawn(&client, a),
        SensorCommand::List(a) => {
            for s in client.list_sensors().map_err(failure)? {
                let kind = s.spec.sensor_kind().map_or("?", |k| k.name());
                if a.json {
                    println!(
                        "{}",
                        serde_json::json!({"id": s.id, "kind": kind, "attach": s.spec.attach_to,
                            "sensor_tick": s.spec.sensor_tick, "captures": s.captures})
                    );
                } else {
                    println!(
                        "sensor {:>3}  {kind:<5}  on actor {:<4} every {} s  {} captures",
                        s.id, s.spec.attach_to, s.spec.sensor_tick, s.captures
                    );
                }
            }
            Ok(())
        }
        SensorCommand::Watch(a) => watch(&client, a),
        SensorCommand::Save(a) => save(&client, a),
        SensorCommand::Destroy { id } => {
            client.destroy_sensor(id).map_err(failure)?;
            println!("destroyed sensor {id}");
            Ok(())
        }
    }
}

fn spawn(client: &Client, a: SpawnArgs) -> Result<(), Failure> {
    let at = numbers::<3>(&a.at, "--at")?;
    let spec = match SensorKind::from_name(&a.kind) {
        Some(SensorKind::Depth) => {
            let [w, h] = numbers::<2>(&a.size, "--size")?;
            SensorSpec::depth(at, w as u32, h as u32, 90.0, 100.0)
        }
        Some(SensorKind::Lidar) => {
            SensorSpec::lidar(at, 32, 512, 50.0, 10.0, -30.0).rotating(a.rotation_frequency)
        }
        Some(SensorKind::Imu) => SensorSpec::imu(at),
        None => {
            return Err(Failure::Refused(anyhow!(
                "unknown sensor kind '{}': expected depth, lidar or imu",
                a.kind
            )))
        }
    }
    .attached_to(a.attach)
    .every(a.sensor_tick);
    let sensor = client.spawn_sensor(spec).map_err(failure)?;
    if a.json {
        println!(
            "{}",
            serde_json::json!({"id": sensor.id(), "kind": a.kind, "attach": a.attach, "sensor_tick": a.sensor_tick})
        );
    } else {
        println!("spawned {} sensor {}", a.kind, sensor.id());
    }
    Ok(())
}

fn print_capture(capture: &Capture, missed: u64, json: bool) {
    let h = capture.header();
    let kind = SensorKind::from_u32(h.kind).map_or("?", |k| k.name());
    if json {
        println!(
            "{}",
            serde_json::json!({"sensor": h.sensor_id, "kind": kind, "frame": h.frame,
                "elapsed_ns": h.elapsed_ns, "sequence": h.sequence, "count": h.count,
                "bytes": capture.bytes().len(), "missed": missed,
                "position": h.position})
        );
    } else {
        println!(
            "sensor {} {kind:<5} frame {:>7}  t = {:.6} s  #{}  {} bytes  {} values",
            h.sensor_id,
            h.frame,
            h.elapsed_ns as f64 / 1e9,
            h.sequence,
            capture.bytes().len(),
            h.count
        );
    }
}

fn watch(client: &Client, a: WatchArgs) -> Result<(), Failure> {
    let interrupted = super::interrupted();
    let mut sensor = client.sensor(a.id).map_err(failure)?;
    let running = || !interrupted.load(std::sync::atomic::Ordering::Relaxed);
    let mut seen = 0;
    if a.lockstep {
        // Follow every frame: read its captures, then report it done.
        let mut frames = Client::connect(client.world().as_str(), Duration::from_secs(5))?;
        let participant = frames.join_lockstep("sensor-watch")?;
        while a.captures.is_none_or(|n| seen < n) && running() {
            let snapshot = match frames.wait_for_tick(Duration::from_millis(200)) {
                Ok(s) => s,
                Err(sim_client::WaitError::Timeout { .. }) => continue,
                Err(e) => return Err(anyhow!(e).into()),
            };
            while let Some(capture) = sensor.try_recv()? {
                print_capture(&capture, sensor.missed(), a.json);
                seen += 1;
            }
            participant.done(snapshot.episode(), snapshot.frame())?;
        }
        return Ok(());
    }
    while a.captures.is_none_or(|n| seen < n) && running() {
        let capture = match sensor.recv(Duration::from_millis(200)) {
            Ok(c) => c,
            Err(sim_client::WaitError::Timeout { .. }) => continue,
            Err(e) => return Err(anyhow!(e).into()),
        };
        print_capture(&capture, sensor.missed(), a.json);
        seen += 1;
    }
    Ok(())
}

fn save(client: &Client, a: SaveArgs) -> Result<(), Failure> {
    std::fs::create_dir_all(&a.out)?;
    let mut sensor = client.sensor(a.id).map_err(failure)?;
    let params = sensor.spec().params;
    for _ in 0..a.frames {
        let capture = sensor.recv(Duration::from_secs(30))?;
        let h = *capture.header();
        let stem = a
            .out
            .join(format!("sensor{}-frame{}", h.sensor_id, h.frame));
        if let Some(depth) = capture.depth() {
            let path = stem.with_extension("png");
            super::pictures::save_depth(
                &path,
                depth,
                h.size[0] as usize,
                h.size[1] as usize,
                params[3],
            )?;
            println!(
                "wrote {} (depth, white = near, legend 0..{} m)",
                path.display(),
                params[3]
            );
        } else if let Some(points) = capture.points() {
            let ply = stem.with_extension("ply");
            super::pictures::save_ply(&ply, points)?;
            let png = stem.with_extension("png");
            super::pictures::save_lidar_top_down(&png, points, params[2])?;
            println!(
                "wrote {} and {} ({} points)",
                ply.display(),
                png.display(),
                points.len()
            );
        } else if let Some(imu) = capture.imu() {
            println!("frame {}: imu {imu:?} (nothing to draw)", h.frame);
        }
    }
    Ok(())
}
