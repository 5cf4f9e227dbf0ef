//! The driving world's own steps: building the episodes' start, reading a
//! frame, walking the walkers, writing the observations and images.

use numpy::PyReadwriteArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rand::RngExt;
use shared_types::roads::{LANE_WIDTH, SIDEWALK_WIDTH};
use shared_types::Command;

use super::{
    error, DrivingWorld, Ego, Outcome, Walker, SETTLE_FRAMES, START_SPACING, VEHICLE_DROP,
    WALKER_SIZE, WALKER_SPEED,
};
use crate::errors::{self, raise};
use crate::gil::detached;
use crate::gym::task;

impl DrivingWorld {
    /// Spawns the egos, traffic and walkers at the first start places,
    /// settles them and saves the episodes' snapshot.
    pub(super) fn populate(
        &mut self,
        py: Python<'_>,
        egos: usize,
        vehicles: usize,
        walkers: usize,
    ) -> PyResult<()> {
        let places = task::start_places(&self.lanes, START_SPACING);
        if egos + vehicles > places.len() {
            return Err(PyValueError::new_err(format!(
                "the town has {} places to start for {} vehicles",
                places.len(),
                egos + vehicles
            )));
        }
        let mut spawns: Vec<Command> = places
            .iter()
            .take(egos + vehicles)
            .map(|&(lane, progress)| {
                let (at, rotation) =
                    task::placed(self.lanes.point(lane, progress, 0.0), VEHICLE_DROP);
                Command {
                    rotation,
                    ..Command::spawn_vehicle(at)
                }
            })
            .collect();
        let side = -(LANE_WIDTH + SIDEWALK_WIDTH) / 2.0;
        let walker_places: Vec<_> = places.iter().rev().take(walkers).copied().collect();
        for &(lane, progress) in &walker_places {
            let (at, _) = task::placed(self.lanes.point(lane, progress, side), 1.0);
            spawns.push(Command::spawn_walker(at, WALKER_SIZE.0, WALKER_SIZE.1));
        }
        let response = self
            .client
            .apply_batch_sync(&spawns, false)
            .map_err(error)?;
        if let Some((index, status)) = response.errors().first() {
            return Err(raise(
                "CommandError",
                format!("spawning the task's actor {index} was refused: {status:?}"),
            ));
        }
        let ids: Vec<u64> = response.results.iter().map(|r| r.actor).collect();
        self.egos = ids[..egos]
            .iter()
            .map(|&id| Ego {
                id,
                ..Ego::default()
            })
            .collect();
        self.traffic = ids[egos..egos + vehicles].to_vec();
        self.walkers = ids[egos + vehicles..]
            .iter()
            .zip(&walker_places)
            .map(|(&id, &(lane, _))| Walker {
                id,
                lane,
                forward: true,
                crossing: None,
            })
            .collect();
        self.spawn_sensors()?;
        let timeout = self.timeout;
        let frame = detached(py, &mut self.ticker, |t| {
            let mut frame = 0;
            for _ in 0..SETTLE_FRAMES {
                frame = t.tick(timeout)?;
            }
            Ok(frame)
        })
        .map_err(errors::tick)?;
        self.read(py, frame)?;
        self.snapshot = self
            .client
            .save_snapshot()
            .map_err(crate::durability::snapshot_error)?;
        Ok(())
    }

    /// Reads frame `frame` (passing over any older) into `actors`.
    /// Waits without the GIL.
    pub(super) fn read(&mut self, py: Python<'_>, frame: u64) -> PyResult<()> {
        let timeout = self.timeout;
        loop {
            let view = detached(py, &mut self.client, |c| c.wait_for_frame(timeout))
                .map_err(errors::wait)?;
            if view.frame() < frame {
                continue;
            }
            self.actors.clear();
            self.actors.extend_from_slice(view.actors());
            // What each light shows, once per frame (the traffic's and the egos').
            self.lights.observe(self.lanes.network(), &self.actors);
            let t = view.timestamp();
            self.time = (t.elapsed_seconds(), t.delta_seconds());
            self.frame = view.frame();
            return Ok(());
        }
    }

    /// Each walker's control: along its sidewalk; at its end, across the
    /// road to the other sidewalk (one in `cross_factor`, seeded) or back.
    pub(super) fn walk(&mut self) {
        let side = -(LANE_WIDTH + SIDEWALK_WIDTH) / 2.0;
        for walker in &mut self.walkers {
            let Some(actor) = self.actors.iter().find(|a| a.id == walker.id) else {
                continue;
            };
            let f = task::Flat::of(actor);
            let length = self.lanes.length(walker.lane);
            if let Some((x, y)) = walker.crossing {
                if (x - f.x).hypot(y - f.y) > CROSSED {
                    self.commands
                        .push(walker_toward(walker.id, (y - f.y).atan2(x - f.x)));
                    continue;
                }
                // Across: on along the other sidewalk, the same way.
                walker.crossing = None;
                self.crossings += 1;
                walker.lane = simbus_traffic::LaneRef {
                    road: walker.lane.road,
                    lane: -walker.lane.lane,
                };
            }
            let Some(on) = self.lanes.project_on(walker.lane, f.x, f.y) else {
                continue;
            };
            let at_end = if walker.forward {
                on.progress > length - 1.0
            } else {
                on.progress < 1.0
            };
            if at_end {
                if self.walker_rng.random_bool(self.cross_factor) {
                    let other = simbus_traffic::LaneRef {
                        road: walker.lane.road,
                        lane: -walker.lane.lane,
                    };
                    let there =
                        self.lanes
                            .point(other, (length - on.progress).clamp(0.0, length), side);
                    walker.crossing = Some((there.x, there.y));
                    self.commands.push(walker_toward(
                        walker.id,
                        (there.y - f.y).atan2(there.x - f.x),
                    ));
                    continue;
                }
                walker.forward = !walker.forward;
            }
            let pose = self
                .lanes
                .point(walker.lane, on.progress.clamp(0.0, length), 0.0);
            let hdg = if walker.forward {
                pose.hdg
            } else {
                pose.hdg + std::f64::consts::PI
            };
            self.commands.push(walker_toward(walker.id, hdg));
        }
    }

    /// Writes each ego's observation (and its sensors' captures) from the
    /// frame read.
    pub(super) fn write(
        &mut self,
        obs: &mut PyReadwriteArray2<'_, f32>,
        captures: super::Captures<'_>,
    ) -> PyResult<Vec<Outcome>> {
        let mut obs = obs.as_array_mut();
        if obs.nrows() != self.egos.len() || obs.ncols() != self.spec.row() {
            return Err(PyValueError::new_err(format!(
                "observations must be {} x {} float32, not {:?}",
                self.egos.len(),
                self.spec.row(),
                obs.shape()
            )));
        }
        let lights = self.lights.states();
        let mut outcomes = std::mem::take(&mut self.outcomes);
        outcomes.clear();
        for (ego, mut row) in self.egos.iter_mut().zip(obs.rows_mut()) {
            let row = row
                .as_slice_mut()
                .ok_or_else(|| PyValueError::new_err("observation rows must be contiguous"))?;
            outcomes.push(task::observe(&self.spec, ego, &self.actors, lights, row));
        }
        self.capture(captures)?;
        Ok(outcomes)
    }
}

/// How close to the far sidewalk's point a crossing walker has crossed, metres.
const CROSSED: f64 = 0.5;

/// Walker `id` walking at walking speed towards heading `hdg` (OpenDRIVE's
/// axes, radians).
fn walker_toward(id: u64, hdg: f64) -> Command {
    Command::walker_control(
        id,
        [hdg.cos() as f32, 0.0, -hdg.sin() as f32],
        WALKER_SPEED,
        false,
    )
}
