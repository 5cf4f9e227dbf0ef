//! `sim-client sensor spawn | list | watch`.

use std::time::Duration;

use anyhow::anyhow;
use clap::{Args, Subcommand};
use shared_types::{Camera, SensorKind, SensorParams, SensorSpec, SensorSpecError, WorldName};
use sim_client::{Client, WaitError};
use simbus_input as input;

use super::sensor_capture::{failure, next_capture};
use super::sensor_text::print_capture;
use super::words::count;
use crate::cli::failure::Failure;

/// Sensors: cameras (depth, RGB, semantic and instance segmentation),
/// lidars (plain and semantic), radar, IMU, GNSS, collision and obstacle,
/// read in place from shared memory.
#[derive(Debug, Args)]
pub(crate) struct SensorArgs {
    #[command(subcommand)]
    command: SensorCommand,
}

#[derive(Debug, Subcommand)]
enum SensorCommand {
    /// Spawn a sensor and print its id.
    Spawn(Box<SpawnArgs>),
    /// List the world's sensors.
    List(ListArgs),
    /// One line per capture of a sensor.
    Watch(WatchArgs),
    /// Write captures to files: cameras as PNG (semantic in CARLA's
    /// CityScapes colours), lidars as PLY and a top-down PNG, radar as PLY,
    /// the other readings as JSON; `--raw` also writes each payload's bytes.
    Save(super::sensor_save::SaveArgs),
    /// Remove a sensor.
    Destroy {
        /// The sensor id.
        #[arg(allow_negative_numbers = true)]
        id: u64,
    },
}

/// Axes everywhere: X forward, Y up, Z right (of the sensor, of the world).
#[derive(Debug, Args)]
struct SpawnArgs {
    /// depth, rgb, semantic, instance, lidar, semantic-lidar, radar, imu,
    /// gnss, collision or obstacle.
    kind: String,
    /// Actor to ride on (default: fixed in the world). The sensor is
    /// destroyed with it.
    #[arg(
        long,
        value_name = "ID",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    attach: u64,
    /// Position relative to the actor (or the world), x,y,z in metres,
    /// each within +-100000.
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,2,0",
        allow_hyphen_values = true,
        value_parser = |s: &str| input::position(s).map(|_| s.to_owned())
    )]
    at: String,
    /// Orientation relative to the actor (or the world): yaw (about Y,
    /// positive turns X toward -Z, i.e. left), pitch (about Z, positive
    /// looks up), roll (about X), in degrees.
    #[arg(
        long,
        value_name = "YAW,PITCH,ROLL",
        default_value = "0,0,0",
        allow_hyphen_values = true
    )]
    rotation: String,
    /// Capture period in simulation seconds, 0..=18446744073 (0: every frame).
    #[arg(long, value_name = "S", default_value_t = 0.0, allow_negative_numbers = true, value_parser = input::sensor_tick)]
    sensor_tick: f64,
    /// Cameras: image width and height in pixels, each 1..=8192 [default: 640,480].
    #[arg(long, value_name = "W,H", allow_hyphen_values = true, value_parser = |s: &str| input::image_size(s).map(|_| s.to_owned()))]
    size: Option<String>,
    /// Cameras and radar: horizontal field of view in degrees, above 0 and
    /// below 180 [default: cameras 90, radar 30].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true, value_parser = input::field_of_view)]
    fov: Option<f32>,
    /// Radar: vertical field of view in degrees, above 0 and below 180
    /// [default: 30].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true, value_parser = input::field_of_view)]
    vertical_fov: Option<f32>,
    /// Radar: rays per simulated second, 1..=1000000, spread at random
    /// over the field of view; a frame of dt casts N × dt [default: 1500].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::radar_points_per_second)]
    points_per_second: Option<u32>,
    /// Cameras: far range (the RGB, semantic and instance cameras see sky
    /// beyond it); lidars and radar: range, in metres, above 0 and at most
    /// 1e6 [default: depth 100, other cameras 1000, lidars 50, radar 100].
    #[arg(long, value_name = "M", allow_negative_numbers = true, value_parser = input::sensor_range)]
    range: Option<f32>,
    /// Lidars: channels (rings), 1..=256 [default: 32].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::lidar_channels)]
    channels: Option<u32>,
    /// Lidars: points per channel in a full turn, 1..=65536 [default: 512].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::lidar_points)]
    points: Option<u32>,
    /// Lidars: elevation of the top and bottom channels, degrees [default: 10,-30].
    #[arg(long, value_name = "UPPER,LOWER", allow_hyphen_values = true)]
    fov_range: Option<String>,
    /// Lidars: turns per simulated second; each capture covers hz × dt of a
    /// turn (0: a full turn every capture; at most 1e6) [default: 0].
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = input::rotation_frequency)]
    rotation_frequency: Option<f32>,
    /// GNSS: standard deviations of the normal errors added to latitude,
    /// longitude (degrees) and altitude (metres), each >= 0 [default:
    /// 0,0,0]; lidar: one, of the error added along each ray, metres.
    #[arg(long, value_name = "LAT,LON,ALT|M", allow_hyphen_values = true)]
    noise_stddev: Option<String>,
    /// Lidar: CARLA's drop-off: the share of rays dropped at random, the
    /// intensity below which returns may be dropped, and the chance a
    /// return of intensity 0 is, each in 0..=1 (CARLA's defaults:
    /// 0.45,0.8,0.4) [default: 0,0,0, nothing dropped].
    #[arg(long, value_name = "GENERAL,LIMIT,ZERO", allow_hyphen_values = true)]
    dropoff: Option<String>,
    /// Lidar: intensity falls as exp(-RATE × distance), RATE >= 0 (CARLA's
    /// default 0.004) [default: 0, intensity 1 - distance / range].
    #[arg(long, value_name = "RATE", allow_negative_numbers = true, value_parser = input::attenuation_rate)]
    attenuation: Option<f32>,
    /// GNSS: biases added to latitude, longitude (degrees) and altitude
    /// (metres) [default: 0,0,0].
    #[arg(long, value_name = "LAT,LON,ALT", allow_hyphen_values = true)]
    noise_bias: Option<String>,
    /// Obstacle: the radius of the sphere swept ahead, metres, in (0, 100]
    /// (--range is how far ahead, in (0, 1000]) [default: 0.5, range 5].
    #[arg(long, value_name = "M", allow_negative_numbers = true, value_parser = input::hit_radius)]
    hit_radius: Option<f32>,
    /// Obstacle: only dynamic actors count (not the ground, ramps, buildings).
    #[arg(long)]
    only_dynamics: bool,
    /// GNSS and lidar: the errors' seed; radar: its rays' seed;
    /// 0..=16777216 (the same seed, the same errors and rays) [default: 0].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::gnss_seed)]
    noise_seed: Option<u32>,
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
    #[arg(allow_negative_numbers = true)]
    id: u64,
    /// Stop after N captures (N >= 1).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::count)]
    captures: Option<u64>,
    /// One JSON object per capture (frame, bytes, ...; an IMU's
    /// accelerometer, gyroscope and compass).
    #[arg(long)]
    json: bool,
    /// Join the lockstep: in synchronous mode the server waits for this
    /// reader every frame, so it never misses a capture however slow it is.
    #[arg(long)]
    lockstep: bool,
    /// Ride through a server restart (`sim-server --resume DIR`): when the
    /// server exits, wait up to --timeout for one to come back, print a
    /// `restarted` line marking the gap (JSON: "event": "restarted"), and go
    /// on reading the sensor, which comes back with the journal under its id.
    #[arg(long, conflicts_with = "lockstep")]
    follow_restarts: bool,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: SensorArgs) -> Result<(), Failure> {
    // A spec is checked before any server is asked.
    let spawning = match &args.command {
        SensorCommand::Spawn(a) => Some(spec(a)?),
        _ => None,
    };
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    match args.command {
        SensorCommand::Spawn(a) => match spawning {
            Some(spec) => spawn(&client, spec, &a),
            None => Ok(()),
        },
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
                    let on = match s.spec.attach_to {
                        0 => "in the world".to_owned(),
                        id => format!("on actor {id}"),
                    };
                    let every = match s.spec.sensor_tick {
                        0.0 => "every frame".to_owned(),
                        t => format!("every {} s", seconds_text(t)),
                    };
                    println!(
                        "sensor {:>3}  {kind:<5}  {on:<14} {every}  {}",
                        s.id,
                        count(s.captures, "capture")
                    );
                }
            }
            Ok(())
        }
        SensorCommand::Watch(a) => watch(&mut client, a, timeout),
        SensorCommand::Save(a) => super::sensor_save::save(&client, a, timeout),
        SensorCommand::Destroy { id } => {
            client.destroy_sensor(id).map_err(failure)?;
            println!("destroyed sensor {id}");
            Ok(())
        }
    }
}

/// Refuses a flag that does not belong to `kind`.
fn only_for(kind: SensorKind, given: &[(&str, bool, &[SensorKind])]) -> Result<(), Failure> {
    for (flag, present, kinds) in given {
        if *present && !kinds.contains(&kind) {
            return Err(Failure::Refused(anyhow!(
                "{flag} applies to {} sensors, not to {}",
                SensorKind::listed(kinds),
                kind.name()
            )));
        }
    }
    Ok(())
}

/// The spec `a` describes, checked.
fn spec(a: &SpawnArgs) -> Result<SensorSpec, Failure> {
    use SensorKind::{Depth, Gnss, Instance, Lidar, Obstacle, Radar, Rgb, Semantic, SemanticLidar};
    let at = super::parse::numbers::<3>(&a.at, "--at")?;
    let [yaw, pitch, roll] = super::parse::numbers::<3>(&a.rotation, "--rotation")?;
    let Some(kind) = SensorKind::from_name(&a.kind) else {
        return Err(Failure::Refused(anyhow!(
            "unknown sensor kind '{}': expected depth, rgb, semantic, instance, lidar, semantic-lidar, radar, imu, gnss, collision or obstacle",
            a.kind
        )));
    };
    only_for(
        kind,
        &[
            (
                "--size",
                a.size.is_some(),
                &[Depth, Rgb, Semantic, Instance],
            ),
            (
                "--fov",
                a.fov.is_some(),
                &[Depth, Rgb, Semantic, Instance, Radar],
            ),
            ("--vertical-fov", a.vertical_fov.is_some(), &[Radar]),
            (
                "--points-per-second",
                a.points_per_second.is_some(),
                &[Radar],
            ),
            (
                "--range",
                a.range.is_some(),
                &[
                    Depth,
                    Rgb,
                    Semantic,
                    Instance,
                    Lidar,
                    SemanticLidar,
                    Radar,
                    Obstacle,
                ],
            ),
            ("--hit-radius", a.hit_radius.is_some(), &[Obstacle]),
            ("--only-dynamics", a.only_dynamics, &[Obstacle]),
            ("--channels", a.channels.is_some(), &[Lidar, SemanticLidar]),
            ("--points", a.points.is_some(), &[Lidar, SemanticLidar]),
            (
                "--fov-range",
                a.fov_range.is_some(),
                &[Lidar, SemanticLidar],
            ),
            (
                "--rotation-frequency",
                a.rotation_frequency.is_some(),
                &[Lidar, SemanticLidar],
            ),
            ("--noise-stddev", a.noise_stddev.is_some(), &[Gnss, Lidar]),
            ("--noise-bias", a.noise_bias.is_some(), &[Gnss]),
            (
                "--noise-seed",
                a.noise_seed.is_some(),
                &[Gnss, Lidar, Radar],
            ),
            ("--dropoff", a.dropoff.is_some(), &[Lidar]),
            ("--attenuation", a.attenuation.is_some(), &[Lidar]),
        ],
    )?;
    // The depth size as typed: the spec holds it as whole pixels, so a
    // fractional size is refused from this (see `check_depth_size`).
    let mut typed_size = None;
    let mut spec = match kind {
        SensorKind::Depth | SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance => {
            let [w, h] =
                super::parse::numbers::<2>(a.size.as_deref().unwrap_or("640,480"), "--size")?;
            typed_size = Some([w, h]);
            let far = if kind == Depth { 100.0 } else { 1000.0 };
            let camera = Camera {
                width: w as u32,
                height: h as u32,
                fov: a.fov.unwrap_or(90.0),
                range: a.range.unwrap_or(far),
            };
            SensorSpec::with_params(
                at,
                SensorParams::camera_of(kind, camera).expect("a camera kind"),
            )
        }
        SensorKind::Lidar | SensorKind::SemanticLidar => {
            let [upper_fov, lower_fov] = super::parse::numbers::<2>(
                a.fov_range.as_deref().unwrap_or("10,-30"),
                "--fov-range",
            )?;
            let lidar = shared_types::Lidar {
                channels: a.channels.unwrap_or(32),
                points: a.points.unwrap_or(512),
                range: a.range.unwrap_or(50.0),
                upper_fov,
                lower_fov,
                rotation_hz: a.rotation_frequency.unwrap_or(0.0),
                noise: Default::default(),
            };
            match kind {
                SensorKind::Lidar => SensorSpec::with_params(
                    at,
                    shared_types::Lidar {
                        noise: lidar_noise(a)?,
                        ..lidar
                    },
                ),
                _ => SensorSpec::semantic_lidar(at, lidar),
            }
        }
        SensorKind::Radar => {
            let defaults = shared_types::Radar::default();
            let radar = shared_types::Radar {
                horizontal_fov: a.fov.unwrap_or(defaults.horizontal_fov),
                vertical_fov: a.vertical_fov.unwrap_or(defaults.vertical_fov),
                range: a.range.unwrap_or(defaults.range),
                points_per_second: a.points_per_second.unwrap_or(defaults.points_per_second),
                seed: a.noise_seed.unwrap_or(defaults.seed),
            };
            SensorSpec::with_params(at, radar)
        }
        SensorKind::Imu => SensorSpec::imu(at),
        SensorKind::Gnss => SensorSpec::with_params(at, gnss_params(a)?),
        SensorKind::Collision => SensorSpec::with_params(at, shared_types::Collision),
        SensorKind::Obstacle => {
            let defaults = shared_types::Obstacle::default();
            let obstacle = shared_types::Obstacle {
                distance: a.range.unwrap_or(defaults.distance),
                hit_radius: a.hit_radius.unwrap_or(defaults.hit_radius),
                only_dynamics: a.only_dynamics,
            };
            SensorSpec::with_params(at, obstacle)
        }
    }
    .attached_to(a.attach)
    .every(a.sensor_tick);
    spec.rotation = simbus_pose::from_yaw_pitch_roll(yaw, pitch, roll);
    check_depth_size(&spec, typed_size)
        .map_err(|e| Failure::Refused(anyhow!("invalid {} sensor: {e}", kind.name())))?;
    Ok(spec)
}

/// A lidar's noise as `--noise-stddev`, `--dropoff`, `--attenuation` and
/// `--noise-seed` give it (checked with the rest of the spec).
fn lidar_noise(a: &SpawnArgs) -> Result<shared_types::LidarNoise, Failure> {
    let [noise_stddev] =
        super::parse::numbers::<1>(a.noise_stddev.as_deref().unwrap_or("0"), "--noise-stddev")?;
    if noise_stddev < 0.0 {
        return Err(Failure::Refused(anyhow!(
            "--noise-stddev takes a standard deviation >= 0, got '{noise_stddev}'"
        )));
    }
    let dropoff = super::parse::numbers::<3>(a.dropoff.as_deref().unwrap_or("0,0,0"), "--dropoff")?;
    if dropoff.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(Failure::Refused(anyhow!(
            "--dropoff takes three shares in 0..=1 (GENERAL,LIMIT,ZERO), got '{}'",
            a.dropoff.as_deref().unwrap_or_default()
        )));
    }
    let [dropoff_general_rate, dropoff_intensity_limit, dropoff_zero_intensity] = dropoff;
    Ok(shared_types::LidarNoise {
        noise_stddev,
        dropoff_general_rate,
        dropoff_intensity_limit,
        dropoff_zero_intensity,
        atmosphere_attenuation_rate: a.attenuation.unwrap_or(0.0),
        seed: a.noise_seed.unwrap_or(0),
    })
}

/// A GNSS receiver's noise as `--noise-stddev`, `--noise-bias` and
/// `--noise-seed` give it (checked with the rest of the spec).
fn gnss_params(a: &SpawnArgs) -> Result<shared_types::Gnss, Failure> {
    let three = |text: &Option<String>, flag| {
        super::parse::numbers::<3>(text.as_deref().unwrap_or("0,0,0"), flag)
    };
    let [lat_stddev, lon_stddev, alt_stddev] = three(&a.noise_stddev, "--noise-stddev")?;
    if [lat_stddev, lon_stddev, alt_stddev]
        .iter()
        .any(|d| *d < 0.0)
    {
        return Err(Failure::Refused(anyhow!(
            "--noise-stddev takes standard deviations >= 0, got '{}'",
            a.noise_stddev.as_deref().unwrap_or_default()
        )));
    }
    let [lat_bias, lon_bias, alt_bias] = three(&a.noise_bias, "--noise-bias")?;
    let seed = a.noise_seed.unwrap_or(0);
    Ok(shared_types::Gnss {
        lat_bias,
        lat_stddev,
        lon_bias,
        lon_stddev,
        alt_bias,
        alt_stddev,
        seed,
    })
}

/// [`SensorSpec::check`], with a depth camera's size as typed (`size`):
/// a size that is not finite, or not a whole number, is refused as the
/// check refuses it, in the check's order.
fn check_depth_size(spec: &SensorSpec, size: Option<[f32; 2]>) -> Result<(), SensorSpecError> {
    let Some(size) = size else {
        return spec.check();
    };
    if size.iter().any(|v| !v.is_finite()) {
        return Err(SensorSpecError::NotFinite);
    }
    match spec.check() {
        Err(
            e @ (SensorSpecError::NotFinite
            | SensorSpecError::Position
            | SensorSpecError::SensorTick),
        ) => Err(e),
        _ if size.iter().any(|v| v.fract() != 0.0) => Err(SensorSpecError::CameraSize),
        checked => checked,
    }
}

fn spawn(client: &Client, spec: SensorSpec, a: &SpawnArgs) -> Result<(), Failure> {
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

/// Seconds as people read them: 0.05, 2, 1e300 (not 301 digits).
fn seconds_text(seconds: f64) -> String {
    if seconds != 0.0 && !(1e-4..1e6).contains(&seconds.abs()) {
        format!("{seconds:e}")
    } else {
        format!("{seconds}")
    }
}

/// Every wait of `sensor watch` honours --timeout: no capture (or frame)
/// within it is an error, and so is the sensor's end.
fn watch(client: &mut Client, a: WatchArgs, timeout: Duration) -> Result<(), Failure> {
    let interrupted = super::interrupt::interrupted();
    let mut sensor = client.sensor(a.id).map_err(failure)?;
    let running = || !interrupted.load(std::sync::atomic::Ordering::Relaxed);
    let mut seen = 0;
    if a.lockstep {
        // Follow every frame: read its captures, then report it done.
        let mut frames = super::session::connect(client.world().as_str(), timeout)?;
        let participant = frames.join_lockstep("sensor-watch")?;
        while a.captures.is_none_or(|n| seen < n) && running() {
            let Some(snapshot) = super::watch::next_frame(&mut frames, timeout)? else {
                break;
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
        let capture = match next_capture(&mut sensor, timeout) {
            Ok(Some(capture)) => capture,
            Ok(None) => break,
            Err(WaitError::ServerGone { .. }) if a.follow_restarts => {
                let restarted = client.reconnect(timeout)?;
                println!("{}", super::watch::restarted_line(&restarted, a.json));
                sensor = client.sensor(a.id).map_err(failure)?;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        print_capture(&capture, sensor.missed(), a.json);
        seen += 1;
    }
    Ok(())
}
