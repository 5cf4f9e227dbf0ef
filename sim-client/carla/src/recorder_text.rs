//! CARLA 0.9.16's texts of a recording: what its server answers to
//! `show_recorder_file_info`, `show_recorder_collisions` and
//! `show_recorder_actors_blocked`, written from a simbus recording in
//! CARLA's layout, so that scripts which print or parse CARLA's answer
//! (`Frames: N`, `Duration: T seconds`, ` Create ID: type_id ...`) read
//! simbus's the same way. The gateway answers these texts; `sim-client
//! recorder info --carla-text` prints the first.
//!
//! What CARLA's recorder writes and simbus's keeps are not the same, so the
//! text says what simbus has in CARLA's words: frames are numbered from 1
//! and timed from the recording's start (as CARLA's are); actors appear as
//! `Create` in the first frame they are in and `Destroy` after the last,
//! with the type id the gateway gives their kind, CARLA's actor type
//! (1 vehicle, 0 other), CARLA's axes and units (centimetres, degrees as
//! roll, pitch, yaw), and no blueprint attributes (a recording keeps none).
//! Numbers are written as C++'s streams write them (six significant
//! digits), and `Date:` in the local time zone, as CARLA's server does.
//!
//! ```no_run
//! let text = simbus_carla::recorder_text::file_info("run.mcap", false)?;
//! let frames = text.lines().find_map(|l| l.strip_prefix("Frames: "));
//! # Ok::<(), simbus_recording::RecordingError>(())
//! ```

use std::collections::BTreeSet;
use std::fmt::Write as _;

use shared_types::{
    ActorKind, ActorState, CommandKind, CommandStatus, LightReading, NANOS_PER_SECOND,
};
use simbus_recording::inspect::{self, BlockedActor};
use simbus_recording::{
    Entry, RecordedCollision, RecordingError, RecordingHeader, RecordingReader,
};

use crate::convert;
use crate::records::type_id;

/// CARLA's actor type number in a `Create` line: 1 vehicle, 2 walker, 0
/// other (CARLA's 3 traffic light does not occur in simbus).
fn actor_type(kind: u32) -> u8 {
    match ActorKind::from_u32(kind) {
        Some(ActorKind::Vehicle) => 1,
        Some(ActorKind::Walker) => 2,
        _ => 0,
    }
}

/// CARLA's collision category letter of an actor: `v` vehicle, `w`
/// walker, `o` other.
fn category(kind: u32) -> char {
    match ActorKind::from_u32(kind) {
        Some(ActorKind::Vehicle) => 'v',
        Some(ActorKind::Walker) => 'w',
        _ => 'o',
    }
}

/// The name simbus gives actor kind `kind` (`box`, `vehicle`, ...).
fn kind_name(kind: u32) -> &'static str {
    ActorKind::from_u32(kind).map_or("unknown", |k| k.name())
}

fn seconds(ns: u64) -> f64 {
    ns as f64 / NANOS_PER_SECOND as f64
}

/// `x` as C++'s `std::ostream << double` writes it by default (`%g`: six
/// significant digits, trailing zeros dropped, an exponent past 1e6 or
/// under 1e-4).
pub(crate) fn cpp_number(x: f64) -> String {
    if x.is_nan() {
        return if x.is_sign_negative() { "-nan" } else { "nan" }.to_string();
    }
    if x.is_infinite() {
        return if x < 0.0 { "-inf" } else { "inf" }.to_string();
    }
    if x == 0.0 {
        return if x.is_sign_negative() { "-0" } else { "0" }.to_string();
    }
    let trim = |s: &str| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s.to_string()
        }
    };
    // The decimal exponent after rounding to six significant digits.
    let scientific = format!("{x:.5e}");
    let (mantissa, exponent) = scientific.split_once('e').unwrap_or((&scientific, "0"));
    let exponent: i32 = exponent.parse().unwrap_or(0);
    if !(-4..6).contains(&exponent) {
        let sign = if exponent < 0 { '-' } else { '+' };
        format!("{}e{sign}{:02}", trim(mantissa), exponent.abs())
    } else {
        let decimals = usize::try_from(5 - exponent).unwrap_or(0);
        trim(&format!("{x:.decimals$}"))
    }
}

/// Wall-clock seconds since the Unix epoch as C's `strftime("%x %X")` in
/// the C locale, in the local time zone: `MM/DD/YY HH:MM:SS`.
fn date(unix_seconds: f64) -> String {
    let t = unix_seconds as libc::time_t; // saturating; NaN reads as 0
                                          // SAFETY: `tm` is plain data (integers and a pointer that may be null),
                                          // so all zeros is a valid value.
    let mut tm: libc::tm = unsafe { std::mem::zeroed() };
    // SAFETY: both pointers are to live locals of the right types;
    // localtime_r writes only into `tm` and is thread-safe.
    let converted = unsafe { libc::localtime_r(&t, &mut tm) };
    if converted.is_null() {
        return "??/??/?? ??:??:??".to_string();
    }
    format!(
        "{:02}/{:02}/{:02} {:02}:{:02}:{:02}",
        tm.tm_mon + 1,
        tm.tm_mday,
        tm.tm_year.rem_euclid(100),
        tm.tm_hour,
        tm.tm_min,
        tm.tm_sec
    )
}

/// CARLA's first lines of every answer: `Version:`, `Map:`, `Date:` and a
/// blank line.
fn heading(header: &RecordingHeader) -> String {
    format!(
        "Version: {}\nMap: {}\nDate: {}\n\n",
        header.recording_version,
        header.scene,
        date(header.start_platform_timestamp)
    )
}

/// CARLA's last lines: the frames recorded and the seconds they cover.
fn footer(out: &mut String, frames: u64, duration: &str) {
    let _ = write!(out, "\nFrames: {frames}\nDuration: {duration} seconds\n");
}

/// A vector of simbus metres in CARLA's axes and centimetres, as CARLA's
/// recorder writes a location: `(x, y, z)`.
fn centimetres(v: [f32; 3]) -> String {
    let [x, y, z] = convert::vector(v).map(|c| cpp_number(f64::from(c * 100.0)));
    format!("({x}, {y}, {z})")
}

/// An orientation as Unreal's `Euler()`: `(roll, pitch, yaw)` in degrees.
fn euler(q: [f32; 4]) -> String {
    let [pitch, yaw, roll] = convert::rotation(q).map(|c| cpp_number(f64::from(c)));
    format!("({roll}, {pitch}, {yaw})")
}

/// The lines of one frame, written when the next one begins.
#[derive(Debug)]
struct FrameText {
    /// The frame's simbus id (to match its collisions).
    frame: u64,
    /// `Frame N at T seconds`.
    title: String,
    /// Its `Create`, `Destroy` and `Collision` lines.
    events: String,
    /// With `show_all`: its `Positions:` lines.
    positions: String,
}

/// CARLA's `show_recorder_file_info` text, built entry by entry.
#[derive(Debug)]
struct InfoText<'a> {
    out: String,
    /// Type ids the caller knows better than the kind does (a catalog
    /// vehicle's model), by CARLA id.
    names: &'a Names,
    show_all: bool,
    /// Frames so far (CARLA numbers them from 1).
    frames: u64,
    /// The recording time of the last frame, nanoseconds.
    last_ns: u64,
    /// The actors of the last frame.
    alive: BTreeSet<u64>,
    /// Collisions so far (CARLA's collision ids count from 0).
    collisions: u64,
    current: Option<FrameText>,
    /// Collisions read before their frame.
    pending: Vec<RecordedCollision>,
    /// Each traffic light's last state and whether it was frozen.
    lights: std::collections::HashMap<u64, (u8, bool)>,
    /// Actors destroyed since the last frame began.
    destroyed: Vec<u64>,
}

impl<'a> InfoText<'a> {
    fn new(header: &RecordingHeader, show_all: bool, names: &'a Names) -> Self {
        Self {
            out: heading(header),
            names,
            show_all,
            frames: 0,
            last_ns: 0,
            alive: BTreeSet::new(),
            collisions: 0,
            current: None,
            pending: Vec::new(),
            lights: std::collections::HashMap::new(),
            destroyed: Vec::new(),
        }
    }

    fn entry(&mut self, entry: &Entry) {
        match entry {
            Entry::Frame {
                log_ns,
                header,
                actors,
            } => self.frame(*log_ns, header.timestamp.frame, actors),
            // A destroyed actor: its `Destroy` comes with the frame that
            // shows it gone, or, when the file ends before that frame, in
            // the last one.
            Entry::Command(c)
                if c.command.kind == CommandKind::Destroy as u32
                    && c.result.status == CommandStatus::Ok as u32 =>
            {
                self.destroyed.push(c.command.actor);
            }
            Entry::Collision(c) => match &mut self.current {
                Some(current) if current.frame == c.frame => {
                    collision_line(&mut current.events, self.collisions, c);
                    self.collisions += 1;
                }
                _ => self.pending.push(*c),
            },
            _ => {}
        }
    }

    /// Begins a frame: its actors that were not in the last one are
    /// created, those of the last one it lacks destroyed.
    fn frame(&mut self, log_ns: u64, frame: u64, actors: &[ActorState]) {
        self.flush();
        self.frames += 1;
        self.last_ns = log_ns;
        let mut text = FrameText {
            frame,
            title: format!(
                "Frame {} at {} seconds\n",
                self.frames,
                cpp_number(seconds(log_ns))
            ),
            events: String::new(),
            positions: String::new(),
        };
        let now: BTreeSet<u64> = actors.iter().map(|a| a.id).collect();
        for a in actors.iter().filter(|a| !self.alive.contains(&a.id)) {
            let _ = writeln!(
                text.events,
                " Create {}: {} ({}) at {}",
                convert::actor_id(a.id),
                name_of(self.names, a.id, a.kind),
                actor_type(a.kind),
                centimetres(a.position)
            );
        }
        for id in self.alive.difference(&now) {
            let _ = writeln!(text.events, " Destroy {}", convert::actor_id(*id));
        }
        self.destroyed.clear();
        self.alive = now;
        for c in std::mem::take(&mut self.pending) {
            collision_line(&mut text.events, self.collisions, &c);
            self.collisions += 1;
        }
        if self.show_all {
            // The lights whose state changed (all of them at first), as
            // CARLA's recorder keeps them.
            let changed: Vec<(u64, LightReading)> = actors
                .iter()
                .filter_map(|a| Some((a.id, a.light()?)))
                .filter(|(id, light)| {
                    self.lights.get(id).is_none_or(|&(state, frozen)| {
                        (state, frozen) != (light.state as u8, light.frozen)
                    })
                })
                .collect();
            if !changed.is_empty() {
                let _ = writeln!(text.events, " State traffic lights: {}", changed.len());
            }
            for (id, light) in changed {
                let state = char::from(b'0' + light.state as u8);
                let _ = writeln!(
                    text.events,
                    "  Id: {} state: {state} frozen: {} elapsedTime: {}",
                    convert::actor_id(id),
                    u8::from(light.frozen),
                    cpp_number(light.elapsed_seconds)
                );
                self.lights.insert(id, (light.state as u8, light.frozen));
            }
            let _ = writeln!(text.positions, " Positions: {}", actors.len());
            for a in actors {
                let _ = writeln!(
                    text.positions,
                    "  Id: {} Location: {} Rotation: {}",
                    convert::actor_id(a.id),
                    centimetres(a.position),
                    euler(a.rotation)
                );
            }
        }
        self.current = Some(text);
    }

    /// Writes the frame begun last: its title when it has events (every
    /// frame with `show_all`), then its lines.
    fn flush(&mut self) {
        if let Some(text) = self.current.take() {
            if self.show_all || !text.events.is_empty() {
                self.out.push_str(&text.title);
            }
            self.out.push_str(&text.events);
            self.out.push_str(&text.positions);
        }
    }

    fn finish(mut self) -> String {
        if let Some(current) = &mut self.current {
            for id in std::mem::take(&mut self.destroyed) {
                if self.alive.contains(&id) {
                    let _ = writeln!(current.events, " Destroy {}", convert::actor_id(id));
                }
            }
            for c in &self.pending {
                collision_line(&mut current.events, self.collisions, c);
                self.collisions += 1;
            }
        }
        self.flush();
        let duration = cpp_number(seconds(self.last_ns));
        footer(&mut self.out, self.frames, &duration);
        self.out
    }
}

/// CARLA's ` Collision id N between A with B` (no actor is CARLA's hero:
/// a recording keeps no `role_name`).
fn collision_line(out: &mut String, id: u64, c: &RecordedCollision) {
    let _ = writeln!(
        out,
        " Collision id {id} between {} with {}",
        convert::actor_id(c.actor_a),
        convert::actor_id(c.actor_b)
    );
}

/// CARLA's `show_recorder_file_info(name, show_all)` of the recording at
/// `path`: the heading, each frame with events (every frame and its
/// positions with `show_all`), and `Frames:` and `Duration:`.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`RecordingReader::open`] if `path` cannot
/// be opened as a simbus recording, and the first error met reading its
/// messages ([`RecordingError::Corrupt`], [`RecordingError::Malformed`], ...).
pub fn file_info(path: &str, show_all: bool) -> Result<String, RecordingError> {
    file_info_named(path, show_all, &Names::new())
}

/// CARLA's type ids of actors, by CARLA id, where the recording's kinds
/// say less (the gateway knows which catalog model each vehicle it
/// spawned is).
pub type Names = std::collections::HashMap<u32, String>;

/// Where the type ids of recording `path`'s actors are kept: beside it.
fn names_path(path: &std::path::Path) -> std::path::PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".carla-names.json");
    std::path::PathBuf::from(name)
}

/// The largest type-id file read, bytes.
const MAX_NAMES_BYTES: u64 = 16 << 20;

/// Writes `names` beside recording `path` (a JSON object of CARLA id to
/// type id).
///
/// # Errors
///
/// Returns the I/O error of writing the file.
pub fn write_names(path: &std::path::Path, names: &Names) -> std::io::Result<()> {
    let object: serde_json::Map<String, serde_json::Value> = names
        .iter()
        .map(|(id, name)| (id.to_string(), serde_json::Value::from(name.as_str())))
        .collect();
    std::fs::write(
        names_path(path),
        serde_json::Value::Object(object).to_string(),
    )
}

/// The type ids written beside recording `path`, if there are any: none
/// for a missing, too large or malformed file (the kinds' names stand).
pub fn read_names(path: &std::path::Path) -> Names {
    let file = names_path(path);
    let fits = std::fs::metadata(&file).is_ok_and(|m| m.len() <= MAX_NAMES_BYTES);
    let text = if fits {
        std::fs::read_to_string(&file).unwrap_or_default()
    } else {
        String::new()
    };
    let Ok(serde_json::Value::Object(object)) = serde_json::from_str(&text) else {
        return Names::new();
    };
    object
        .into_iter()
        .filter_map(|(id, name)| Some((id.parse().ok()?, name.as_str()?.to_owned())))
        .collect()
}

/// The type id of simbus actor `id` of `kind`: its name in `names`, else
/// its kind's.
fn name_of(names: &Names, id: u64, kind: u32) -> &str {
    names
        .get(&convert::actor_id(id))
        .map_or_else(|| type_id(kind), String::as_str)
}

/// [`file_info`], naming the actors in `names` by their type ids there.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`RecordingReader::open`] if `path` cannot
/// be opened as a simbus recording, and the first error met reading its
/// messages ([`RecordingError::Corrupt`], [`RecordingError::Malformed`], ...).
pub fn file_info_named(
    path: &str,
    show_all: bool,
    names: &Names,
) -> Result<String, RecordingError> {
    let mut reader = RecordingReader::open(path)?;
    let mut text = InfoText::new(reader.header(), show_all, names);
    while let Some(entry) = reader.next() {
        text.entry(&entry?);
    }
    Ok(text.finish())
}

/// CARLA's `show_recorder_collisions` text: the heading, a row per
/// collision that started between actors of kinds for which
/// `keep(kind_a, kind_b)` (simbus's kind names) holds, and the footer.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`RecordingReader::open`] if `path` cannot
/// be opened as a simbus recording, and the first error met reading its
/// messages ([`RecordingError::Corrupt`], [`RecordingError::Malformed`], ...).
pub fn collisions(
    path: &str,
    keep: impl Fn(&str, &str) -> bool,
    names: &Names,
) -> Result<String, RecordingError> {
    let mut reader = RecordingReader::open(path)?;
    let mut out = heading(reader.header());
    let _ = writeln!(
        out,
        "{:>8} {:>6} {:>6} {:<35} {:>6} {:<35}",
        "Time", "Types", "Id", "Actor 1", "Id", "Actor 2"
    );
    let (mut frames, mut last) = (0, (u64::MAX, 0));
    let mut rows = false;
    while let Some(entry) = reader.next() {
        match entry? {
            Entry::Frame { log_ns, header, .. } => {
                frames += 1;
                last = (header.timestamp.frame, log_ns);
            }
            Entry::Collision(c) if keep(kind_name(c.kind_a), kind_name(c.kind_b)) => {
                rows = true;
                // The time of the collision's frame (read just before it).
                let _ = writeln!(
                    out,
                    "{:>8.0}   {} {}  {:>6} {:<35} {:>6} {:<35}",
                    seconds(last.1),
                    category(c.kind_a),
                    category(c.kind_b),
                    convert::actor_id(c.actor_a),
                    name_of(names, c.actor_a, c.kind_a),
                    convert::actor_id(c.actor_b),
                    name_of(names, c.actor_b, c.kind_b)
                );
            }
            _ => {}
        }
    }
    // CARLA's stream stays in whole seconds after its first row.
    let duration = if rows {
        format!("{:.0}", seconds(last.1))
    } else {
        cpp_number(seconds(last.1))
    };
    footer(&mut out, frames, &duration);
    Ok(out)
}

/// CARLA's `show_recorder_actors_blocked` text of `blocked`.
///
/// `blocked` is what [`inspect::actors_blocked`] found in the recording at
/// `path`; the text is the heading, a row per stretch an actor stayed still
/// (longest first), and the footer.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`inspect::file_info`] if the recording at
/// `path` cannot be opened or read (it is read again for its heading and
/// footer).
pub fn actors_blocked(path: &str, blocked: &[BlockedActor]) -> Result<String, RecordingError> {
    let info = inspect::file_info(path, false)?;
    let mut out = heading(&info.header);
    let _ = writeln!(
        out,
        "{:>8} {:>6} {:<35} {:>10}",
        "Time", "Id", "Actor", "Duration"
    );
    let mut rows: Vec<(f64, String)> = Vec::new();
    for actor in blocked {
        let kind = ActorKind::from_name(actor.kind).map_or(0, |k| k as u32);
        for s in &actor.stretches {
            let row = format!(
                "{:>8.0} {:>6} {:<35} {:>10.0}\n",
                s.from_seconds,
                convert::actor_id(actor.actor),
                type_id(kind),
                s.duration_seconds
            );
            rows.push((s.duration_seconds, row));
        }
    }
    // Longest first; equal ones in the order found (a stable sort).
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (_, row) in rows {
        out.push_str(&row);
    }
    footer(&mut out, info.frames, &cpp_number(info.duration_seconds));
    Ok(out)
}

#[cfg(test)]
#[path = "recorder_text_tests.rs"]
mod tests;
