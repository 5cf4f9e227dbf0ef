//! `sim-client ros2`: the world on ROS 2, published by the `simbus-ros2`
//! crate; here its flags and what the command prints.

use std::collections::BTreeSet;
use std::time::Duration;

use clap::Args;
use shared_types::WorldName;
use simbus_ros2::{routes, Config, Event, Naming, Ros2Error, Selection};

use crate::cli::failure::Failure;

/// Publish the world on ROS 2 (DDS), drive vehicles and tick it from ROS.
#[derive(Debug, Args)]
pub(crate) struct Ros2Args {
    /// The ROS 2 domain (DDS domain id, 0..=232).
    #[arg(
        long,
        env = "ROS_DOMAIN_ID",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    domain_id: u16,
    /// The namespace of the world's topics (`/clock`, `/tf` and
    /// `/tf_static` stay at the root, where ROS looks for them).
    #[arg(long, default_value = "/simbus")]
    namespace: String,
    /// Publish only these sensors (ids, comma-separated; default: every
    /// sensor of the world, and those spawned later).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "IDS",
        allow_negative_numbers = true
    )]
    sensors: Option<Vec<u64>>,
    /// Drive only these vehicles from ROS (ids, comma-separated; default:
    /// every vehicle).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "IDS",
        allow_negative_numbers = true
    )]
    vehicles: Option<Vec<u64>>,
    /// Be the world's ticker: synchronous mode with --delta-seconds, one
    /// frame per message on `<namespace>/tick` (std_msgs/Empty). The ticker
    /// is let go when the ROS node publishing the ticks leaves, and taken
    /// again when one comes.
    #[arg(long)]
    tick_from_ros: bool,
    /// The fixed step while ticking from ROS, seconds.
    #[arg(long, value_name = "S", default_value_t = 0.05, allow_negative_numbers = true, value_parser = simbus_input::fixed_step)]
    delta_seconds: f64,
    /// Every publication reliable and blocking: in synchronous mode a slow
    /// ROS reader holds the world instead of missing a frame.
    #[arg(long)]
    lockstep: bool,
    /// Do not publish the scene's markers (`<namespace>/markers`).
    #[arg(long)]
    no_markers: bool,
    /// One JSON object per line (events, and a summary at exit).
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: Ros2Args) -> Result<(), Failure> {
    let namespace = routes::namespace(&args.namespace).map_err(|e| Failure::Refused(e.into()))?;
    let only = |ids: Option<Vec<u64>>| ids.map(|ids| ids.into_iter().collect::<BTreeSet<_>>());
    let config = Config {
        domain_id: args.domain_id,
        naming: Naming::Simbus { namespace },
        selection: Selection {
            sensors: only(args.sensors),
            vehicles: only(args.vehicles),
            ..Selection::default()
        },
        tick_from_ros: args.tick_from_ros,
        delta_seconds: args.delta_seconds,
        lockstep: args.lockstep,
        markers: !args.no_markers,
        timeout,
    };
    let json = args.json;
    let published = simbus_ros2::run(
        world.as_str(),
        &config,
        super::interrupt::interrupted(),
        |event| {
            print_event(&event, json);
        },
    )
    .map_err(|e: Ros2Error| {
        if e.is_refused() {
            Failure::Refused(e.into())
        } else {
            Failure::Runtime(e.into())
        }
    })?;
    if json {
        println!(
            "{}",
            serde_json::json!({
                "event": "stopped",
                "frames": published.frames,
                "missed_frames": published.missed_frames,
                "captures": published.captures,
                "send_failures": published.send_failures,
                "controls_applied": published.controls_applied,
                "controls_dropped": published.controls_dropped,
                "ticks": published.ticks,
            })
        );
    } else {
        eprintln!(
            "ros2: {} published ({} missed), {}, {} applied, {} dropped, {}",
            super::words::count(published.frames, "frame"),
            published.missed_frames,
            super::words::count(published.captures, "capture"),
            super::words::count(published.controls_applied, "control"),
            published.controls_dropped,
            super::words::count(published.ticks, "tick"),
        );
    }
    Ok(())
}

/// One event as a line for people, or a JSON object.
fn print_event(event: &Event, json: bool) {
    let (value, line) = match event {
        Event::Ready {
            domain_id,
            node,
            ticker,
        } => {
            (
                serde_json::json!({"event": "ready", "domain_id": domain_id, "node": node, "ticker": ticker}),
                format!(
                "ros2: node /{node} on domain {domain_id}{}; publishing /clock, /tf, /tf_static",
                if *ticker { ", ticking the world from ROS" } else { "" }
            ),
            )
        }
        Event::Publishing { sensor, topic } => (
            serde_json::json!({"event": "publishing", "sensor": sensor, "topic": topic}),
            format!("ros2: sensor {sensor} on {topic}"),
        ),
        Event::ControlDropped {
            vehicle,
            reason,
            dropped,
        } => (
            serde_json::json!({"event": "control_dropped", "vehicle": vehicle, "reason": reason, "dropped": dropped}),
            format!("ros2: control for vehicle {vehicle} dropped ({dropped} so far): {reason}"),
        ),
        Event::TickerClaimed => (
            serde_json::json!({"event": "ticker_claimed"}),
            "ros2: ticking the world from ROS".to_owned(),
        ),
        Event::TickerReleased { reason } => (
            serde_json::json!({"event": "ticker_released", "reason": reason}),
            format!("ros2: ticker released: {reason}"),
        ),
        _ => return,
    };
    if json {
        println!("{value}");
    } else {
        println!("{line}");
    }
    use std::io::Write;
    let _ = std::io::stdout().flush();
}
