//! `simbus-scenario WORLD STEPS SEED`: the crash loop's driver. It ticks a
//! synchronous world through a seeded scenario — boxes and walkers
//! spawned, impulses, a vehicle driven, walkers walked, a reload at step
//! 1000, a depth camera and a lidar —
//! and prints one JSON line per frame it reads: step, episode, frame,
//! digest and a hash of each sensor's capture of that frame.
//!
//! The commands of each step are a function of the seed, the step and
//! the frame before it, nothing else, so a driver that rides through a
//! server restart (its `Ticker` claims the resumed world again, its
//! `Client` reconnects) goes on from the frame the world resumed at and
//! sends the commands of the frames after it again. The test
//! (`tests/tests/journal.rs`) compares its lines with an uninterrupted
//! run's.

use std::time::Duration;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared_types::{ActorKind, Command, FrameHeader, SensorSpec, WorldSettings};
use sim_client::{Client, Sensor, TickError, Ticker, WorldSnapshot};

/// The step at which the world is reloaded (a new episode).
const RELOAD_AT: u64 = 1000;
/// How long anything waits, a restart included.
const WAIT: Duration = Duration::from_secs(30);

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, world, steps, seed] = args.as_slice() else {
        eprintln!("usage: simbus-scenario WORLD STEPS SEED");
        std::process::exit(2);
    };
    let steps: u64 = steps.parse().expect("STEPS: a number");
    let seed: u64 = seed.parse().expect("SEED: a number");
    let mut client = Client::connect(world, WAIT).expect("connect");
    let mut ticker = client.claim_ticker().expect("claim");
    ticker.set_follow_restarts(Some(WAIT));
    ticker
        .apply_settings(WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.05),
            ..WorldSettings::default()
        })
        .expect("synchronous mode");
    let mut sensors = sensors(&client);
    let mut first_episode = None;
    let mut now = client.wait_for_tick(WAIT).expect("the first frame");
    loop {
        let first = *first_episode.get_or_insert(now.episode());
        let step = step_of(&now, first);
        print(step, &now, &mut sensors);
        if step >= steps {
            break;
        }
        let reloading = step == RELOAD_AT && now.frame() == RELOAD_AT;
        match advance(&client, &mut ticker, &now, seed, step) {
            Ok(()) if reloading => match client.wait_for_tick(WAIT) {
                Ok(next) => {
                    now = next;
                    sensors = self::sensors(&client);
                }
                Err(e) => {
                    eprintln!("reading the reloaded frame: {e}");
                    now = recover(&mut client, &mut ticker, &mut sensors);
                }
            },
            Ok(()) => match client.wait_for_tick(WAIT) {
                Ok(next) => now = next,
                Err(e) => {
                    eprintln!("reading the frame: {e}");
                    now = recover(&mut client, &mut ticker, &mut sensors);
                }
            },
            Err(e) => {
                eprintln!("step {step}: {e}");
                now = recover(&mut client, &mut ticker, &mut sensors);
            }
        }
    }
    ticker.release().expect("release");
}

/// Steps from the run's start: episode 1's frames, then the reloaded
/// episode's after [`RELOAD_AT`].
fn step_of(now: &WorldSnapshot, first_episode: u64) -> u64 {
    if now.episode() == first_episode {
        now.frame()
    } else {
        RELOAD_AT + now.frame()
    }
}

/// Sends `step`'s commands and ticks (or reloads at [`RELOAD_AT`]).
fn advance(
    client: &Client,
    ticker: &mut Ticker,
    now: &WorldSnapshot,
    seed: u64,
    step: u64,
) -> Result<(), String> {
    if step == RELOAD_AT && now.frame() == RELOAD_AT {
        // The reload ends the episode's sensors; the loop spawns new ones.
        return client
            .reload_world(false)
            .map(drop)
            .map_err(|e| e.to_string());
    }
    let commands = commands(now, seed, step);
    if !commands.is_empty() {
        client
            .apply_batch_sync(&commands, false)
            .map_err(|e| e.to_string())?;
    }
    match ticker.tick(WAIT) {
        Ok(_) => Ok(()),
        Err(TickError::Restarted(r)) => Err(r.to_string()),
        Err(e) => panic!("tick: {e}"),
    }
}

/// The commands of `step`: a function of the seed, the step and the
/// frame before it.
fn commands(now: &WorldSnapshot, seed: u64, step: u64) -> Vec<Command> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ step.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut commands = Vec::new();
    if step % 50 == 7 {
        let at = [
            rng.random_range(-8.0..8.0),
            6.0,
            rng.random_range(-8.0..8.0),
        ];
        commands.push(Command::spawn_box(at, [0.4, 0.4, 0.4]));
    }
    if step % 9 == 3 {
        let dynamic: Vec<_> = now
            .actors
            .iter()
            .filter(|a| a.kind != ActorKind::Static as u32)
            .collect();
        if !dynamic.is_empty() {
            let actor = dynamic[rng.random_range(0..dynamic.len())];
            let push = [rng.random_range(-3.0..3.0), rng.random_range(0.0..4.0), 0.0];
            commands.push(Command::apply_impulse(actor.id, push));
        }
    }
    if step % 50 == 17 {
        // On the ground (centre at its surface: the walker stands on it),
        // or refused where something is.
        let at = [
            rng.random_range(-12.0..12.0),
            0.0,
            rng.random_range(-12.0..12.0),
        ];
        commands.push(Command::spawn_walker(at, 0.25, 0.9));
    }
    if step % 15 == 4 {
        let walkers: Vec<_> = now
            .actors
            .iter()
            .filter(|a| a.kind == ActorKind::Walker as u32)
            .collect();
        if !walkers.is_empty() {
            let walker = walkers[rng.random_range(0..walkers.len())];
            let direction = [
                rng.random_range(-1.0..1.0),
                0.0,
                rng.random_range(-1.0..1.0),
            ];
            let speed = rng.random_range(0.0..2.5);
            commands.push(Command::walker_control(
                walker.id,
                direction,
                speed,
                step % 45 == 4,
            ));
        }
    }
    if step.is_multiple_of(20) {
        if let Some(vehicle) = now
            .actors
            .iter()
            .find(|a| a.kind == ActorKind::Vehicle as u32)
        {
            let throttle = rng.random_range(0.2..0.9);
            let steer = rng.random_range(-0.5..0.5);
            commands.push(Command::vehicle_control(
                vehicle.id, throttle, steer, 0.0, false,
            ));
        }
    }
    commands
}

/// The episode's two sensors: those the world has (a resumed world brings
/// them back under their ids), else spawned now.
fn sensors(client: &Client) -> Vec<Sensor> {
    let alive = client.list_sensors().expect("the sensor list");
    if !alive.is_empty() {
        return alive
            .iter()
            .map(|info| client.sensor(info.id).expect("a reader"))
            .collect();
    }
    let depth = SensorSpec::depth([0.0, 4.0, -14.0], 48, 32, 80.0, 60.0);
    let lidar = SensorSpec::lidar([0.0, 3.0, 0.0], 8, 90, 40.0, 10.0, -30.0);
    [depth, lidar]
        .into_iter()
        .map(|spec| client.spawn_sensor(spec).expect("sensor"))
        .collect()
}

/// Prints `now` with a hash of each sensor's capture of its frame.
fn print(step: u64, now: &WorldSnapshot, sensors: &mut [Sensor]) {
    let captures: Vec<String> = sensors
        .iter_mut()
        .map(|sensor| capture_of(sensor, now))
        .collect();
    println!(
        "{}",
        serde_json::json!({
            "step": step,
            "episode": now.episode(),
            "frame": now.frame(),
            "digest": format!("{:016x}", now.digest()),
            "captures": captures,
        })
    );
}

/// A hash of `sensor`'s capture of `now`'s frame ("-" when it has none:
/// a frame published without a step, or the sensor ended).
fn capture_of(sensor: &mut Sensor, now: &WorldSnapshot) -> String {
    // Not stepped (a load's, a reload's, a resumed server's first frame):
    // nothing was captured for it.
    if now.header.flags & FrameHeader::STEPPED == 0 {
        return "-".into();
    }
    loop {
        match sensor.recv(Duration::from_secs(5)) {
            Ok(capture) if capture.header().frame < now.frame() => continue,
            Ok(capture) if capture.header().frame == now.frame() => {
                return format!("{:016x}", xxhash(capture.bytes()));
            }
            _ => return "-".into(),
        }
    }
}

fn xxhash(bytes: &[u8]) -> u64 {
    // FNV-1a: enough to tell captures apart.
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3)
    })
}

/// The server restarted: reconnect, claim the resumed world, reopen the
/// sensors (same ids), and return the frame it resumed at.
fn recover(client: &mut Client, ticker: &mut Ticker, sensors: &mut Vec<Sensor>) -> WorldSnapshot {
    if !sim_client::process_alive(client.server_pid()) {
        let r = client.reconnect(WAIT).expect("a server came back");
        eprintln!("{r}");
    }
    if ticker.server_pid() != client.server_pid() {
        match ticker.reclaim(WAIT) {
            Ok(r) => eprintln!("ticker: {r}"),
            Err(e) => panic!("claiming the resumed world: {e}"),
        }
    }
    let now = client.wait_for_tick(WAIT).expect("the resumed frame");
    println!(
        "{}",
        serde_json::json!({"restarted": now.frame(), "episode": now.episode()})
    );
    *sensors = self::sensors(client);
    now
}
