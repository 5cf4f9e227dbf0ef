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
//! holding the sample to done.
//!
//! Two floors for that read, in the same reader on the same frames: the
//! same poses read again straight after (the frame now in the reader's
//! cache: what the additions cost), and, on every other frame, one word
//! of every cache line of the actors (what bringing the frame's bytes to
//! the reader's core costs, with nothing added). The pose read touches
//! most of those lines (a 28-byte pose every 96 bytes) and never more, so
//! the line floor moves at least its bytes. A third floor, on a third of
//! the frames, touches only the lines the same poses would fill packed
//! (28 of every 96 bytes, as a layout with the poses apart from the rest
//! of the actors' state would hold them): what such a layout would move.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use shared_types::{ActorState, WorldName, WorldSettings};
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
    /// From holding a frame to having read every pose.
    reads: Latencies,
    /// The same read again straight after, the frame in cache.
    warm: Latencies,
    /// One word of every cache line of a frame's actors (other frames).
    lines: Latencies,
    /// One word of every line of the first 28/96 of a frame's actors: the
    /// bytes of its poses, were they packed (other frames again).
    packed: Latencies,
}

impl ReaderReport {
    /// The report's lines, in the order the reader prints them.
    fn parse(lines: &[String]) -> anyhow::Result<Self> {
        let [reads, warm, lines, packed] = lines else {
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
            reads: parse(reads)?,
            warm: parse(warm)?,
            lines: parse(lines)?,
            packed: parse(packed)?,
        })
    }

    /// The pose read's p50 over the line floor's.
    fn read_over_lines(&self) -> f64 {
        self.reads.quantile_us(0.5) / self.lines.quantile_us(0.5).max(0.001)
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
            let report: Vec<String> = lines.by_ref().take(4).collect();
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
                "reader_reads_frame_in_place": r.reader.reads.json(),
                "reader_reads_it_again_warm": r.reader.warm.json(),
                "reader_touches_every_line": r.reader.lines.json(),
                "reader_touches_packed_poses_lines": r.reader.packed.json(),
                "read_over_line_floor_p50": r.reader.read_over_lines(),
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
        "{:>6} {:>17} {:>17} {:>13} {:>6} {:>6} | {:>13} {:>6} {:>6} | {:>11} {:>6} {:>6} {:>6} {:>6}",
        "actors",
        "rapier step µs",
        "server frame µs",
        "bus µs",
        "over-",
        "p50",
        "bus, 1 reader",
        "over-",
        "p50",
        "reader µs",
        "warm",
        "lines",
        "read /",
        "packed"
    );
    println!(
        "{:>6} {:>17} {:>17} {:>13} {:>6} {:>6} | {:>13} {:>6} {:>6} | {:>11} {:>6} {:>6} {:>6} {:>6}",
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
        "p50",
        "lines",
        "p50"
    );
    let pair = |l: &Latencies| format!("{:.1} / {:.1}", l.quantile_us(0.5), l.quantile_us(0.99));
    for r in rows {
        println!(
            "{:>6} {:>17} {:>17} {:>13} {:>5.1}% {:>5.1}% | {:>13} {:>5.1}% {:>5.1}% | {:>11} {:>6.1} {:>6.1} {:>5.2}x {:>6.1}",
            r.actors,
            pair(&r.alone.physics),
            pair(&r.alone.whole),
            pair(&r.alone.bus),
            r.alone.overhead * 100.0,
            r.alone.p50_ratio() * 100.0,
            pair(&r.with_reader.bus),
            r.with_reader.overhead * 100.0,
            r.with_reader.p50_ratio() * 100.0,
            pair(&r.reader.reads),
            r.reader.warm.quantile_us(0.5),
            r.reader.lines.quantile_us(0.5),
            r.reader.read_over_lines(),
            r.reader.packed.quantile_us(0.5)
        );
    }
    println!(
        "bus: server frame − rapier step, per frame; overhead: Σ bus / Σ rapier step; p50 ratio: \
         bus p50 / rapier step p50; reader: one subscriber process sums every actor's position \
         and rotation in place, timed from holding the frame to done; warm: the same read again \
         straight after; lines: one word of every cache line of the actors, on other frames \
         (the memory floor of the read); packed: one word of every line the poses alone would \
         fill (28 of each 96 bytes), on other frames again"
    );
}

/// The `frame-reader` peer: prints `ready`, then reads frames until it
/// has read `samples` frames' poses, and prints four lines of
/// nanoseconds: each pose read, each warm re-read of the same frame
/// straight after, each line touch and each packed-poses touch. The three
/// kinds take turns frame by frame, so each reads frames as fresh from the
/// server as the others'. Fewer if frames stop coming for 5 s.
pub(crate) fn reader(world: &str, samples: u64) -> anyhow::Result<()> {
    let mut client = Client::connect(world, Duration::from_secs(30))?;
    client.set_wait_mode(WaitMode::Block);
    println!("ready");
    let capacity = samples as usize;
    let [mut reads, mut warm, mut lines, mut packed] =
        std::array::from_fn::<Vec<u64>, 4, _>(|_| Vec::with_capacity(capacity));
    let mut total = [0.0f32; 7];
    let mut touched = 0u64;
    while (reads.len() as u64) < samples {
        let Ok(view) = client.wait_for_frame(Duration::from_secs(5)) else {
            break;
        };
        let held = Instant::now();
        let actors = view.actors();
        if lines.len() < reads.len() {
            touched = touched.wrapping_add(touch_every_line(actors));
            lines.push(held.elapsed().as_nanos() as u64);
        } else if packed.len() < reads.len() {
            let poses_bytes = actors.len() * POSE_BYTES / std::mem::size_of::<ActorState>();
            touched = touched.wrapping_add(touch_every_line(&actors[..poses_bytes]));
            packed.push(held.elapsed().as_nanos() as u64);
        } else {
            let sum = sum_poses(actors);
            reads.push(held.elapsed().as_nanos() as u64);
            let again = Instant::now();
            let sum_again = sum_poses(actors);
            warm.push(again.elapsed().as_nanos() as u64);
            for ((t, s), a) in total.iter_mut().zip(sum).zip(sum_again) {
                *t += s + a;
            }
        }
    }
    std::hint::black_box((total, touched));
    for timings in [reads, warm, lines, packed] {
        let line: Vec<String> = timings.iter().map(u64::to_string).collect();
        println!("{}", line.join(" "));
    }
    Ok(())
}

/// A pose's bytes: position and rotation, seven `f32`.
const POSE_BYTES: usize = 7 * 4;

/// Every actor's position and rotation, summed: seven independent sums,
/// so the read is bound by memory, not by one chain of dependent additions.
fn sum_poses(actors: &[ActorState]) -> [f32; 7] {
    let mut sum = [0.0f32; 7];
    for actor in actors {
        let (p, q) = (actor.position, actor.rotation);
        for (s, v) in sum.iter_mut().zip(p.iter().chain(&q)) {
            *s += v;
        }
    }
    std::hint::black_box(sum)
}

/// One word of every 64-byte line the actors span, and nothing else:
/// each 96-byte record's id (offset 0), `rotation[1]` (32) and
/// `angular_velocity[2]` (64) are 32 bytes apart, so at least one falls in
/// every line, wherever the frame begins.
fn touch_every_line(actors: &[ActorState]) -> u64 {
    let mut acc = 0u64;
    for actor in actors {
        acc = acc
            .wrapping_add(actor.id)
            .wrapping_add(u64::from(actor.rotation[1].to_bits()))
            .wrapping_add(u64::from(actor.angular_velocity[2].to_bits()));
    }
    std::hint::black_box(acc)
}
