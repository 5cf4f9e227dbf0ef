//! `sim-client carla-gateway`: CARLA 0.9.16's own Python client drives
//! the world through the `simbus-carla` crate; here its flags and what the
//! command prints.

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use shared_types::WorldName;
use simbus_carla::{Config, GatewayError, Stop};

use crate::cli::failure::Failure;

/// Serve a simbus world to CARLA's Python client (`import carla`).
#[derive(Debug, Args)]
pub(crate) struct GatewayArgs {
    /// The address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// The RPC port (CARLA's `carla.Client(host, port)`); 0: any free port
    /// (and any free streaming port), printed once listening.
    #[arg(long, default_value_t = 2000, allow_negative_numbers = true)]
    port: u16,
    /// The streaming port (0: any free port) [default: --port + 1; with
    /// --port 0, any free port]. Give it to use a privileged port
    /// (below 1024) for the streams, or with --port 65535.
    #[arg(long, value_name = "PORT", allow_negative_numbers = true)]
    streaming_port: Option<u16>,
    /// Once listening, print one JSON object on stdout instead of the
    /// sentence: {"world", "host", "port", "streaming_port"}, the ports
    /// actually bound (so scripts can use --port 0).
    #[arg(long)]
    json: bool,
    /// Refuse to load CARLA's towns (Town01 … Town15, Town10HD_Opt):
    /// without it, `load_world("Town10HD_Opt")` loads simbus's town in
    /// their place and says so (in the log and in the map's name).
    #[arg(long)]
    strict_maps: bool,
    /// Let CARLA's client run its own traffic manager inside the script
    /// (CARLA's behaviour) instead of the gateway's native one. The native
    /// one answers `client.get_trafficmanager(port)` from the gateway,
    /// steps in lockstep with the world and cannot deadlock.
    #[arg(long)]
    client_traffic_manager: bool,
    /// CARLA's native ROS 2 (CARLA's server flag): publish /clock every
    /// frame and the sensors scripts enable with `enable_for_ros()` under
    /// CARLA's topic names (/carla/<parent ros_name>/<ros_name>/...), and
    /// drive `hero` vehicles from /carla/<ros_name>/vehicle_control_cmd.
    #[arg(long)]
    ros2: bool,
    /// The ROS 2 domain with --ros2 (DDS domain id, 0..=232).
    #[arg(
        long,
        env = "ROS_DOMAIN_ID",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    ros_domain_id: u16,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: GatewayArgs) -> Result<(), Failure> {
    if args.ros_domain_id > 232 {
        return Err(Failure::Refused(anyhow::anyhow!(
            "ROS domain id {} is out of range: 0..=232",
            args.ros_domain_id
        )));
    }
    let config = Config {
        host: args.host,
        port: args.port,
        streaming_port: args.streaming_port,
        timeout,
        strict_maps: args.strict_maps,
        client_traffic_manager: args.client_traffic_manager,
        ros2: args.ros2.then_some(args.ros_domain_id),
    };
    let host = config.host.as_str();
    // Ctrl-C / SIGTERM end the gateway: they wake it, it never polls.
    let stop = Stop::new()
        .map_err(|e| Failure::Runtime(anyhow::Error::new(e).context("the gateway's stop")))?;
    let stop = Arc::new(stop);
    let waker = stop.clone();
    super::interrupt::on_interrupt(move || waker.stop());
    simbus_carla::serve(world, &config, &stop, |listening| {
        let (port, streaming_port) = (listening.port, listening.streaming_port);
        if args.json {
            println!(
                "{}",
                serde_json::json!({"world": world.as_str(), "host": host,
                    "port": port, "streaming_port": streaming_port})
            );
        } else {
            println!(
                "carla-gateway: world '{world}' served to CARLA clients on {host}:{port} (streams on port {streaming_port})"
            );
        }
        let _ = std::io::stdout().flush();
    })
    .map_err(|e: GatewayError| {
        if e.is_refused() {
            Failure::Refused(e.into())
        } else {
            Failure::Runtime(e.into())
        }
    })
}
