//! The machine-wide setup iceoryx2 needs before a process creates its
//! node: which configuration to use, and whether this user may use the
//! shared directory another user created.
//!
//! iceoryx2 keeps its node and service files under one root directory
//! (`/tmp/iceoryx2/` by default), created with mode 0750 by whichever user
//! came first. Another user then cannot create a node at all, and iceoryx2
//! says only `InternalError`. [`prepare`] turns that into a message naming
//! the directory and the fix: give each user its own root path and prefix in
//! an iceoryx2 configuration file, and point `SIMBUS_IOX2_CONFIG` at it.

use std::path::PathBuf;
use std::sync::OnceLock;

use iceoryx2::config::{Config, ConfigCreationError};
use iceoryx2::prelude::*;

/// The environment variable naming an iceoryx2 TOML configuration file that
/// every simbus process loads before it creates a node.
pub const CONFIG_ENV: &str = "SIMBUS_IOX2_CONFIG";

/// Why this process cannot use iceoryx2 as configured. Each message is a
/// sentence for people: what is wrong and how to fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvironmentError {
    /// `SIMBUS_IOX2_CONFIG` does not name a path iceoryx2 can use.
    #[error("{CONFIG_ENV}={path} is not a usable file path: {source:?}")]
    ConfigPath {
        /// The value of `SIMBUS_IOX2_CONFIG`.
        path: String,
        /// Why iceoryx2 refused it as a path.
        #[source]
        source: SemanticStringError,
    },
    /// iceoryx2 cannot load the configuration file `SIMBUS_IOX2_CONFIG` names.
    #[error("{CONFIG_ENV}={path}: cannot load this iceoryx2 configuration: {source:?}")]
    LoadConfig {
        /// The value of `SIMBUS_IOX2_CONFIG`.
        path: String,
        /// Why iceoryx2 could not load it.
        #[source]
        source: ConfigCreationError,
    },
    /// iceoryx2's shared root directory belongs to another user.
    #[error(
        "this user (uid {uid}) cannot use iceoryx2's shared directory {} (owned by uid {owner}, mode {mode:04o}): \
         it belongs to the user who first ran an iceoryx2 program. Give each user its own: write a file \
         with `[global]` `root-path = \"/tmp/iceoryx2-{uid}/\"` and `prefix = \"iox2_{uid}_\"`, and set \
         {CONFIG_ENV}=/path/to/that.toml for every simbus process (server and clients) of this user",
        root.display()
    )]
    UnusableRoot {
        /// This process's effective user id.
        uid: u32,
        /// The root directory.
        root: PathBuf,
        /// The user id that owns it.
        owner: u32,
        /// Its permission bits.
        mode: u32,
    },
}

/// Loads the configuration `SIMBUS_IOX2_CONFIG` names (once per process)
/// and checks that this user can use iceoryx2's root directory.
///
/// # Errors
///
/// Returns [`EnvironmentError::ConfigPath`] if `SIMBUS_IOX2_CONFIG` is set to
/// something iceoryx2 cannot use as a file path,
/// [`EnvironmentError::LoadConfig`] if iceoryx2 cannot load the file it names
/// (both are remembered: every later call returns the same error), and
/// [`EnvironmentError::UnusableRoot`] if iceoryx2's root directory exists but
/// this user may not read its `nodes` directory (another user created it).
pub fn prepare() -> Result<(), EnvironmentError> {
    static LOADED: OnceLock<Result<(), EnvironmentError>> = OnceLock::new();
    LOADED.get_or_init(load_config).clone()?;
    match unusable_root() {
        Some(problem) => Err(problem),
        None => Ok(()),
    }
}

fn load_config() -> Result<(), EnvironmentError> {
    let Some(path) = std::env::var_os(CONFIG_ENV) else {
        return Ok(());
    };
    let path = path.to_string_lossy().into_owned();
    let file = match FilePath::new(path.as_bytes()) {
        Ok(file) => file,
        Err(source) => return Err(EnvironmentError::ConfigPath { path, source }),
    };
    Config::setup_global_config_from_file(&file)
        .map(drop)
        .map_err(|source| EnvironmentError::LoadConfig { path, source })
}

/// iceoryx2's root directory, as configured.
pub fn root_directory() -> PathBuf {
    let root = Config::global_config().global.root_path();
    PathBuf::from(String::from_utf8_lossy(root.as_bytes()).into_owned())
}

/// `Some(why)` when the root directory exists but this user cannot use it.
fn unusable_root() -> Option<EnvironmentError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let root = root_directory();
    let metadata = std::fs::metadata(&root).ok()?;
    let nodes = root.join("nodes");
    match std::fs::read_dir(&nodes) {
        Err(e) if e.kind() == std::io::ErrorKind::PermissionDenied => {}
        _ => return None,
    }
    // /proc/self belongs to the process's effective user.
    let uid = std::fs::metadata("/proc/self").map_or(u32::MAX, |m| m.uid());
    Some(EnvironmentError::UnusableRoot {
        uid,
        root,
        owner: metadata.uid(),
        mode: metadata.permissions().mode() & 0o7777,
    })
}
