//! Snapshots: the whole world saved in the server's memory at a frame
//! and restored later as a new episode that starts from exactly that
//! state — what CARLA's users ask for (carla-simulator/carla#6604,
//! #7511) and reinforcement learning needs for fast resets. The frame ids
//! go on; the time, actors, ids, sensors and settings are the snapshot's.

use shared_types::{SensorSpec, SnapshotInfo, SnapshotList, WorldSettings, MAX_SNAPSHOTS};

use crate::scene::Scene;

/// One saved world.
#[derive(Debug)]
pub(crate) struct Snapshot {
    pub(crate) info: SnapshotInfo,
    /// The world, copied again on every restore, so a snapshot restores
    /// any number of times.
    pub(crate) world: crate::world::World,
    pub(crate) scene: Scene,
    pub(crate) settings: WorldSettings,
    pub(crate) delta_ns: u64,
    pub(crate) sensors: Vec<(u64, SensorSpec)>,
}

/// The snapshots a server holds, oldest first.
#[derive(Debug, Default)]
pub(crate) struct Snapshots {
    list: Vec<Snapshot>,
    last_id: u64,
}

impl Snapshots {
    /// Whether another snapshot fits.
    pub(crate) fn is_full(&self) -> bool {
        self.list.len() >= MAX_SNAPSHOTS
    }

    /// Keeps `snapshot` under a new id, which it returns.
    pub(crate) fn keep(&mut self, mut snapshot: Snapshot) -> SnapshotInfo {
        self.last_id += 1;
        snapshot.info.id = self.last_id;
        let info = snapshot.info;
        self.list.push(snapshot);
        info
    }

    /// Snapshot `id`.
    pub(crate) fn get(&self, id: u64) -> Option<&Snapshot> {
        self.list.iter().find(|s| s.info.id == id)
    }

    /// Forgets snapshot `id`; `false` if there is none.
    pub(crate) fn forget(&mut self, id: u64) -> bool {
        let before = self.list.len();
        self.list.retain(|s| s.info.id != id);
        self.list.len() != before
    }

    /// How many are held.
    pub(crate) fn len(&self) -> usize {
        self.list.len()
    }

    /// Every snapshot, as the wire lists them.
    pub(crate) fn list(&self) -> SnapshotList {
        let mut list = <SnapshotList as bytemuck::Zeroable>::zeroed();
        for (slot, snapshot) in list.items.iter_mut().zip(&self.list) {
            *slot = snapshot.info;
        }
        list.count = self.list.len().min(MAX_SNAPSHOTS) as u32;
        list
    }
}
