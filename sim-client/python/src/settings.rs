//! The world's settings and status as Python objects (read-only
//! attributes, `repr`, equality), converted from and to the Rust types.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::{SubstepRule, WorldSettings};

/// The world's time-step and synchrony settings, as CARLA's
/// `WorldSettings` names them.
#[pyclass(module = "simbus", frozen, eq, get_all)]
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Settings {
    /// The server computes a frame only after a tick from the ticker.
    synchronous_mode: bool,
    /// Seconds per frame; `None`: variable step.
    fixed_delta_seconds: Option<f64>,
    /// Physics runs in substeps of at most `max_substep_delta_time`.
    substepping: bool,
    /// The longest physics substep, in seconds.
    max_substep_delta_time: f64,
    /// The most substeps per frame.
    max_substeps: u32,
    /// What a fixed step longer than `max_substeps * max_substep_delta_time`
    /// does: "refuse", "clamp" (CARLA's) or "stretch".
    substep_rule: &'static str,
}

impl From<WorldSettings> for Settings {
    fn from(s: WorldSettings) -> Self {
        Self {
            synchronous_mode: s.synchronous_mode,
            fixed_delta_seconds: s.fixed_delta_seconds,
            substepping: s.substepping,
            max_substep_delta_time: s.max_substep_delta_time,
            max_substeps: s.max_substeps,
            substep_rule: s.substep_rule.name(),
        }
    }
}

#[pymethods]
impl Settings {
    fn __repr__(&self) -> String {
        format!(
            "Settings(synchronous_mode={}, fixed_delta_seconds={}, substepping={}, max_substep_delta_time={}, max_substeps={}, substep_rule='{}')",
            py_bool(self.synchronous_mode),
            self.fixed_delta_seconds.map_or("None".to_owned(), |d| d.to_string()),
            py_bool(self.substepping),
            self.max_substep_delta_time,
            self.max_substeps,
            self.substep_rule
        )
    }
}

fn py_bool(value: bool) -> &'static str {
    if value {
        "True"
    } else {
        "False"
    }
}

/// Which fields a caller changes: `None` keeps the current value. A
/// `fixed_delta_seconds` of 0 asks for the variable step.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Changes {
    pub(crate) synchronous_mode: Option<bool>,
    pub(crate) fixed_delta_seconds: Option<f64>,
    pub(crate) substepping: Option<bool>,
    pub(crate) max_substep_delta_time: Option<f64>,
    pub(crate) max_substeps: Option<u32>,
    pub(crate) substep_rule: Option<SubstepRule>,
}

impl Changes {
    /// `current` with these changes.
    pub(crate) fn applied_to(self, current: WorldSettings) -> WorldSettings {
        WorldSettings {
            synchronous_mode: self.synchronous_mode.unwrap_or(current.synchronous_mode),
            fixed_delta_seconds: self
                .fixed_delta_seconds
                .map_or(current.fixed_delta_seconds, |d| (d != 0.0).then_some(d)),
            substepping: self.substepping.unwrap_or(current.substepping),
            max_substep_delta_time: self
                .max_substep_delta_time
                .unwrap_or(current.max_substep_delta_time),
            max_substeps: self.max_substeps.unwrap_or(current.max_substeps),
            substep_rule: self.substep_rule.unwrap_or(current.substep_rule),
        }
    }
}

/// A `substep_rule` argument ("refuse", "clamp" or "stretch"); another word
/// raises `ValueError` naming the three.
pub(crate) fn substep_rule(word: Option<&str>) -> PyResult<Option<SubstepRule>> {
    word.map(|w| w.parse().map_err(|e| PyValueError::new_err(format!("{e}"))))
        .transpose()
}

/// Who holds tick ownership.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct TickerInfo {
    /// The ticker's process id.
    pid: u32,
    /// Its node's name.
    node_name: String,
    /// The last frame published before it claimed the world.
    since_frame: u64,
}

#[pymethods]
impl TickerInfo {
    fn __repr__(&self) -> String {
        format!(
            "TickerInfo(pid={}, node_name={:?}, since_frame={})",
            self.pid, self.node_name, self.since_frame
        )
    }
}

/// One lockstep participant in a [`Status`].
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct ParticipantStatus {
    /// Its name.
    name: String,
    /// Its process (the joining port's).
    pid: u32,
    /// How many frames the world may run ahead of its last `done`.
    window: u32,
    /// The last frame it reported done.
    done_frame: u64,
    /// How many frames the world is ahead of that (`None` before its first
    /// report in this episode).
    lag: Option<u64>,
}

#[pymethods]
impl ParticipantStatus {
    fn __repr__(&self) -> String {
        format!(
            "ParticipantStatus(name={:?}, pid={}, window={}, done_frame={}, lag={:?})",
            self.name, self.pid, self.window, self.done_frame, self.lag
        )
    }
}

/// The world's state when the server answered.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug)]
pub(crate) struct Status {
    /// The latest published frame.
    frame: u64,
    /// Its simulation time in integer nanoseconds.
    elapsed_ns: u64,
    /// Its simulation time in seconds.
    elapsed_seconds: f64,
    /// The current episode (a load or reload starts the next).
    episode: u64,
    /// The server's process id.
    server_pid: u32,
    /// The pid of the server that began this run: `server_pid` unless the
    /// server resumed a journal.
    run_pid: u32,
    /// Actors in the world.
    actor_count: u32,
    /// The settings in force for the next frame.
    settings: Settings,
    /// The scene the world was loaded from.
    scene: String,
    /// The ticker, or `None`.
    ticker: Option<TickerInfo>,
    /// The scene's seed (0: none).
    seed: u64,
    /// Lockstep participants the server waits for.
    participants: u32,
    /// The first eight of them, in joining order.
    lockstep: Vec<ParticipantStatus>,
    /// The server's journal, or `None` when it keeps none.
    journal: Option<JournalStatus>,
    /// Snapshots held in the server's memory.
    snapshots: u32,
}

/// A server's journal (`sim-server --journal DIR`).
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct JournalStatus {
    /// Whether it is being written (`False`: it stopped, `reason` says why;
    /// the world runs on).
    writing: bool,
    /// Its directory while it is written.
    dir: Option<String>,
    /// Why it stopped (a full disk...).
    reason: Option<String>,
    /// The last frame it made durable: where a resume would start.
    durable_frame: u64,
}

#[pymethods]
impl JournalStatus {
    fn __repr__(&self) -> String {
        match (&self.dir, &self.reason) {
            (Some(dir), _) => format!(
                "JournalStatus(writing=True, dir={dir:?}, durable_frame={})",
                self.durable_frame
            ),
            (None, reason) => format!(
                "JournalStatus(writing=False, reason={:?}, durable_frame={})",
                reason.as_deref().unwrap_or(""),
                self.durable_frame
            ),
        }
    }
}

impl From<sim_client::JournalStatus> for JournalStatus {
    fn from(j: sim_client::JournalStatus) -> Self {
        match j {
            sim_client::JournalStatus::Writing { dir, durable_frame } => Self {
                writing: true,
                dir: Some(dir),
                reason: None,
                durable_frame,
            },
            sim_client::JournalStatus::Stopped {
                reason,
                durable_frame,
            } => Self {
                writing: false,
                dir: None,
                reason: Some(reason),
                durable_frame,
            },
        }
    }
}

impl From<sim_client::Status> for Status {
    fn from(s: sim_client::Status) -> Self {
        Self {
            frame: s.frame,
            elapsed_ns: s.elapsed_ns,
            elapsed_seconds: s.elapsed_seconds(),
            episode: s.episode,
            server_pid: s.server_pid,
            run_pid: s.run_pid,
            actor_count: s.actor_count,
            settings: s.settings.into(),
            scene: s.scene,
            ticker: s.ticker.map(|t| TickerInfo {
                pid: t.pid,
                node_name: t.node_name,
                since_frame: t.since_frame,
            }),
            seed: s.seed,
            participants: s.participants,
            lockstep: s
                .lockstep
                .into_iter()
                .map(|p| ParticipantStatus {
                    name: p.name,
                    pid: p.pid,
                    window: p.window,
                    done_frame: p.done_frame,
                    lag: p.lag,
                })
                .collect(),
            journal: s.journal.map(JournalStatus::from),
            snapshots: s.snapshots,
        }
    }
}

#[pymethods]
impl Status {
    fn __repr__(&self) -> String {
        format!(
            "Status(frame={}, elapsed_seconds={}, episode={}, scene={:?}, actor_count={}, ticker={})",
            self.frame,
            self.elapsed_seconds,
            self.episode,
            self.scene,
            self.actor_count,
            self.ticker.as_ref().map_or("None".to_owned(), |t| t.__repr__())
        )
    }
}
