//! Snapshots of the whole world, saved in the server's memory and restored
//! later as a new episode starting from exactly that state (CARLA has no
//! such call; its users asked for it in carla-simulator/carla#6604 and
//! #7511). While a ticker holds the world only its process saves,
//! restores and drops them.

use shared_types::{
    ControlRequest, ControlResponse, RequestKind, ResponseStatus, SnapshotInfo, TickerInfo,
    MAX_SNAPSHOTS,
};

use crate::{Client, RequestError};

/// The id of a snapshot the server holds (never reused within its life).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SnapshotId(pub u64);

impl std::fmt::Display for SnapshotId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// Why a snapshot was not saved, restored or dropped. Nothing changed.
#[derive(Debug, thiserror::Error)]
pub enum SnapshotError {
    /// Another process ticks the world; only it saves and restores.
    #[error("world '{world}' has a ticker ({}); only the ticker saves, restores and drops snapshots", owner.map_or_else(|| "another process".to_owned(), |o| o.to_string()))]
    NotTicker {
        /// The world.
        world: String,
        /// The ticker, as the server named it.
        owner: Option<TickerInfo>,
    },
    /// No snapshot has this id.
    #[error("world '{world}' holds no snapshot {id}")]
    Unknown {
        /// The world.
        world: String,
        /// The id asked for.
        id: SnapshotId,
    },
    /// The server holds as many snapshots as it keeps.
    #[error("world '{world}' holds {max} snapshots, as many as a server keeps: drop one first")]
    Full {
        /// The world.
        world: String,
        /// How many a server keeps.
        max: usize,
    },
    /// A replay runs: its world is the recording's.
    #[error("world '{world}' is replaying a recording; save or restore after it ends")]
    Replaying {
        /// The world.
        world: String,
    },
    /// The server could not restore it (its log says why).
    #[error("world '{world}' could not restore snapshot {id} (the server's log says why)")]
    Failed {
        /// The world.
        world: String,
        /// The snapshot.
        id: SnapshotId,
    },
    /// The request failed (timeout, server gone, protocol).
    #[error(transparent)]
    Request(#[from] RequestError),
}

impl Client {
    /// Saves the whole world as it is after the current frame — actors,
    /// ids, physics, time, settings and sensors — in the server's memory,
    /// and returns its id. At most [`MAX_SNAPSHOTS`] are kept.
    ///
    /// # Errors
    ///
    /// Returns [`SnapshotError::NotTicker`] if another process ticks the world,
    /// [`SnapshotError::Full`] if the server already holds [`MAX_SNAPSHOTS`],
    /// [`SnapshotError::Replaying`] during a replay, and
    /// [`SnapshotError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`], ...). Nothing
    /// is saved in any of these cases.
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    /// use shared_types::WorldSettings;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "snapshot", std::process::id());
    /// # let stop = Arc::new(AtomicBool::new(false));
    /// # let server = {
    /// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
    /// #     std::thread::spawn(move || {
    /// #         let mut config = sim_server::ServerConfig::new(world);
    /// #         config.settings.fixed_delta_seconds = Some(0.01);
    /// #         config.realtime = true;
    /// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
    /// #     })
    /// # };
    /// let mut client = Client::connect(&name, Duration::from_secs(5))?;
    /// let mut ticker = client.claim_ticker()?;
    /// let sync = WorldSettings { synchronous_mode: true, ..client.get_settings()? };
    /// ticker.apply_settings(sync)?;
    /// let saved_at = ticker.tick(Duration::from_secs(1))?;
    /// let id = client.save_snapshot()?;
    /// assert_eq!(client.snapshots()?[0].frame, saved_at);
    /// for _ in 0..5 {
    ///     ticker.tick(Duration::from_secs(1))?;
    /// }
    /// // Frame ids go on; the world is the one saved after `saved_at`.
    /// let restored = client.restore_snapshot(id)?;
    /// assert_eq!(restored, saved_at + 6);
    /// let snapshot = loop {
    ///     let snapshot = client.wait_for_tick(Duration::from_secs(1))?;
    ///     if snapshot.frame() == restored {
    ///         break snapshot;
    ///     }
    /// };
    /// assert_eq!(snapshot.header.source_timestamp().frame, saved_at);
    /// client.drop_snapshot(id)?;
    /// # drop(ticker);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn save_snapshot(&self) -> Result<SnapshotId, SnapshotError> {
        let response = self.snapshot_request(RequestKind::SaveSnapshot, 0)?;
        Ok(SnapshotId(response.snapshot))
    }

    /// Restores snapshot `id` as a new episode, published at once as the next frame.
    ///
    /// The frame ids go on, and the world's time, actors, ids, sensors and
    /// settings are the snapshot's (synchronous mode stays as it is). Its
    /// frames digest as those after the save, so the same commands give the
    /// same digests. Returns the frame published.
    ///
    /// # Errors
    ///
    /// Returns [`SnapshotError::Unknown`] if the server holds no snapshot `id`,
    /// [`SnapshotError::NotTicker`] if another process ticks the world,
    /// [`SnapshotError::Replaying`] during a replay, [`SnapshotError::Failed`]
    /// if the server could not restore it (its log says why), and
    /// [`SnapshotError::Request`] if the request fails. The world is unchanged
    /// in each case.
    pub fn restore_snapshot(&self, id: SnapshotId) -> Result<u64, SnapshotError> {
        let response = self.snapshot_request(RequestKind::RestoreSnapshot, id.0)?;
        Ok(response.report.frame)
    }

    /// Forgets snapshot `id`.
    ///
    /// # Errors
    ///
    /// Returns [`SnapshotError::Unknown`] if the server holds no snapshot `id`,
    /// [`SnapshotError::NotTicker`] if another process ticks the world, and
    /// [`SnapshotError::Request`] if the request fails.
    pub fn drop_snapshot(&self, id: SnapshotId) -> Result<(), SnapshotError> {
        self.snapshot_request(RequestKind::DropSnapshot, id.0)
            .map(drop)
    }

    /// The snapshots the server holds, oldest first.
    ///
    /// # Errors
    ///
    /// Returns the [`RequestError`]s of [`Client::status`]
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// [`RequestError::ProtocolMismatch`], ...).
    pub fn snapshots(&self) -> Result<Vec<SnapshotInfo>, RequestError> {
        let response = self.request(ControlRequest::new(RequestKind::ListSnapshots))?;
        Ok(response.snapshots.as_slice().to_vec())
    }

    fn snapshot_request(
        &self,
        kind: RequestKind,
        id: u64,
    ) -> Result<ControlResponse, SnapshotError> {
        let response = self.request(ControlRequest::snapshot(kind, id))?;
        let world = self.world.to_string();
        let id = SnapshotId(id);
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response),
            Some(ResponseStatus::NotTicker) => Err(SnapshotError::NotTicker {
                world,
                owner: response.report.ticker.active(),
            }),
            Some(ResponseStatus::UnknownSnapshot) => Err(SnapshotError::Unknown { world, id }),
            Some(ResponseStatus::SnapshotsFull) => Err(SnapshotError::Full {
                world,
                max: MAX_SNAPSHOTS,
            }),
            Some(ResponseStatus::Replaying) => Err(SnapshotError::Replaying { world }),
            Some(ResponseStatus::LoadFailed) => Err(SnapshotError::Failed { world, id }),
            _ => Err(RequestError::UnknownAnswer {
                status: response.status,
            }
            .into()),
        }
    }
}
