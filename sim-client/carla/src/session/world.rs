//! The world's calls: version and episode, map, settings and ticks, and
//! the stream tokens.

use std::time::{Duration, Instant};

use rmpv::Value;
use shared_types::WaitMode;
use sim_client::{Reconnected, TickError, Ticker};
use tracing::{info, warn};

use super::{arg_flag, arg_str, arg_u64, Session, RESTART_PATIENCE};
use crate::episode_settings::{
    carla_substep_warning, default_other_fields, episode_settings, other_fields, parse_settings,
};
use crate::error::CallError;
use crate::locks::lock;
use crate::maps::{EpisodeMap, MapAnswer, MapRequest, AVAILABLE_MAPS, TOWN};
use crate::rpc::Answer;
use crate::sensors;
use crate::wire::{self, token, CARLA_VERSION};

/// How long a claim waits for another connection of this gateway whose
/// client died to release the tick (its end read and its ticker dropped).
const SIBLING_RELEASE: Duration = Duration::from_secs(2);

/// The longest [`Session::publish`] waits for the frame its tick stepped
/// (already in shared memory when the tick returns, so in practice no
/// wait); past it the world stream's pump sends that frame instead.
const STEPPED_FRAME: Duration = Duration::from_millis(5);

impl Session {
    pub(super) fn on_version(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(Value::from(CARLA_VERSION)))
    }

    /// The episode id and a token of the world stream, under an id of its
    /// own ([`crate::stream::Hub::next_world_stream`]).
    pub(super) fn on_get_episode_info(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let episode = self.client()?.status().map_err(CallError::simbus)?.episode;
        let episode = wire::episode_id(self.run_pid()?, episode);
        Ok(Answer::Value(Value::Array(vec![
            Value::from(episode),
            Value::Array(vec![Value::Binary(
                token(self.hub.next_world_stream(), self.streaming_port).to_vec(),
            )]),
        ])))
    }

    /// A stream's token; a sensor's stream starts being forwarded.
    pub(super) fn on_get_sensor_token(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let stream = arg_u64(args, 0, "get_sensor_token")?;
        let stream = u32::try_from(stream).map_err(|_| CallError::NoStream(stream))?;
        if !wire::is_world_stream(stream) {
            let run_pid = self.run_pid()?;
            sensors::expect(
                &self.hub,
                (&self.world, run_pid, self.streaming_port),
                stream,
                self.timeout,
            )?;
        }
        Ok(Answer::Value(Value::Array(vec![Value::Binary(
            token(stream, self.streaming_port).to_vec(),
        )])))
    }

    pub(super) fn on_get_episode_settings(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let settings = self.client()?.get_settings().map_err(CallError::simbus)?;
        let other = lock(&self.hub.other_settings).clone();
        Ok(Answer::Value(episode_settings(&settings, &other)))
    }

    /// CARLA's `apply_settings`: entering synchronous mode makes this
    /// connection the world's ticker (refused, naming the owner, if another
    /// client ticks); leaving it gives the ownership back.
    pub(super) fn on_set_episode_settings(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let settings = parse_settings(args.first()).ok_or(CallError::Shape {
            method: "set_episode_settings",
            what: "settings of the wrong shape",
        })?;
        if let Some(warning) = carla_substep_warning(&settings) {
            warn!(peer = %self.peer, "{warning}");
        }
        if settings.synchronous_mode && self.live_ticker()?.is_none() {
            self.claim()?;
            info!(peer = %self.peer, "a CARLA connection is the ticker");
        }
        let applied = match self.live_ticker()? {
            Some(ticker) => ticker.apply_settings(settings),
            None => self.client()?.apply_settings(settings),
        };
        let frame = applied.map_err(CallError::simbus)?;
        if !settings.synchronous_mode {
            if let Some(ticker) = self.ticker.take() {
                let _ = ticker.release();
                info!(peer = %self.peer, "the CARLA ticker left synchronous mode");
            }
        }
        if let Some(other) = other_fields(args.first()) {
            *lock(&self.hub.other_settings) = other;
        }
        // The frame the settings hold from; the client waits for the one before.
        Ok(Answer::Value(Value::from(frame.saturating_sub(1))))
    }

    pub(super) fn on_tick_cue(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        self.tick()
    }

    /// CARLA's `MapInfo`: the map's name and its recommended spawn points.
    pub(super) fn on_get_map_info(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(self.map()?.info()))
    }

    /// The map's OpenDRIVE text (CARLA's client builds its map from it).
    pub(super) fn on_get_map_data(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(Value::from(&*self.map()?.opendrive)))
    }

    /// simbus's scenes (`config.py --list` prints them, `-m` loads one).
    pub(super) fn on_get_available_maps(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(Value::Array(
            AVAILABLE_MAPS.into_iter().map(Value::from).collect(),
        )))
    }

    /// The first half of CARLA's `generate_opendrive_world`: the
    /// OpenDRIVE to build the next `OpenDriveMap` on, checked (a text that
    /// is not OpenDRIVE is refused and nothing changes).
    pub(super) fn on_copy_opendrive_to_file(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let opendrive = arg_str(args, 0, "copy_opendrive_to_file")?;
        self.hub.maps.send(&opendrive).map_err(CallError::simbus)?;
        Ok(Answer::Done)
    }

    /// The map of the world's current episode.
    fn map(&mut self) -> Result<MapAnswer, CallError> {
        let status = self.client()?.status().map_err(CallError::simbus)?;
        self.hub
            .maps
            .answer(status.run_pid, status.episode, &status.scene)
            .map_err(CallError::simbus)
    }

    /// CARLA's `get_required_files(folder)`: for `"Nav"`, the walkers'
    /// navigation file of the map (none for an OpenDRIVE a client sent);
    /// no other folder has files.
    pub(super) fn on_get_required_files(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let folder = arg_str(args, 0, "get_required_files")?;
        let files = match folder.trim_matches('/') {
            "Nav" => self
                .map()?
                .navigation
                .map(|file| Value::from(file.name.as_str()))
                .into_iter()
                .collect(),
            _ => Vec::new(),
        };
        Ok(Answer::Value(Value::Array(files)))
    }

    /// CARLA's `request_file(name)`: the map's navigation file by the name
    /// `get_required_files` gave; empty for any other name (as CARLA's
    /// server answers a file it does not have).
    pub(super) fn on_request_file(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "request_file")?;
        let bytes = self
            .map()?
            .navigation
            .filter(|file| file.name == name)
            .map(|file| file.bytes.clone())
            .unwrap_or_default();
        Ok(Answer::Value(Value::Binary(bytes)))
    }

    /// The calls simbus answers with an empty list (no lights).
    pub(super) fn on_empty_list(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(Value::Array(Vec::new())))
    }

    /// CARLA's `load_world`/`reload_world`: a scene by name (with or
    /// without CARLA's `/Game/Carla/Maps/`), the same again (empty name),
    /// simbus's `town` in place of one of CARLA's towns (refused with
    /// `--strict-maps`), or `OpenDriveMap`: a flat world on the OpenDRIVE
    /// `generate_opendrive_world` sent. A reload keeps the map the
    /// episode had.
    pub(super) fn on_load_new_episode(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let change = self.hub.change_episode();
        let name = arg_str(args, 0, "load_new_episode")?;
        let reset = arg_flag(args, 1);
        let request = MapRequest::of(&name);
        let (scene, map) = match &request {
            MapRequest::Reload => {
                let status = self.client()?.status().map_err(CallError::simbus)?;
                ("", self.hub.maps.given((status.run_pid, status.episode)))
            }
            MapRequest::Scene(scene) => (scene.as_str(), None),
            MapRequest::CarlaTown(town) => {
                let scene = self
                    .hub
                    .maps
                    .stand_in_for(town)
                    .map_err(CallError::simbus)?;
                (scene, Some(EpisodeMap::substitute(town)))
            }
            MapRequest::OpenDrive => {
                let (scene, map) = self.hub.maps.opendrive_world().map_err(CallError::simbus)?;
                (scene, Some(map))
            }
        };
        let client = self.client()?;
        let loaded = if scene.is_empty() {
            client.reload_world(reset)
        } else {
            client.load_world(scene, reset)
        };
        let status = loaded.map_err(CallError::simbus)?;
        change.let_captures_land();
        change.begun(status.run_pid, status.episode);
        self.hub.maps.give(status.run_pid, status.episode, map);
        if let MapRequest::CarlaTown(town) = &request {
            info!(peer = %self.peer, "CARLA's map {town} is not in simbus: loading simbus's {TOWN} instead");
        }
        if reset {
            *lock(&self.hub.other_settings) = default_other_fields();
        }
        Ok(Answer::Done)
    }

    /// CARLA's `world.tick()`: the ticker steps a frame; in asynchronous
    /// mode anyone may wait for the next one; in synchronous mode another
    /// client's tick is refused naming the owner.
    pub(super) fn tick(&mut self) -> Result<Answer, CallError> {
        if self.live_ticker()?.is_none() {
            let settings = self.client()?.get_settings().map_err(CallError::simbus)?;
            if !settings.synchronous_mode {
                let next = self.hub.last_frame() + 1;
                return Ok(Answer::Value(Value::from(next)));
            }
            // Synchronous and not ours: take it if free, else say who has it.
            self.claim()?;
        }
        let frame = self.ticked()?;
        self.publish(frame);
        Ok(Answer::Value(Value::from(frame)))
    }

    /// Claims the world for this connection. Its ticker follows a server
    /// restart: when the server exits and one resumed from its journal
    /// comes back within [`RESTART_PATIENCE`], it claims that one and
    /// ticks on.
    fn claim(&mut self) -> Result<(), CallError> {
        let name = self.ticker_name();
        // A client killed while it ticked leaves its connection's ticker
        // until the gateway reads the connection's end: a claim it refuses
        // waits that long (at most SIBLING_RELEASE) before it is refused.
        let deadline = Instant::now() + SIBLING_RELEASE;
        let mut ticker = loop {
            match self.client()?.claim_ticker_as(&name) {
                Ok(ticker) => break ticker,
                Err(TickError::NotTicker {
                    owner: Some(owner), ..
                }) if owner.pid == std::process::id()
                    && owner.node_name.to_string_lossy().starts_with("carla:")
                    && self.hub.wait_for_a_connection_to_end(deadline) => {}
                Err(e) => return Err(CallError::simbus(e)),
            }
        };
        ticker.set_wait_mode(WaitMode::Hybrid);
        ticker.set_follow_restarts(Some(RESTART_PATIENCE.min(self.timeout)));
        self.ticker = Some(ticker);
        self.ticker_run = self.run_pid;
        Ok(())
    }

    /// After this connection's ticker claimed a server that came back:
    /// keeps it when that server resumed the run the ticker was claimed
    /// in; a fresh server is a new episode, so the world is given back
    /// and the error says so.
    fn same_run(&mut self, restarted: &Reconnected) -> Result<(), CallError> {
        self.client = None;
        if self.run_pid()? == self.ticker_run {
            return Ok(());
        }
        if let Some(ticker) = self.ticker.take() {
            if let Err(e) = ticker.release() {
                warn!(peer = %self.peer, "giving back a fresh server's world: {e}");
            }
        }
        warn!(peer = %self.peer, "{restarted}, a fresh server: the CARLA ticker gave the world back");
        Err(CallError::NewRun {
            previous: restarted.previous_pid,
            server: restarted.server_pid,
        })
    }

    /// A tick of this connection's ticker: the frame it stepped. A tick
    /// that met a server restart claimed the resumed server and steps the
    /// frame after the one the world resumed at, so CARLA's `world.tick()`
    /// only takes longer.
    fn ticked(&mut self) -> Result<u64, CallError> {
        let ticker = self.ticker.as_mut().ok_or(CallError::NoConnection)?;
        match ticker.tick(self.timeout) {
            Err(TickError::Restarted(restarted)) => {
                self.same_run(&restarted)?;
                info!(peer = %self.peer, "{restarted}; the CARLA ticker ticks on");
                let ticker = self.ticker.as_mut().ok_or(CallError::NoConnection)?;
                ticker.tick(self.timeout).map_err(CallError::simbus)
            }
            ticked => ticked.map_err(CallError::simbus),
        }
    }

    /// This connection's ticker, if it holds one, claimed again from the
    /// server that came back when its own exited (a resume). When none
    /// came back within [`RESTART_PATIENCE`] the ticker is dropped and the
    /// error says so.
    pub(super) fn live_ticker(&mut self) -> Result<Option<&mut Ticker>, CallError> {
        let gone = self
            .ticker
            .as_ref()
            .is_some_and(|t| !sim_client::process_alive(t.server_pid()));
        let patience = RESTART_PATIENCE.min(self.timeout);
        let reclaimed = self
            .ticker
            .as_mut()
            .filter(|_| gone)
            .map(|ticker| ticker.reclaim(patience));
        match reclaimed {
            Some(Ok(restarted)) => {
                self.same_run(&restarted)?;
                info!(peer = %self.peer, "{restarted}; the CARLA ticker claimed it again");
            }
            Some(Err(e)) => {
                warn!(peer = %self.peer, "the CARLA ticker's server is gone: {e}");
                self.ticker = None;
                return Err(CallError::simbus(e));
            }
            None => {}
        }
        Ok(self.ticker.as_mut())
    }

    /// Sends the world state of `frame`, just stepped, to the CARLA clients
    /// now (the pump would send it after its own wake-up).
    fn publish(&mut self, frame: u64) {
        let Ok(run_pid) = self.run_pid() else {
            return;
        };
        let Some(client) = self.client.as_mut() else {
            return;
        };
        // The frame is in shared memory already: older queued ones are
        // skipped without waiting.
        while let Ok(view) = client.wait_for_frame(STEPPED_FRAME) {
            if view.frame() >= frame {
                crate::stream::publish(&self.hub, &view, run_pid);
                return;
            }
        }
    }
}
