//! The Python tests (`tests/python`, pytest): CARLA 0.9.16's own client
//! library against the gateway, a Foxglove WebSocket client against the
//! live view, a Zenoh peer and a ROS 2 CDR decoder against the Zenoh
//! bridge, and simbus's own Python package (`sim-client/python`, built
//! from this checkout into the venv: `test_simbus_*.py`); run in the venv
//! the fixture creates with pinned packages. Each test starts its own
//! server and the process it checks.

#[test]
fn the_python_tests_pass() {
    let python = simbus_tests::python_with_simbus();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("python");
    let bin_dir = simbus_tests::bin("sim-client")
        .parent()
        .expect("the binaries' directory")
        .to_path_buf();
    let output = std::process::Command::new(python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(&dir)
        .env("SIMBUS_BIN_DIR", bin_dir)
        .output()
        .expect("running pytest");
    assert!(
        output.status.success(),
        "pytest failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}
