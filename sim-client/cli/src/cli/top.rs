//! `sim-client top`: one refreshing screen of a world — its mode and
//! settings, frame rate and real-time factor, the ticker, the lockstep
//! participants, every client with the services it has ports on, every
//! sensor with its readers and capture rate, and the shared memory the
//! server maps. Like `dora top` or `iox2 node list`, for a simbus world.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use crate::census::{self, Holder, SharedMemory};
use anyhow::Context;
use clap::Args;
use serde::Serialize;
use shared_types::{SensorInfo, SensorKind, Timestamp, WorldName, WorldSettings};
use sim_client::Client;

use crate::cli::failure::Failure;

/// Show a world's clients, sensors, rates and shared memory, refreshing.
#[derive(Debug, Args)]
pub(crate) struct TopArgs {
    /// Seconds between refreshes, 0.05..=3600 (rates are measured over
    /// this interval).
    #[arg(long, value_name = "S", default_value_t = 1.0, allow_negative_numbers = true, value_parser = simbus_input::refresh_interval)]
    interval: f64,
    /// Measure one interval, print once and exit.
    #[arg(long)]
    once: bool,
    /// Print JSON: one object per refresh (with --once: just one).
    #[arg(long)]
    json: bool,
}

/// One sensor's line.
#[derive(Debug, Serialize)]
struct SensorLine {
    id: u64,
    kind: String,
    attached_to: u64,
    captures: u64,
    captures_per_second: f64,
    readers: Vec<String>,
}

/// One refresh.
#[derive(Debug, Serialize)]
struct Screen {
    world: String,
    server_pid: u32,
    scene: String,
    episode: u64,
    frame: u64,
    elapsed_seconds: f64,
    actors: u32,
    settings: serde_json::Value,
    frames_per_second: f64,
    real_time_factor: f64,
    ticker: Option<serde_json::Value>,
    /// Participants in all (the server describes the first eight).
    participant_count: u32,
    participants: Vec<serde_json::Value>,
    clients: Vec<Holder>,
    sensors: Vec<SensorLine>,
    shared_memory: SharedMemory,
    /// For the text screen.
    #[serde(skip)]
    world_settings: WorldSettings,
    #[serde(skip)]
    lockstep: Vec<sim_client::ParticipantStatus>,
    #[serde(skip)]
    ticker_line: String,
}

fn seconds(elapsed_ns: u64) -> f64 {
    Timestamp {
        elapsed_ns,
        ..Default::default()
    }
    .elapsed_seconds()
}

fn label(holder: &Holder) -> String {
    let name = holder.nodes.join(" ");
    format!(
        "{} (pid {})",
        if name.is_empty() {
            &holder.process
        } else {
            &name
        },
        holder.pid
    )
}

/// Measures one interval and gathers everything on the screen.
fn measure(client: &Client, interval: Duration) -> anyhow::Result<Screen> {
    let (first, first_sensors, started) =
        (client.status()?, client.list_sensors()?, Instant::now());
    std::thread::sleep(interval);
    let report: sim_client::Status = client.status()?;
    let wall = started.elapsed().as_secs_f64();
    let sensors_now = client.list_sensors()?;
    let clients = census::holders(client).map_err(anyhow::Error::msg)?;
    let shared_memory = census::shared_memory_of(report.server_pid)
        .with_context(|| format!("reading the server's maps (pid {})", report.server_pid))?;
    // Rates over the interval (a reload in between restarts the frame count).
    let same_episode = report.episode == first.episode;
    let (frames, simulated) = if same_episode {
        (
            report.frame.saturating_sub(first.frame) as f64,
            seconds(report.elapsed_ns.saturating_sub(first.elapsed_ns)),
        )
    } else {
        (0.0, 0.0)
    };
    let sensors = sensor_lines(
        &first_sensors,
        &sensors_now,
        wall,
        &clients,
        report.server_pid,
    );
    let settings = report.settings;
    Ok(Screen {
        world: client.world().to_string(),
        server_pid: report.server_pid,
        scene: report.scene.clone(),
        episode: report.episode,
        frame: report.frame,
        elapsed_seconds: seconds(report.elapsed_ns),
        actors: report.actor_count,
        settings: super::describe::settings_json(&settings),
        frames_per_second: frames / wall,
        real_time_factor: simulated / wall,
        ticker: report.ticker.as_ref().map(|t| {
            serde_json::json!({"node": t.node_name, "pid": t.pid, "since_frame": t.since_frame})
        }),
        participant_count: report.participants,
        participants: report.lockstep.iter().map(super::describe::participant_json).collect(),
        clients: clients
            .into_iter()
            .filter(|h| h.pid != report.server_pid)
            .collect(),
        sensors,
        shared_memory,
        world_settings: settings,
        lockstep: report.lockstep.clone(),
        ticker_line: report
            .ticker
            .as_ref()
            .map_or_else(|| "none".to_owned(), ToString::to_string),
    })
}

/// Each sensor's line: its capture rate over the `wall` seconds between
/// `before` and `now`, and the clients (not the server) reading it.
fn sensor_lines(
    before: &[SensorInfo],
    now: &[SensorInfo],
    wall: f64,
    clients: &[Holder],
    server_pid: u32,
) -> Vec<SensorLine> {
    let holding = |service: &str| -> Vec<String> {
        clients
            .iter()
            .filter(|h| h.pid != server_pid && h.services.iter().any(|s| s == service))
            .map(label)
            .collect()
    };
    let before: BTreeMap<u64, u64> = before.iter().map(|s| (s.id, s.captures)).collect();
    now.iter()
        .map(|info| SensorLine {
            id: info.id,
            kind: SensorKind::from_u32(info.spec.kind)
                .map_or_else(|| "unknown".to_owned(), |k| format!("{k:?}").to_lowercase()),
            attached_to: info.spec.attach_to,
            captures: info.captures,
            captures_per_second: before
                .get(&info.id)
                .map_or(0.0, |&c| info.captures.saturating_sub(c) as f64 / wall),
            readers: holding(&format!("sensor/{}", info.id)),
        })
        .collect()
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// A table after a blank line: the count of its `noun`s, its `heading`,
/// and a line for each of `items` as `row` writes it.
fn table<T>(
    out: &mut String,
    noun: &str,
    items: &[T],
    heading: std::fmt::Arguments<'_>,
    row: impl Fn(&T) -> String,
) {
    use std::fmt::Write;
    let _ = writeln!(out);
    let _ = writeln!(out, "{}", super::words::count(items.len() as u64, noun));
    let _ = writeln!(out, "{heading}");
    for item in items {
        let _ = writeln!(out, "{}", row(item));
    }
}

/// The screen as lines for people.
fn render(screen: &Screen) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "world {}  server pid {}  scene {}  episode {}  {}",
        screen.world,
        screen.server_pid,
        screen.scene,
        screen.episode,
        super::words::count(screen.actors, "actor")
    );
    let _ = writeln!(
        out,
        "frame {}  t = {:.3} s  {:.1} frames/s  real-time factor {:.2}",
        screen.frame, screen.elapsed_seconds, screen.frames_per_second, screen.real_time_factor
    );
    for (name, value) in super::describe::settings_lines(&screen.world_settings) {
        let _ = writeln!(out, "{name:<9} {value}");
    }
    let _ = writeln!(out, "ticker    {}", screen.ticker_line);
    let _ = writeln!(
        out,
        "lockstep  {}",
        super::words::count(screen.participant_count, "participant")
    );
    for p in &screen.lockstep {
        let _ = writeln!(out, "          {}", super::describe::participant_line(p));
    }
    let _ = writeln!(
        out,
        "shm       {} files, {:.1} MiB mapped by the server, {:.1} MiB resident",
        screen.shared_memory.files,
        mib(screen.shared_memory.bytes),
        mib(screen.shared_memory.resident_bytes)
    );
    tables(&mut out, screen);
    out
}

/// The screen's tables: the clients, and the sensors with their readers.
fn tables(out: &mut String, screen: &Screen) {
    table(
        out,
        "client",
        &screen.clients,
        format_args!("{:<8} {:<12} {:<40} services", "pid", "process", "nodes"),
        |holder| {
            format!(
                "{:<8} {:<12} {:<40} {}",
                holder.pid,
                holder.process,
                holder.nodes.join(" "),
                holder.services.join(" ")
            )
        },
    );
    table(
        out,
        "sensor",
        &screen.sensors,
        format_args!(
            "{:<6} {:<7} {:>9} {:>10} {:>10}  readers",
            "id", "kind", "attached", "captures", "per s"
        ),
        |s| {
            format!(
                "{:<6} {:<7} {:>9} {:>10} {:>10.1}  {}",
                s.id,
                s.kind,
                s.attached_to,
                s.captures,
                s.captures_per_second,
                if s.readers.is_empty() {
                    "-".to_owned()
                } else {
                    s.readers.join(", ")
                }
            )
        },
    );
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: TopArgs) -> Result<(), Failure> {
    if !(args.interval.is_finite() && (0.05..=3600.0).contains(&args.interval)) {
        return Err(Failure::Refused(anyhow::anyhow!(
            "--interval must be between 0.05 and 3600 seconds, not {}",
            args.interval
        )));
    }
    let interval = Duration::from_secs_f64(args.interval);
    let stop = super::interrupt::interrupted();
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    loop {
        let screen = measure(&client, interval)?;
        if args.json {
            println!("{}", serde_json::to_string(&screen)?);
        } else {
            let text = render(&screen);
            if args.once {
                print!("{text}");
            } else {
                // Clear the screen and draw from the top.
                print!("\x1b[2J\x1b[H{text}");
            }
        }
        if args.once || stop.load(std::sync::atomic::Ordering::Relaxed) {
            return Ok(());
        }
    }
}
