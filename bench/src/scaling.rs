//! `frames`' scaling rows: the bus as the world grows. For `boxes:N`
//! (N boxes dropped in a grid onto the ground: they fall, land on each
//! other, topple and come to rest), an unpaced asynchronous server in this
//! process times every frame (`Server::time_frames`): rapier's own pipeline
//! step (every substep, nothing else) and the whole frame, from one frame's
//! beginning to the next (step, snapshot writing, publishing, the loop's
//! bookkeeping). What the whole frame adds to the step is the server's
//! cost beyond physics — the bus.
//!
//! Each N is run twice: with no subscriber (frames 1..=F of the episode,
//! the same simulated seconds for every N), and with one subscriber process
//! (the hidden `peer --kind frame-reader`) that, for each frame it gets,
//! reads every actor's pose in place in shared memory and times it from
//! holding the sample to done: from the frame's packed poses
//! (`FrameView::poses`, 48 bytes an actor), the read a reader of where
//! things are makes, and on other frames from the actors' whole 96-byte
//! records (`FrameView::actors`), the read of a reader of everything.
//!
//! Each read has its floor in the same reader on the same frames: one word
//! of every cache line it spans and nothing else (what bringing its bytes
//! to the reader's core costs, with nothing added), on other frames. The
//! packed read is also repeated straight after (the frame now in the
//! reader's cache: what the additions cost). The kinds take turns frame by
//! frame, so each reads frames as fresh from the server as the others'.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use shared_types::{WorldName, WorldSettings};
use sim_client::{Client, WaitMode};
use sim_server::{FrameTime, Scene, Server, ServerConfig};
use simbus_process::ChildGuard;

use crate::stats::Latencies;

/// Frames at the start of each run left out (first contacts, cold caches).
const WARMUP_FRAMES: usize = 5;

/// The per-frame figures of one run.
pub(crate) struct Timed {
    /// rapier's pipeline step per frame.
    physics: Latencies,
    /// The whole frame.
    whole: Latencies,
    /// Whole frame minus rapier's step, per frame.
    bus: Latencies,
    /// Σ(whole − step) / Σ step over the run.
    overhead: f64,
    frames: usize,
}

impl Timed {
    fn of(frames: &[FrameTime]) -> anyhow::Result<Self> {
        anyhow::ensure!(!frames.is_empty(), "no frame was timed");
        let (mut physics, mut whole, mut bus) =
            (Latencies::new(), Latencies::new(), Latencies::new());
        let (mut sum_physics, mut sum_whole) = (0u128, 0u128);
        for f in frames {
            let (p, w) = (f.physics.as_nanos(), f.whole.as_nanos());
            physics.record(p as u64);
            whole.record(w as u64);
            bus.record(w.saturating_sub(p) as u64);
            sum_physics += p;
            sum_whole += w;
        }
        Ok(Self {
            physics,
            whole,
            bus,
            overhead: (sum_whole as f64 - sum_physics as f64) / (sum_physics.max(1) as f64),
            frames: frames.len(),
        })
    }

    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "frames": self.frames,
            "rapier_step": self.physics.json(),
            "server_frame": self.whole.json(),
            "bus": self.bus.json(),
            "overhead": self.overhead,
            "bus_over_step_p50": self.p50_ratio(),
        })
    }

    /// The median frame's bus time over the median rapier step.
    fn p50_ratio(&self) -> f64 {
        self.bus.quantile_us(0.5) / self.physics.quantile_us(0.5).max(0.001)
    }
}

/// One scaling row.
pub(crate) struct Row {
    actors: usize,
    alone: Timed,
    with_reader: Timed,
    /// What its reader measured.
    reader: ReaderReport,
}

/// What the reader peer measured (ns each), on frames as fresh from the
/// server as each other.
struct ReaderReport {
    /// From holding a frame to having read every packed pose.
    poses: Latencies,
    /// The same read again straight after, the frame in cache.
    warm: Latencies,
    /// One word of every cache line of a frame's packed poses.
    poses_floor: Latencies,
    /// From holding a frame to having read every pose from the actors'
    /// whole records.
    records: Latencies,
    /// One word of every cache line of a frame's actors.
    records_floor: Latencies,
}

impl ReaderReport {
    /// The report's lines, in the order the reader prints them.
    fn parse(lines: &[String]) -> anyhow::Result<Self> {
        let [poses, warm, poses_floor, records, records_floor] = lines else {
            anyhow::bail!("the frame reader's report ended early");
        };
        let parse = |line: &str| -> anyhow::Result<Latencies> {
            let mut latencies = Latencies::new();
            for item in line.split_whitespace() {
                latencies.record(item.parse()?);
            }
            Ok(latencies)
        };
        Ok(Self {
            poses: parse(poses)?,
            warm: parse(warm)?,
            poses_floor: parse(poses_floor)?,
            records: parse(records)?,
            records_floor: parse(records_floor)?,
        })
    }

    /// A read's p50 over its floor's.
    fn over_floor(read: &Latencies, floor: &Latencies) -> f64 {
        read.quantile_us(0.5) / floor.quantile_us(0.5).max(0.001)
    }
}

/// The configuration of a timed run: `boxes:n`, async, fixed step 0.01 s
/// (one substep of the default 0.01 s), unpaced.
fn config(n: u32, tag: &str, max_frames: Option<u64>) -> anyhow::Result<ServerConfig> {
    Ok(ServerConfig {
        scene: Scene::Boxes(n),
        settings: WorldSettings {
            fixed_delta_seconds: Some(0.01),
            ..Default::default()
        },
        max_fps: 0.0,
        max_frames,
        wait_mode: shared_types::WaitMode::Block,
        ..ServerConfig::new(WorldName::new(&format!(
            "bench-scale-{tag}-{n}-{}",
            std::process::id()
        ))?)
    })
}

/// Frames 1..=`frames` of `boxes:n` with no subscriber.
fn alone(n: u32, frames: usize) -> anyhow::Result<(usize, Timed)> {
    let mut server = Server::start(config(n, "alone", Some(frames as u64 + 1))?)?;
    server.time_frames(frames + 1);
    server.run(&AtomicBool::new(false))?;
    let timed: Vec<FrameTime> = server
        .frame_timings()
        .context("frame timings")?
        .frames()
        .skip(WARMUP_FRAMES)
        .collect();
    let actors = n as usize + 1;
    Ok((actors, Timed::of(&timed)?))
}

/// `boxes:n` with one reader process, until it has read `reads` frames.
fn with_reader(n: u32, reads: u64) -> anyhow::Result<(Timed, ReaderReport)> {
    let config = config(n, "reader", None)?;
    let world = config.world.to_string();
    let mut server = Server::start(config)?;
    server.time_frames(1 << 20);
    let mut child = Command::new(std::env::current_exe()?)
        .args(["peer", "--kind", "frame-reader", "--name", &world])
        .args(["--samples", &reads.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("starting the frame reader")?;
    let stdout = child.stdout.take().context("reader stdout")?;
    let guard = ChildGuard::new(child, Duration::from_secs(2));
    let shutdown = AtomicBool::new(false);
    let (ready, report) = std::thread::scope(|scope| {
        let listener = scope.spawn(|| {
            let mut lines = BufReader::new(stdout).lines().map_while(Result::ok);
            let ready = lines
                .next()
                .filter(|l| l == "ready")
                .map(|_| Instant::now());
            let report: Vec<String> = lines.by_ref().take(5).collect();
            shutdown.store(true, Ordering::Relaxed);
            (ready, report)
        });
        let run = server.run(&shutdown);
        let heard = listener.join().expect("the reader's listener");
        run.map(|_| heard)
    })?;
    drop(guard);
    let ready = ready.context("the frame reader did not start")?;
    let report = ReaderReport::parse(&report)?;
    let timed: Vec<FrameTime> = server
        .frame_timings()
        .context("frame timings")?
        .frames()
        .filter(|f| f.started >= ready)
        .collect();
    anyhow::ensure!(
        !timed.is_empty(),
        "the reader read its {reads} frames of boxes:{n} before the server timed a frame after \
         the reader was ready: give --scale-reads more frames"
    );
    Ok((Timed::of(&timed)?, report))
}

/// Every row, one per actor count.
pub(crate) fn rows(boxes: &[u32], frames: usize, reads: u64) -> anyhow::Result<Vec<Row>> {
    boxes
        .iter()
        .map(|&n| {
            let (actors, quiet) = alone(n, frames)?;
            let (read, reader) = with_reader(n, reads)?;
            Ok(Row {
                actors,
                alone: quiet,
                with_reader: read,
                reader,
            })
        })
        .collect()
}

/// The rows as JSON.
pub(crate) fn json(rows: &[Row]) -> serde_json::Value {
    let rows: Vec<_> = rows
        .iter()
        .map(|r| {
            serde_json::json!({
                "actors": r.actors,
                "no_subscriber": r.alone.json(),
                "one_reader": r.with_reader.json(),
                "reader_reads_poses_in_place": r.reader.poses.json(),
                "reader_reads_them_again_warm": r.reader.warm.json(),
                "reader_touches_every_line_of_the_poses": r.reader.poses_floor.json(),
                "poses_over_floor_p50": ReaderReport::over_floor(&r.reader.poses, &r.reader.poses_floor),
                "reader_reads_poses_from_the_records": r.reader.records.json(),
                "reader_touches_every_line_of_the_records": r.reader.records_floor.json(),
                "records_over_floor_p50": ReaderReport::over_floor(&r.reader.records, &r.reader.records_floor),
            })
        })
        .collect();
    serde_json::Value::Array(rows)
}

/// The rows as a table.
pub(crate) fn print(rows: &[Row], frames: usize) {
    println!(
        "the bus as the world grows: boxes:N (falling, landing, resting), async, fixed step 0.01 s \
         (1 substep), unpaced, in this process; frames {}..={frames}",
        WARMUP_FRAMES + 1
    );
    println!(
        "{:>6} {:>17} {:>17} {:>13} {:>6} {:>6} | {:>13} {:>6} {:>6} | {:>11} {:>6} {:>6} {:>6} | {:>7} {:>6} {:>6}",
        "actors",
        "rapier step µs",
        "server frame µs",
        "bus µs",
        "over-",
        "p50",
        "bus, 1 reader",
        "over-",
        "p50",
        "poses µs",
        "floor",
        "read /",
        "warm",
        "records",
        "floor",
        "read /"
    );
    println!(
        "{:>6} {:>17} {:>17} {:>13} {:>6} {:>6} | {:>13} {:>6} {:>6} | {:>11} {:>6} {:>6} {:>6} | {:>7} {:>6} {:>6}",
        "",
        "p50 / p99",
        "p50 / p99",
        "p50 / p99",
        "head",
        "ratio",
        "p50 / p99",
        "head",
        "ratio",
        "p50 / p99",
        "p50",
        "floor",
        "p50",
        "p50",
        "p50",
        "floor"
    );
    let pair = |l: &Latencies| format!("{:.1} / {:.1}", l.quantile_us(0.5), l.quantile_us(0.99));
    for r in rows {
        let reader = &r.reader;
        println!(
            "{:>6} {:>17} {:>17} {:>13} {:>5.1}% {:>5.1}% | {:>13} {:>5.1}% {:>5.1}% | {:>11} {:>6.1} {:>5.2}x {:>6.1} | {:>7.1} {:>6.1} {:>5.2}x",
            r.actors,
            pair(&r.alone.physics),
            pair(&r.alone.whole),
            pair(&r.alone.bus),
            r.alone.overhead * 100.0,
            r.alone.p50_ratio() * 100.0,
            pair(&r.with_reader.bus),
            r.with_reader.overhead * 100.0,
            r.with_reader.p50_ratio() * 100.0,
            pair(&reader.poses),
            reader.poses_floor.quantile_us(0.5),
            ReaderReport::over_floor(&reader.poses, &reader.poses_floor),
            reader.warm.quantile_us(0.5),
            reader.records.quantile_us(0.5),
            reader.records_floor.quantile_us(0.5),
            ReaderReport::over_floor(&reader.records, &reader.records_floor),
        );
    }
    println!(
        "bus: server frame − rapier step, per frame; overhead: Σ bus / Σ rapier step; p50 ratio: \
         bus p50 / rapier step p50; poses: one subscriber process sums every actor's position \
         and rotation from the frame's packed poses in place, timed from holding the frame to \
         done; floor: one word of every cache line the read spans, on other frames (what \
         moving its bytes costs); warm: the same read again straight after; records: the same \
         sums from the actors' whole records, on other frames again"
    );
}

/// The `frame-reader` peer: prints `ready`, then reads `samples` frames,
/// and prints five lines of
/// nanoseconds: each packed read, each warm re-read of the same frame
/// straight after, each touch of the poses' lines, each read from the
/// whole records, each touch of the records' lines. The kinds take turns
/// frame by frame, so each reads frames as fresh from the server as the
/// others'. Fewer if frames stop coming for 5 s.
pub(crate) fn reader(world: &str, samples: u64) -> anyhow::Result<()> {
    let mut client = Client::connect(world, Duration::from_secs(30))?;
    client.set_wait_mode(WaitMode::Block);
    println!("ready");
    let capacity = samples as usize / 4 + 1;
    let [mut poses, mut warm, mut poses_floor, mut records, mut records_floor] =
        std::array::from_fn::<Vec<u64>, 5, _>(|_| Vec::with_capacity(capacity));
    let mut total = [0.0f32; 7];
    let mut touched = 0u64;
    let mut turn = 0usize;
    while (turn as u64) < samples {
        let Ok(view) = client.wait_for_frame(Duration::from_secs(5)) else {
            break;
        };
        let held = Instant::now();
        match turn % 4 {
            0 => {
                let sum = sum_poses(view.poses(), |p| (p.position, p.rotation));
                poses.push(held.elapsed().as_nanos() as u64);
                let again = Instant::now();
                let sum_again = sum_poses(view.poses(), |p| (p.position, p.rotation));
                warm.push(again.elapsed().as_nanos() as u64);
                for ((t, s), a) in total.iter_mut().zip(sum).zip(sum_again) {
                    *t += s + a;
                }
            }
            1 => {
                touched = touched.wrapping_add(touch_every_line(view.poses(), |p| {
                    [p.id, u64::from(p.rotation[1].to_bits())]
                }));
                poses_floor.push(held.elapsed().as_nanos() as u64);
            }
            2 => {
                let sum = sum_poses(view.actors(), |a| (a.position, a.rotation));
                records.push(held.elapsed().as_nanos() as u64);
                for (t, s) in total.iter_mut().zip(sum) {
                    *t += s;
                }
            }
            _ => {
                touched = touched.wrapping_add(touch_every_line(view.actors(), |a| {
                    [
                        a.id,
                        u64::from(a.rotation[1].to_bits()),
                        u64::from(a.angular_velocity[2].to_bits()),
                    ]
                }));
                records_floor.push(held.elapsed().as_nanos() as u64);
            }
        }
        turn += 1;
    }
    std::hint::black_box((total, touched));
    for timings in [poses, warm, poses_floor, records, records_floor] {
        let line: Vec<String> = timings.iter().map(u64::to_string).collect();
        println!("{}", line.join(" "));
    }
    Ok(())
}

/// Every item's position and rotation, summed: seven independent sums,
/// so the read is bound by memory, not by one chain of dependent additions.
fn sum_poses<T>(items: &[T], pose: impl Fn(&T) -> ([f32; 3], [f32; 4])) -> [f32; 7] {
    let mut sum = [0.0f32; 7];
    for item in items {
        let (p, q) = pose(item);
        for (s, v) in sum.iter_mut().zip(p.iter().chain(&q)) {
            *s += v;
        }
    }
    std::hint::black_box(sum)
}

/// One word of every 64-byte line `items` span, and nothing else: `words`
/// gives words of an item no more than 32 bytes apart (an `ActorState`'s
/// id at 0, `rotation[1]` at 32 and `angular_velocity[2]` at 64; an
/// `ActorPose`'s id at 0 and `rotation[1]` at 32, the next pose's id 16
/// bytes later), so at least one falls in every line, wherever the frame
/// begins.
fn touch_every_line<T, const N: usize>(items: &[T], words: impl Fn(&T) -> [u64; N]) -> u64 {
    let mut acc = 0u64;
    for item in items {
        for word in words(item) {
            acc = acc.wrapping_add(word);
        }
    }
    std::hint::black_box(acc)
}
