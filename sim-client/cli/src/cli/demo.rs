//! `sim-client demo`: a server on the default scene, watched live.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{anyhow, Context};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use shared_types::{ActorKind, ActorState, Command as SimCommand, WorldName};
use sim_client::{Client, WorldSnapshot};
use simbus_input as input;
use simbus_process::ChildGuard;

use super::words::count;
use crate::cli::failure::Failure;

/// Options of `sim-client demo` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct DemoArgs {
    /// Frames to watch before stopping (N >= 1).
    #[arg(long, value_name = "N", default_value_t = 300, allow_negative_numbers = true, value_parser = input::count)]
    frames: u64,

    /// Scene for the server: default, empty, town (roads with 144 spawn points), flat (a 4 km ground) or boxes:N (N in 1..=100000).
    #[arg(long, default_value = "default", value_parser = input::scene)]
    scene: String,

    /// Fixed time-step of the server, in seconds (1e-6..=3600).
    #[arg(long, value_name = "S", default_value_t = 0.02, allow_negative_numbers = true, value_parser = input::fixed_step)]
    delta_seconds: f64,

    /// The sim-server binary (default: next to this sim-client).
    #[arg(long, value_name = "PATH")]
    server: Option<PathBuf>,
}

fn server_binary(explicit: Option<PathBuf>) -> anyhow::Result<PathBuf> {
    if let Some(path) = explicit {
        return Ok(path);
    }
    let exe = std::env::current_exe().context("locating sim-client")?;
    let path = exe.with_file_name(format!("sim-server{}", std::env::consts::EXE_SUFFIX));
    if path.exists() {
        Ok(path)
    } else {
        Err(anyhow!(
            "sim-server not found at {}; build it with `cargo build --release` (or pass --server PATH)",
            path.display()
        ))
    }
}

fn length(v: [f32; 3]) -> f32 {
    v.iter().map(|x| x * x).sum::<f32>().sqrt()
}

/// One readable line about what the scene is doing.
fn summary(s: &WorldSnapshot) -> String {
    let dynamic: Vec<&ActorState> = s
        .actors
        .iter()
        .filter(|a| a.actor_kind() != Some(ActorKind::Static))
        .collect();
    let moving = dynamic
        .iter()
        .filter(|a| length(a.linear_velocity) > 0.05)
        .count();
    let mut line = format!(
        "t = {:>6.2} s  frame {:>5}  moving {:>2}/{:<2}",
        s.timestamp().elapsed_seconds(),
        s.frame(),
        moving,
        dynamic.len()
    );
    if let Some(sphere) = dynamic
        .iter()
        .find(|a| a.actor_kind() == Some(ActorKind::Sphere))
    {
        let [x, y, z] = sphere.position;
        line.push_str(&format!(
            "  sphere at ({x:>6.2}, {y:>5.2}, {z:>5.2}) {:>5.2} m/s",
            length(sphere.linear_velocity)
        ));
    }
    if let Some(top) = dynamic
        .iter()
        .filter(|a| a.actor_kind() == Some(ActorKind::Box))
        .map(|a| a.position[1])
        .reduce(f32::max)
    {
        line.push_str(&format!("  highest box {top:>5.2} m"));
    }
    let cars: Vec<String> = dynamic
        .iter()
        .filter(|a| a.actor_kind() == Some(ActorKind::Vehicle))
        .map(|a| format!("{:.1}", length(a.linear_velocity)))
        .collect();
    if !cars.is_empty() {
        line.push_str(&format!("  cars {} m/s", cars.join("/")));
    }
    line
}

/// Puts the scene's cars on the road: throttle, one steering left, one right.
fn drive_cars(client: &Client, snapshot: &WorldSnapshot) -> Result<(), Failure> {
    let controls: Vec<SimCommand> = snapshot
        .actors
        .iter()
        .filter(|a| a.actor_kind() == Some(ActorKind::Vehicle))
        .enumerate()
        .map(|(i, car)| {
            let steer = if i % 2 == 0 { 0.25 } else { -0.25 };
            SimCommand::vehicle_control(car.id, 0.3, steer, 0.0, false)
        })
        .collect();
    client.apply_batch(&controls)?;
    Ok(())
}

/// Makes `command`'s process receive SIGTERM when this process dies, so a
/// demo killed even with SIGKILL takes its server with it.
fn die_with_parent(command: &mut Command) {
    use std::os::unix::process::CommandExt;
    let parent = std::process::id();
    // SAFETY: the closure runs in the forked child before exec and calls
    // only async-signal-safe functions (prctl, getppid, _exit); it
    // allocates nothing and touches no lock.
    unsafe {
        command.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The parent may have died before prctl took effect.
            if libc::getppid() as u32 != parent {
                libc::_exit(1);
            }
            Ok(())
        });
    }
}

/// Copies the server's stderr to ours as it comes, so its messages are
/// seen; the thread ends with the server's stderr and says whether the
/// server wrote anything.
fn forward_stderr(mut from: impl std::io::Read + Send + 'static) -> JoinHandle<bool> {
    std::thread::spawn(move || {
        let mut said = false;
        let mut buf = [0u8; 4096];
        while let Ok(n) = from.read(&mut buf) {
            if n == 0 {
                break;
            }
            said = true;
            let mut stderr = std::io::stderr().lock();
            let _ = stderr.write_all(&buf[..n]);
            let _ = stderr.flush();
        }
        said
    })
}

/// Connects to the demo server's world, giving up at once if the server
/// exits (it refused its options, or the world is taken), saying whether
/// it left a message (`said`: the [`forward_stderr`] thread).
fn connect(
    world: &str,
    server: &mut ChildGuard,
    said: &mut Option<JoinHandle<bool>>,
    timeout: Duration,
) -> Result<Client, Failure> {
    let deadline = std::time::Instant::now() + timeout;
    loop {
        if let Some(status) = server.try_wait()? {
            // Its stderr closed when it exited: everything it wrote is out.
            let said = said.take().is_none_or(|t| t.join().unwrap_or(true));
            return Err(Failure::Runtime(if said {
                anyhow!("the demo server exited at once ({status}); its message is above")
            } else {
                anyhow!("the demo server exited at once ({status}) without a message")
            }));
        }
        let slice = deadline
            .saturating_duration_since(std::time::Instant::now())
            .min(Duration::from_millis(200));
        match Client::connect(world, slice) {
            // Another server may own the world: then ours exits at once.
            Ok(client) if client.server_pid() != server.id() => {}
            Ok(client) => return Ok(client),
            Err(_) if std::time::Instant::now() < deadline => continue,
            Err(e) => {
                let status = server.stop()?;
                return Err(anyhow!(e)
                    .context(format!("the demo server did not come up ({status})"))
                    .into());
            }
        }
    }
}

pub(crate) fn run(
    world: Option<WorldName>,
    timeout: Duration,
    args: DemoArgs,
) -> Result<(), Failure> {
    if !(args.delta_seconds.is_finite() && args.delta_seconds > 0.0) {
        return Err(Failure::Refused(anyhow!(
            "--delta-seconds must be a positive number of seconds"
        )));
    }
    let interrupted = super::interrupt::interrupted();
    let binary = server_binary(args.server.clone())?;
    let world = world.map_or_else(
        || format!("demo-{}", std::process::id()),
        |w| w.as_str().to_owned(),
    );
    let (mut server, mut said) = start_server(&binary, &world, &args)?;
    let mut client = connect(&world, &mut server, &mut said, timeout)?;
    // Every frame in order (not the newest), so no summary line is
    // skipped with the frame it belongs to.
    client.set_every_frame(true);
    println!(
        "demo: started sim-server (pid {}) on world '{world}', scene {}, fixed step {} s at wall-clock speed",
        server.id(),
        args.scene,
        args.delta_seconds
    );
    let (seen, missed) = watch(&mut client, &args, timeout)?;
    drop(client);
    let status = server.stop()?;
    let how = if interrupted.load(std::sync::atomic::Ordering::Relaxed) {
        "interrupted"
    } else {
        "finished"
    };
    println!(
        "demo {how}: watched {} ({missed} missed); server stopped ({status})",
        count(seen, "frame")
    );
    Ok(())
}

/// Starts the demo's sim-server on `world` (dying with this process), its
/// stderr copied to ours by the returned thread.
fn start_server(
    binary: &std::path::Path,
    world: &str,
    args: &DemoArgs,
) -> Result<(ChildGuard, Option<JoinHandle<bool>>), Failure> {
    let mut command = Command::new(binary);
    command
        .args(["--world", world, "--scene", &args.scene, "--realtime"])
        .args(["--delta-seconds", &args.delta_seconds.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if std::env::var_os("RUST_LOG").is_none() {
        command.env("RUST_LOG", "warn");
    }
    die_with_parent(&mut command);
    let mut child = command
        .spawn()
        .with_context(|| format!("starting {}", binary.display()))?;
    let said = child.stderr.take().map(forward_stderr);
    Ok((ChildGuard::new(child, Duration::from_secs(3)), said))
}

/// Watches up to `--frames` frames (a progress bar on a terminal), drives
/// the cars on the first and prints a summary line about every half
/// second of simulated time; returns the frames seen and missed.
fn watch(client: &mut Client, args: &DemoArgs, timeout: Duration) -> Result<(u64, u64), Failure> {
    let bar = std::io::IsTerminal::is_terminal(&std::io::stdout()).then(|| {
        let bar = ProgressBar::new(args.frames);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {msg}")
                .expect("valid template"),
        );
        bar
    });
    let say = |line: String| match &bar {
        Some(bar) => bar.println(line),
        None => println!("{line}"),
    };
    let frames_per_line = ((0.5 / args.delta_seconds).round() as u64).max(1);
    let (mut seen, mut missed) = (0, 0);
    while seen < args.frames {
        let snapshot = match super::watch::next_frame(client, timeout) {
            Ok(Some(view)) => view.to_snapshot(),
            Ok(None) => break,
            Err(e) => return Err(anyhow!(e).into()),
        };
        seen += 1;
        missed += snapshot.missed;
        if let Some(bar) = &bar {
            bar.set_position(seen);
            bar.set_message(format!(
                "t = {:.2} s",
                snapshot.timestamp().elapsed_seconds()
            ));
        }
        if seen == 1 {
            drive_cars(client, &snapshot)?;
        }
        if seen == 1 || snapshot.frame() % frames_per_line == 0 {
            say(summary(&snapshot));
        }
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    Ok((seen, missed))
}
