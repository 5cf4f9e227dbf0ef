//! [`Status`]: the world's state as [`crate::Client::status`] returns it,
//! owned and typed (the wire's [`StatusReport`] has fixed-size text and
//! reserved fields).

use std::time::Duration;

use shared_types::{StatusReport, TickerInfo, WorldSettings};

/// The world's state when the server answered.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// The latest published frame.
    pub frame: u64,
    /// Its simulation time in nanoseconds.
    pub elapsed_ns: u64,
    /// The current episode (a load or reload starts the next).
    pub episode: u64,
    /// The server's process id.
    pub server_pid: u32,
    /// The run the server continues: the pid of the server that began it,
    /// `server_pid` unless it resumed a journal (then the first server's).
    pub run_pid: u32,
    /// Actors in the world.
    pub actor_count: u32,
    /// The settings in force for the next frame.
    pub settings: WorldSettings,
    /// The scene the world was loaded from (`default`, `boxes:10`, …).
    pub scene: String,
    /// Who holds tick ownership; `None` when nobody does.
    pub ticker: Option<TickerStatus>,
    /// The seed the scene was built with (0: none).
    pub seed: u64,
    /// Lockstep participants the server waits for in synchronous mode
    /// (all of them; [`Status::lockstep`] describes the first few).
    pub participants: u32,
    /// Clients of each kind the world admits (`--max-clients`).
    pub max_clients: u32,
    /// Readers each sensor admits (`--max-sensor-readers`).
    pub max_sensor_readers: u32,
    /// The first [`shared_types::REPORTED_PARTICIPANTS`] participants, in
    /// joining order.
    pub lockstep: Vec<ParticipantStatus>,
    /// The server's journal (`sim-server --journal DIR`), if it keeps one.
    pub journal: Option<JournalStatus>,
    /// Snapshots held in the server's memory.
    pub snapshots: u32,
}

/// The state of a server's journal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum JournalStatus {
    /// Being written into this directory.
    Writing {
        /// The journal's directory.
        dir: String,
        /// The last frame made durable.
        durable_frame: u64,
    },
    /// Stopped (the disk is full, the file cannot be written); the world
    /// runs on, and a resume starts from `durable_frame`.
    Stopped {
        /// Why.
        reason: String,
        /// The last frame made durable.
        durable_frame: u64,
    },
}

/// The client that holds tick ownership.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TickerStatus {
    /// Its process id.
    pub pid: u32,
    /// Its iceoryx2 node name.
    pub node_name: String,
    /// The last frame published before it claimed ownership.
    pub since_frame: u64,
}

/// One lockstep participant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParticipantStatus {
    /// Its name.
    pub name: String,
    /// Its process.
    pub pid: u32,
    /// Its window: how many frames the world may run ahead of its last
    /// "done" (0: every frame waits for it).
    pub window: u32,
    /// The last frame it reported done.
    pub done_frame: u64,
    /// How many frames the world is ahead of its last "done" (`None`
    /// before its first report in this episode). A participant holds the
    /// ticker when its lag would pass its window.
    pub lag: Option<u64>,
    /// How long after that frame's publication its "done" came (how long
    /// it made that frame's step wait at most); `None` before its first
    /// report, or when the report was for an older frame.
    pub done_after: Option<Duration>,
}

impl Status {
    /// The simulation time of [`Status::frame`], in seconds.
    pub fn elapsed_seconds(&self) -> f64 {
        shared_types::nanos_to_seconds(self.elapsed_ns)
    }
}

impl From<&StatusReport> for Status {
    fn from(report: &StatusReport) -> Self {
        let filled = (report.participants as usize).min(report.lockstep.len());
        Self {
            frame: report.frame,
            elapsed_ns: report.elapsed_ns,
            episode: report.episode,
            server_pid: report.server_pid,
            run_pid: match report.run_pid {
                0 => report.server_pid,
                run => run,
            },
            actor_count: report.actor_count,
            settings: report.settings.into(),
            scene: report.scene.to_string_lossy(),
            ticker: TickerStatus::of(&report.ticker),
            seed: report.seed,
            participants: report.participants,
            max_clients: report.max_clients,
            max_sensor_readers: report.max_sensor_readers,
            lockstep: report.lockstep[..filled]
                .iter()
                .map(|p| ParticipantStatus {
                    name: p.name.to_string_lossy(),
                    pid: p.pid,
                    window: p.window,
                    done_frame: p.done_frame,
                    lag: p.lag(),
                    done_after: p.done_after(),
                })
                .collect(),
            journal: match report.journal {
                StatusReport::JOURNALING => Some(JournalStatus::Writing {
                    dir: report.journal_note.to_string_lossy(),
                    durable_frame: report.journal_durable_frame,
                }),
                StatusReport::JOURNAL_STOPPED => Some(JournalStatus::Stopped {
                    reason: report.journal_note.to_string_lossy(),
                    durable_frame: report.journal_durable_frame,
                }),
                _ => None,
            },
            snapshots: report.snapshots,
        }
    }
}

impl TickerStatus {
    /// The owner `info` names, if it names one.
    pub fn of(info: &TickerInfo) -> Option<Self> {
        info.active().map(|t| Self {
            pid: t.pid,
            node_name: t.node_name.to_string_lossy(),
            since_frame: t.since_frame,
        })
    }
}

impl std::fmt::Display for TickerStatus {
    /// `NAME (pid PID) since frame N`, as the wire's [`TickerInfo`] prints.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} (pid {}) since frame {}",
            self.node_name, self.pid, self.since_frame
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytemuck::Zeroable;
    use shared_types::FixedText;

    #[test]
    fn the_report_becomes_owned_text_and_only_the_filled_participants() {
        let mut report = StatusReport::zeroed();
        report.frame = 7;
        report.scene = FixedText::new("boxes:3");
        report.participants = 2;
        report.lockstep[0].name = FixedText::new("planner");
        report.lockstep[0].done_after_ns = 1_500;
        report.lockstep[1].name = FixedText::new("logger");
        report.lockstep[1].done_after_ns = shared_types::ParticipantStatus::NOT_YET;
        let status = Status::from(&report);
        assert_eq!(status.frame, 7);
        assert_eq!(status.scene, "boxes:3");
        assert_eq!(status.ticker, None);
        assert_eq!(status.lockstep.len(), 2);
        assert_eq!(status.lockstep[0].name, "planner");
        assert_eq!(
            status.lockstep[0].done_after,
            Some(Duration::from_nanos(1_500))
        );
        assert_eq!(status.lockstep[1].done_after, None);

        report.ticker = TickerInfo {
            active: 1,
            pid: 42,
            since_frame: 5,
            node_name: FixedText::new("sim-client-tick"),
        };
        report.participants = 100;
        let status = Status::from(&report);
        let ticker = status.ticker.expect("a ticker");
        assert_eq!(ticker.to_string(), report.ticker.to_string());
        assert_eq!(status.lockstep.len(), shared_types::REPORTED_PARTICIPANTS);
        assert_eq!(status.participants, 100);
    }
}
