//! Stamps of the tick path: the `CLOCK_MONOTONIC` time at which each stage
//! of a synchronous round trip happened, in whichever process it happened.
//! `CLOCK_MONOTONIC` is one clock for every process of the machine, so a
//! client's and a server's stamps of the same frame line up.
//!
//! Off unless a process turns it on ([`enable`], or [`SIMBUS_STAMPS`] for
//! the `sim-server` binary): a stage then costs one relaxed atomic load.
//! `simbus-bench tick --breakdown` turns it on in its client and in the
//! server it starts, and prints the median of every stage.
//!
//! ```
//! use simbus_transport::stamps::{self, Stage};
//!
//! stamps::stamp(Stage::ClientSend, 1); // off: nothing kept
//! stamps::enable(16);
//! stamps::stamp(Stage::ClientSend, 2);
//! let kept = stamps::take();
//! assert_eq!(kept.len(), 1);
//! assert_eq!((kept[0].stage, kept[0].frame), (Stage::ClientSend, 2));
//! ```

use std::io::{BufRead, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

/// The environment variable that makes `sim-server` keep stamps and write
/// them, one `stage frame ns` line each, to the file it names when it stops.
pub const SIMBUS_STAMPS: &str = "SIMBUS_STAMPS";

/// A stage of the synchronous tick round trip, in the order they happen.
/// The `Mirror…` and `Export…` stages are those of a tick through the
/// Zenoh bridges (a ticker on the mirror's host).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stage {
    /// The client is about to send the tick request.
    ClientSend,
    /// The mirror took the local ticker's request.
    MirrorTakes,
    /// The mirror's Zenoh publication of the tick returned.
    MirrorAsked,
    /// The exporter's Zenoh callback has the tick.
    ExportGets,
    /// The exporter's frame thread sent the tick to the server.
    ExportSends,
    /// The server's loop woke from its sleep (or, spinning, found the tick).
    ServerWake,
    /// The server's ticker domain took the tick request.
    ServerTick,
    /// Physics begins.
    StepBegin,
    /// Physics ends.
    StepEnd,
    /// The frame's snapshot is published.
    Published,
    /// The tick's answer is sent.
    Answered,
    /// The frame-ready event is notified (waiting clients wake now).
    Notified,
    /// The exporter's frame thread took the server's answer.
    ExportTakes,
    /// The exporter's Zenoh publication of the frame (the answer attached)
    /// returned.
    ExportPuts,
    /// The mirror's Zenoh callback has the frame.
    MirrorGets,
    /// The mirror published the frame in its host's shared memory.
    MirrorPublishes,
    /// The mirror sent the local ticker its answer.
    MirrorAnswers,
    /// The client's wait returned (woken, or its poll found the answer).
    ClientWake,
    /// The client holds the frame's snapshot.
    ClientHolds,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 19] = [
        Stage::ClientSend,
        Stage::MirrorTakes,
        Stage::MirrorAsked,
        Stage::ExportGets,
        Stage::ExportSends,
        Stage::ServerWake,
        Stage::ServerTick,
        Stage::StepBegin,
        Stage::StepEnd,
        Stage::Published,
        Stage::Answered,
        Stage::Notified,
        Stage::ExportTakes,
        Stage::ExportPuts,
        Stage::MirrorGets,
        Stage::MirrorPublishes,
        Stage::MirrorAnswers,
        Stage::ClientWake,
        Stage::ClientHolds,
    ];

    /// The stage's name in files and tables.
    pub fn name(self) -> &'static str {
        match self {
            Stage::ClientSend => "client_send",
            Stage::MirrorTakes => "mirror_takes",
            Stage::MirrorAsked => "mirror_asked",
            Stage::ExportGets => "export_gets",
            Stage::ExportSends => "export_sends",
            Stage::ServerWake => "server_wake",
            Stage::ServerTick => "server_tick",
            Stage::StepBegin => "step_begin",
            Stage::StepEnd => "step_end",
            Stage::Published => "published",
            Stage::Answered => "answered",
            Stage::Notified => "notified",
            Stage::ExportTakes => "export_takes",
            Stage::ExportPuts => "export_puts",
            Stage::MirrorGets => "mirror_gets",
            Stage::MirrorPublishes => "mirror_publishes",
            Stage::MirrorAnswers => "mirror_answers",
            Stage::ClientWake => "client_wake",
            Stage::ClientHolds => "client_holds",
        }
    }

    /// The stage named `name`.
    pub fn from_name(name: &str) -> Option<Stage> {
        Stage::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// One stage of one frame, at `ns` nanoseconds of `CLOCK_MONOTONIC`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    /// What happened.
    pub stage: Stage,
    /// The frame the round trip computes.
    pub frame: u64,
    /// When, in `CLOCK_MONOTONIC` nanoseconds.
    pub ns: u64,
}

static ENABLED: AtomicBool = AtomicBool::new(false);
static KEPT: Mutex<Vec<Stamp>> = Mutex::new(Vec::new());
/// When the last wait of this process returned (see [`woke`]).
static LAST_WAKE: AtomicU64 = AtomicU64::new(0);
/// When this process last began waiting for a round trip's next stage: a
/// client when it sent, a server when it notified.
static LAST_START: AtomicU64 = AtomicU64::new(0);
/// The frame this process's next round trip computes, for a thread that
/// cannot know it (a Zenoh callback): see [`expect`].
static EXPECTED: AtomicU64 = AtomicU64::new(0);

/// `CLOCK_MONOTONIC` now, in nanoseconds.
pub fn now_ns() -> u64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid timespec for clock_gettime to write.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    (now.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(now.tv_nsec as u64)
}

/// Starts keeping stamps (room for `capacity` reserved now, so keeping one
/// does not allocate on the path it measures).
pub fn enable(capacity: usize) {
    if let Ok(mut kept) = KEPT.lock() {
        kept.reserve(capacity);
    }
    ENABLED.store(true, Ordering::Relaxed);
}

/// Whether this process keeps stamps.
#[inline]
pub fn enabled() -> bool {
    ENABLED.load(Ordering::Relaxed)
}

/// Keeps `stage` of `frame` as happening now (nothing when off).
#[inline]
pub fn stamp(stage: Stage, frame: u64) {
    if enabled() {
        stamp_at(stage, frame, now_ns());
    }
}

/// Notes that the next round trip this process takes part in computes
/// `frame`, for [`stamp_expected`] on a thread that cannot know it.
#[inline]
pub fn expect(frame: u64) {
    if enabled() {
        EXPECTED.store(frame, Ordering::Relaxed);
    }
}

/// Keeps `stage` as happening now, for the frame last [`expect`]ed.
#[inline]
pub fn stamp_expected(stage: Stage) {
    if enabled() {
        stamp_at(stage, EXPECTED.load(Ordering::Relaxed), now_ns());
    }
}

/// Keeps `stage` of `frame` as happening at `ns` (nothing when off).
pub fn stamp_at(stage: Stage, frame: u64, ns: u64) {
    if !enabled() {
        return;
    }
    if stage == Stage::Notified {
        LAST_START.store(ns, Ordering::Relaxed);
    }
    if let Ok(mut kept) = KEPT.lock() {
        kept.push(Stamp { stage, frame, ns });
    }
}

/// Notes that this process begins a round trip now (a client about to
/// send) and returns the time, for [`stamp_at`] once the frame is known;
/// 0 when off.
#[inline]
pub fn began() -> u64 {
    if !enabled() {
        return 0;
    }
    let ns = now_ns();
    LAST_START.store(ns, Ordering::Relaxed);
    ns
}

/// Notes that a wait of this process just returned: the next
/// [`stamp_wake`] reports this time.
#[inline]
pub fn woke() {
    if enabled() {
        LAST_WAKE.store(now_ns(), Ordering::Relaxed);
    }
}

/// Keeps `stage` of `frame` at the time of the last [`woke`], or now if
/// this process has not slept since it sent (a client) or notified (a
/// server): it found the work while polling.
pub fn stamp_wake(stage: Stage, frame: u64) {
    if !enabled() {
        return;
    }
    let last = LAST_WAKE.load(Ordering::Relaxed);
    let ns = if last > LAST_START.load(Ordering::Relaxed) {
        last
    } else {
        now_ns()
    };
    stamp_at(stage, frame, ns);
}

/// The stamps kept so far, which are forgotten.
pub fn take() -> Vec<Stamp> {
    KEPT.lock()
        .map(|mut kept| std::mem::take(&mut *kept))
        .unwrap_or_default()
}

/// Turns stamps on if [`SIMBUS_STAMPS`] names a file; returns that file.
pub fn enable_from_env() -> Option<std::path::PathBuf> {
    let path = std::env::var_os(SIMBUS_STAMPS)?;
    enable(1 << 20);
    Some(path.into())
}

/// Writes `stamps` to `path`, one `stage frame ns` line each.
///
/// # Errors
///
/// Returns the [`std::io::Error`] of creating `path` (a missing directory, no
/// permission) or of writing to it.
pub fn write(path: &Path, stamps: &[Stamp]) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for s in stamps {
        writeln!(out, "{} {} {}", s.stage.name(), s.frame, s.ns)?;
    }
    out.flush()
}

/// Reads stamps [`write()`] wrote; a line that does not read is an error
/// naming it.
///
/// # Errors
///
/// Returns the [`std::io::Error`] of opening or reading `path`, and one of kind
/// [`InvalidData`](std::io::ErrorKind::InvalidData), naming the file, the line
/// number and the line, for a line that is not `stage frame ns` with a known
/// stage name and two whole numbers.
pub fn read(path: &Path) -> std::io::Result<Vec<Stamp>> {
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    let mut stamps = Vec::new();
    for (n, line) in file.lines().enumerate() {
        let line = line?;
        let mut fields = line.split_whitespace();
        let stamp = (|| {
            Some(Stamp {
                stage: Stage::from_name(fields.next()?)?,
                frame: fields.next()?.parse().ok()?,
                ns: fields.next()?.parse().ok()?,
            })
        })();
        match stamp {
            Some(stamp) => stamps.push(stamp),
            None => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("{}:{}: not a stamp: {line:?}", path.display(), n + 1),
                ))
            }
        }
    }
    Ok(stamps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_round_trip_through_a_file_and_bad_lines_are_named() {
        let dir = std::env::temp_dir().join(format!("simbus-stamps-{}", std::process::id()));
        let stamps = vec![
            Stamp {
                stage: Stage::ServerTick,
                frame: 7,
                ns: 123,
            },
            Stamp {
                stage: Stage::Notified,
                frame: 7,
                ns: 456,
            },
        ];
        write(&dir, &stamps).unwrap();
        assert_eq!(read(&dir).unwrap(), stamps);
        std::fs::write(&dir, "server_tick 7 123\nnonsense\n").unwrap();
        let error = read(&dir).unwrap_err().to_string();
        assert!(error.ends_with(":2: not a stamp: \"nonsense\""), "{error}");
        std::fs::remove_file(&dir).unwrap();
        for stage in Stage::ALL {
            assert_eq!(Stage::from_name(stage.name()), Some(stage));
        }
    }

    #[test]
    fn a_stamp_for_the_expected_frame_is_kept_under_that_frame_and_only_when_on() {
        // Off: nothing is kept, whatever was expected.
        expect(41);
        stamp_expected(Stage::MirrorGets);
        assert!(take().is_empty());
        enable(4);
        expect(42);
        stamp_expected(Stage::MirrorGets);
        stamp(Stage::MirrorPublishes, 42);
        let kept = take();
        let kept: Vec<_> = kept.iter().map(|s| (s.stage, s.frame)).collect();
        assert_eq!(
            kept,
            [(Stage::MirrorGets, 42), (Stage::MirrorPublishes, 42)],
            "the callback's stamp lands on the frame the main thread expected"
        );
    }
}
