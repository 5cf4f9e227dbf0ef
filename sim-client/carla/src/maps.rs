//! The map CARLA's client reads (`get_map_info`, `get_map_data`): the
//! road network of the world's scene, or, for an episode the gateway
//! loaded in place of a CARLA town or built on an OpenDRIVE a client sent
//! (`generate_opendrive_world`), the map that load gave it.
//!
//! A map given to an episode is kept with that episode's id: a load by
//! anyone else starts another episode, whose map is its scene's again.

use std::sync::{Arc, Mutex};

use rmpv::Value;
use shared_types::roads::{self, OpenDriveError, SpawnPoint};
use shared_types::scene::{SceneName, SceneNameError};

use crate::locks::lock;

/// The folder CARLA's map names start with (`get_available_maps`).
const CARLA_MAPS_FOLDER: &str = "/Game/Carla/Maps/";
/// The map CARLA loads after `copy_opendrive_to_file`
/// (`generate_opendrive_world`), and the name such a world's map has.
pub(crate) const OPENDRIVE_MAP: &str = "OpenDriveMap";
/// The scene that stands in for CARLA's towns.
pub(crate) const TOWN: &str = "town";
/// The scene an OpenDRIVE world is built on.
const FLAT: &str = "flat";
/// The maps `get_available_maps` lists: simbus's scenes.
pub(crate) const AVAILABLE_MAPS: [&str; 5] = ["default", "empty", "town", "flat", "boxes:100"];

/// Why a map could not be loaded or answered.
#[derive(Debug, thiserror::Error)]
pub(crate) enum MapError {
    /// A CARLA town asked for, with `--strict-maps`.
    #[error(
        "CARLA's map {0} is not in simbus, and this gateway runs with --strict-maps, which \
         refuses to load simbus's town in its place: load one of simbus's maps (default, empty, \
         town, flat, boxes:N) or start carla-gateway without --strict-maps"
    )]
    Strict(String),
    /// `OpenDriveMap` loaded before any OpenDRIVE was sent.
    #[error(
        "no OpenDRIVE to build {OPENDRIVE_MAP} on: generate_opendrive_world(xodr) sends one first"
    )]
    NoOpenDrive,
    /// The OpenDRIVE sent is not one.
    #[error("generate_opendrive_world refused the OpenDRIVE given (nothing changed): {0}")]
    OpenDrive(#[from] OpenDriveError),
    /// The world's scene is not one this gateway knows.
    #[error("the world's scene has no map here: {0}")]
    Scene(#[from] SceneNameError),
}

/// What a `load_new_episode` asks for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum MapRequest {
    /// The current scene again (an empty name).
    Reload,
    /// A simbus scene (or a name the server will refuse).
    Scene(String),
    /// One of CARLA's towns, by its name without the folder.
    CarlaTown(String),
    /// The world built on the last OpenDRIVE sent.
    OpenDrive,
}

impl MapRequest {
    /// The request a CARLA map name makes, with or without CARLA's folder.
    pub(crate) fn of(name: &str) -> Self {
        let bare = name
            .strip_prefix(CARLA_MAPS_FOLDER)
            .or_else(|| name.strip_prefix("Carla/Maps/"))
            .unwrap_or(name);
        if bare.is_empty() {
            Self::Reload
        } else if bare == OPENDRIVE_MAP {
            Self::OpenDrive
        } else if bare.parse::<SceneName>().is_err() && carla_town(bare) {
            Self::CarlaTown(bare.to_owned())
        } else {
            Self::Scene(bare.to_owned())
        }
    }
}

/// Whether `name` is one of CARLA's towns: `Town01` to `Town15`, with
/// `HD` and `_Opt` or not (any case).
fn carla_town(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    let Some(rest) = lower.strip_prefix("town") else {
        return false;
    };
    let rest = rest.strip_suffix("_opt").unwrap_or(rest);
    let rest = rest.strip_suffix("hd").unwrap_or(rest);
    rest.len() == 2 && rest.parse::<u8>().is_ok_and(|n| (1..=15).contains(&n))
}

/// The map an episode was given: its name, and its own OpenDRIVE (none:
/// its scene's network).
#[derive(Debug, Clone)]
pub(crate) struct EpisodeMap {
    name: String,
    opendrive: Option<Arc<str>>,
}

impl EpisodeMap {
    /// Whether the map is an OpenDRIVE of a client's own (not a scene's).
    pub(crate) fn is_foreign(&self) -> bool {
        self.opendrive.is_some()
    }

    /// The map of a load in place of CARLA's `town`: simbus's town.
    pub(crate) fn substitute(town: &str) -> Self {
        Self {
            name: format!("simbus/{TOWN} (for {town})"),
            opendrive: None,
        }
    }
}

/// (run pid, episode): one episode of one run of the world (a server and
/// those resumed from its journal).
type EpisodeKey = (u32, u64);

/// The maps the gateway gave episodes, and whether CARLA's towns may be
/// stood in for (a field of the gateway's `Hub`).
#[derive(Debug, Default)]
pub(crate) struct Maps {
    /// `--strict-maps`: loading a CARLA town is refused.
    pub(crate) strict: bool,
    state: Mutex<MapState>,
}

#[derive(Debug, Default)]
struct MapState {
    /// The map of one episode, when not its scene's.
    given: Option<(EpisodeKey, EpisodeMap)>,
    /// The last OpenDRIVE a client sent (`copy_opendrive_to_file`).
    sent: Option<Arc<str>>,
}

/// A map as the map calls answer it.
#[derive(Debug)]
pub(crate) struct MapAnswer {
    /// `world.get_map().name`.
    pub(crate) name: String,
    /// The OpenDRIVE text.
    pub(crate) opendrive: Arc<str>,
    /// The recommended spawn points.
    pub(crate) spawn_points: Vec<SpawnPoint>,
    /// The walkers' navigation file, for a scene's roads (none for an
    /// OpenDRIVE a client sent: CARLA's client then has no navigation).
    pub(crate) navigation: Option<Arc<NavigationFile>>,
}

/// A navigation file as CARLA's client fetches it (`get_required_files`
/// `"Nav"`, `request_file`).
#[derive(Debug)]
pub(crate) struct NavigationFile {
    /// Its name in CARLA's file cache (`~/carlaCache/0.9.16/<name>`,
    /// never fetched again once there): the scene and a digest of the
    /// bytes, so a client never reads another mesh under the same name.
    pub(crate) name: String,
    pub(crate) bytes: Vec<u8>,
}

/// The navigation file of `network` (computed once per network name).
fn navigation_of(network: &roads::RoadNetwork) -> Option<Arc<NavigationFile>> {
    type Cache = Mutex<Vec<(String, Option<Arc<NavigationFile>>)>>;
    static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
    let cache = CACHE.get_or_init(Cache::default);
    if let Some((_, file)) = lock(cache).iter().find(|(name, _)| *name == network.name) {
        return file.clone();
    }
    let file = crate::navigation::navmesh(&crate::navigation::polygons(network)).map(|bytes| {
        // FNV-1a, 64 bits: the same bytes, the same name.
        let digest = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        });
        let scene: String = network
            .name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        Arc::new(NavigationFile {
            name: format!("Carla/Maps/Nav/simbus_{scene}_{digest:016x}.bin"),
            bytes,
        })
    });
    lock(cache).push((network.name.clone(), file.clone()));
    file
}

impl MapAnswer {
    /// CARLA's `MapInfo`: the name and the spawn points as transforms.
    pub(crate) fn info(&self) -> Value {
        let floats = |v: [f64; 3]| Value::Array(v.iter().map(|&x| Value::F32(x as f32)).collect());
        let points = self
            .spawn_points
            .iter()
            .map(|p| Value::Array(vec![floats(p.location), floats(p.rotation)]))
            .collect();
        Value::Array(vec![Value::from(self.name.as_str()), Value::Array(points)])
    }
}

impl Maps {
    /// The gateway's maps; `strict`: `--strict-maps`.
    pub(crate) fn new(strict: bool) -> Self {
        Self {
            strict,
            state: Mutex::default(),
        }
    }

    /// The map of episode `episode` of run `run_pid`, whose scene is
    /// `scene`.
    pub(crate) fn answer(
        &self,
        run_pid: u32,
        episode: u64,
        scene: &str,
    ) -> Result<MapAnswer, MapError> {
        let given = self.given((run_pid, episode));
        let network = || scene.parse::<SceneName>().map(roads::network);
        match given {
            Some(EpisodeMap {
                name,
                opendrive: Some(opendrive),
            }) => Ok(MapAnswer {
                name,
                opendrive,
                // Not computed from a foreign OpenDRIVE: CARLA's client
                // finds its waypoints itself.
                spawn_points: Vec::new(),
                navigation: None,
            }),
            Some(EpisodeMap { name, .. }) => {
                let network = network()?;
                Ok(answer_of(name, &network))
            }
            None => Ok(answer_of(scene.to_owned(), &network()?)),
        }
    }

    /// The map given to an episode, if it is `key`.
    pub(crate) fn given(&self, key: EpisodeKey) -> Option<EpisodeMap> {
        match &lock(&self.state).given {
            Some((at, map)) if *at == key => Some(map.clone()),
            _ => None,
        }
    }

    /// Gives episode `episode` of run `run_pid` its map (`None`: its
    /// scene's).
    pub(crate) fn give(&self, run_pid: u32, episode: u64, map: Option<EpisodeMap>) {
        lock(&self.state).given = map.map(|map| ((run_pid, episode), map));
    }

    /// The scene to load for CARLA's `town`, or the refusal under
    /// `--strict-maps`.
    pub(crate) fn stand_in_for(&self, town: &str) -> Result<&'static str, MapError> {
        if self.strict {
            return Err(MapError::Strict(town.to_owned()));
        }
        Ok(TOWN)
    }

    /// Keeps `opendrive` for the next `OpenDriveMap` load, if it is an
    /// OpenDRIVE document; else nothing changes.
    pub(crate) fn send(&self, opendrive: &str) -> Result<(), MapError> {
        roads::check_opendrive(opendrive)?;
        lock(&self.state).sent = Some(Arc::from(opendrive));
        Ok(())
    }

    /// The scene and the map of an `OpenDriveMap` load.
    pub(crate) fn opendrive_world(&self) -> Result<(&'static str, EpisodeMap), MapError> {
        let sent = lock(&self.state)
            .sent
            .clone()
            .ok_or(MapError::NoOpenDrive)?;
        Ok((
            FLAT,
            EpisodeMap {
                name: OPENDRIVE_MAP.to_owned(),
                opendrive: Some(sent),
            },
        ))
    }
}

/// The answer for `network`, named `name`.
fn answer_of(name: String, network: &roads::RoadNetwork) -> MapAnswer {
    MapAnswer {
        name,
        opendrive: Arc::from(network.to_opendrive()),
        spawn_points: network.spawn_points(),
        navigation: navigation_of(network),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn carla_towns_with_or_without_the_folder_are_told_from_scenes() {
        for town in [
            "Town01",
            "Town10HD_Opt",
            "Town15",
            "/Game/Carla/Maps/Town05_Opt",
            "town03",
        ] {
            assert!(
                matches!(MapRequest::of(town), MapRequest::CarlaTown(_)),
                "{town}"
            );
        }
        assert_eq!(
            MapRequest::of("/Game/Carla/Maps/Town10HD_Opt"),
            MapRequest::CarlaTown("Town10HD_Opt".into())
        );
        for other in ["Town16", "Town1", "Town00", "Townhall", "nope"] {
            assert_eq!(
                MapRequest::of(other),
                MapRequest::Scene(other.into()),
                "{other}"
            );
        }
        assert_eq!(MapRequest::of("town"), MapRequest::Scene("town".into()));
        assert_eq!(
            MapRequest::of("/Game/Carla/Maps/empty"),
            MapRequest::Scene("empty".into())
        );
        assert_eq!(MapRequest::of(""), MapRequest::Reload);
        assert_eq!(MapRequest::of("OpenDriveMap"), MapRequest::OpenDrive);
    }

    #[test]
    fn a_given_map_holds_for_its_episode_only() {
        let maps = Maps::new(false);
        maps.give(7, 3, Some(EpisodeMap::substitute("Town10HD_Opt")));
        let map = maps.answer(7, 3, "town").unwrap();
        assert_eq!(map.name, "simbus/town (for Town10HD_Opt)");
        assert!(map.spawn_points.len() >= 100);
        assert_eq!(maps.answer(7, 4, "town").unwrap().name, "town");
        assert_eq!(maps.answer(8, 3, "default").unwrap().name, "default");
    }

    #[test]
    fn strict_maps_refuse_stand_ins_and_bad_opendrive_changes_nothing() {
        let e = Maps::new(true).stand_in_for("Town10HD_Opt").unwrap_err();
        assert!(e.to_string().contains("Town10HD_Opt") && e.to_string().contains("--strict-maps"));
        let maps = Maps::new(false);
        assert_eq!(maps.stand_in_for("Town01").unwrap(), TOWN);
        assert!(matches!(maps.opendrive_world(), Err(MapError::NoOpenDrive)));
        assert!(matches!(maps.send("garbage"), Err(MapError::OpenDrive(_))));
        assert!(matches!(maps.opendrive_world(), Err(MapError::NoOpenDrive)));
        let xodr = roads::network(SceneName::Default).to_opendrive();
        maps.send(&xodr).unwrap();
        let (scene, map) = maps.opendrive_world().unwrap();
        maps.give(1, 1, Some(map));
        let answer = maps.answer(1, 1, scene).unwrap();
        assert_eq!(
            (answer.name.as_str(), &*answer.opendrive),
            (OPENDRIVE_MAP, xodr.as_str())
        );
    }
}
