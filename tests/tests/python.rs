//! The Python tests (`tests/python`, pytest): CARLA 0.9.16's own client
//! library against the gateway, a Foxglove WebSocket client against the
//! live view, a Zenoh peer and a ROS 2 CDR decoder against the Zenoh
//! bridge, and simbus's own Python package (`sim-client/python`, built
//! from this checkout into the venv: `test_simbus_*.py`); run in the venv
//! the fixture creates with pinned packages. Each test starts its own
//! server and the process it checks, on free ports, so the groups below
//! run side by side (one pytest each, as the test harness's threads take
//! them): every file belongs to exactly one group, by its name.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The venv's `python` with `simbus` built and installed once for every
/// group (installing it again under a running pytest would swap its files).
fn python() -> &'static Path {
    static PYTHON: OnceLock<PathBuf> = OnceLock::new();
    PYTHON.get_or_init(simbus_tests::python_with_simbus)
}

/// `tests/python`.
fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("python")
}

/// The groups the test files are run in, by name: CARLA's own scripts (the
/// longest, and one after another), the other CARLA tests in two halves,
/// simbus's package, and the rest (Foxglove, Zenoh, any new file).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    CarlaScripts,
    CarlaFirstHalf,
    CarlaSecondHalf,
    Simbus,
    Others,
}

/// Every test file and its group.
fn files() -> Vec<(PathBuf, Group)> {
    let mut names: Vec<String> = std::fs::read_dir(dir())
        .expect("tests/python")
        .filter_map(Result::ok)
        .map(|entry| entry.file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with("test_") && name.ends_with(".py"))
        .collect();
    names.sort();
    let carla: Vec<&String> = names
        .iter()
        .filter(|n| n.starts_with("test_carla_") && !n.starts_with("test_carla_scripts_"))
        .collect();
    let half = carla.len().div_ceil(2);
    names
        .iter()
        .map(|name| {
            let group = if name.starts_with("test_carla_scripts_") {
                Group::CarlaScripts
            } else if let Some(i) = carla.iter().position(|c| *c == name) {
                if i < half {
                    Group::CarlaFirstHalf
                } else {
                    Group::CarlaSecondHalf
                }
            } else if name.starts_with("test_simbus_") {
                Group::Simbus
            } else {
                Group::Others
            };
            (dir().join(name), group)
        })
        .collect()
}

/// Runs pytest on `group`'s files and fails with its output if it fails.
fn pytest(group: Group) {
    let files: Vec<PathBuf> = files()
        .into_iter()
        .filter(|(_, g)| *g == group)
        .map(|(path, _)| path)
        .collect();
    assert!(!files.is_empty(), "no test file in {group:?}");
    let bin_dir = simbus_tests::bin("sim-client")
        .parent()
        .expect("the binaries' directory")
        .to_path_buf();
    let output = std::process::Command::new(python())
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir"])
        .arg(dir())
        .args(&files)
        .env("SIMBUS_BIN_DIR", bin_dir)
        .output()
        .expect("running pytest");
    assert!(
        output.status.success(),
        "pytest {group:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn carla_scripts_run_unchanged() {
    pytest(Group::CarlaScripts);
}

#[test]
fn carla_client_first_half() {
    pytest(Group::CarlaFirstHalf);
}

#[test]
fn carla_client_second_half() {
    pytest(Group::CarlaSecondHalf);
}

#[test]
fn simbus_python_package() {
    pytest(Group::Simbus);
}

#[test]
fn foxglove_zenoh_and_the_rest() {
    pytest(Group::Others);
}

#[test]
fn every_test_file_is_in_one_group_and_every_group_has_files() {
    let files = files();
    assert!(files.len() >= 30, "{files:?}");
    for group in [
        Group::CarlaScripts,
        Group::CarlaFirstHalf,
        Group::CarlaSecondHalf,
        Group::Simbus,
        Group::Others,
    ] {
        assert!(files.iter().any(|(_, g)| *g == group), "{group:?} is empty");
    }
}
