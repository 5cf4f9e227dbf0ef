//! `sim-client recorder info FILE --carla-text` prints the text CARLA's
//! server answers to `show_recorder_file_info` (issue #28): `Version:`,
//! `Map:`, `Date:`, each frame with events as `Frame N at T seconds` (every
//! frame and its positions with `--all`), ` Create ID: type_id (type) at
//! (x, y, z)` and ` Destroy ID` lines, then `Frames: N` and `Duration: T
//! seconds`, so a script that parses CARLA's text reads simbus's. simbus's
//! own text stays the default; `--json` and `--carla-text` exclude each
//! other.

use std::path::Path;
use std::time::Duration;

use shared_types::Command;
use simbus_tests::{Finished, Scratch};

const T: Duration = Duration::from_secs(20);

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The lines that follow the line `line` of `out`, up to the next frame.
fn frame_lines<'a>(out: &'a Finished, line: &str) -> Vec<&'a str> {
    let at = out
        .stdout
        .iter()
        .position(|l| l == line)
        .unwrap_or_else(|| panic!("no line {line:?}:\n{out}"));
    out.stdout[at + 1..]
        .iter()
        .take_while(|l| l.starts_with(' '))
        .map(String::as_str)
        .collect()
}

#[test]
fn carla_text_is_carlas_file_info_layout() {
    let scratch = Scratch::new("rec-carla-text");
    let path = scratch.file("run.mcap");
    let (world, client, mut ticker) =
        simbus_tests::sync_world_at("rec-carla-text", "0.05", &["--seed", "3"]);
    // Five frames 0.05 s apart: a box appears in the third, is gone in the
    // fourth.
    client.start_recorder(&path, false).unwrap();
    ticker.tick(T).unwrap();
    let spawned = client
        .spawn_actor(Command::spawn_box([0.0, 30.0, 0.0], [0.5; 3]))
        .unwrap();
    ticker.tick(T).unwrap();
    client.destroy(spawned).unwrap();
    ticker.tick(T).unwrap();
    ticker.tick(T).unwrap();
    client.stop_recorder().unwrap();

    let json = world.cli(&["recorder", "info", text(&path), "--all", "--json"]);
    json.assert_success();
    let info = json.json().pop().unwrap();
    let first_actors = info["frame_list"][0]["actors"].as_u64().unwrap() as usize;
    assert_eq!(info["frames"], 5, "{info}");

    let out = world.cli(&["recorder", "info", text(&path), "--carla-text"]);
    out.assert_success();
    assert_eq!(out.stdout[0], "Version: 1", "{out}");
    assert_eq!(
        out.stdout[1],
        format!("Map: {}", info["header"]["scene"].as_str().unwrap())
    );
    let date: String = out.stdout[2]
        .chars()
        .map(|c| if c.is_ascii_digit() { '9' } else { c })
        .collect();
    assert_eq!(date, "Date: 99/99/99 99:99:99", "{out}");
    // Every actor of the first frame is created in it, as CARLA's recorder
    // adds the actors that exist when it starts.
    let creates = frame_lines(&out, "Frame 1 at 0 seconds");
    let creates: Vec<_> = creates
        .iter()
        .filter(|l| l.starts_with(" Create "))
        .collect();
    assert_eq!(creates.len(), first_actors, "{out}");
    let created = format!(" Create {spawned}: static.prop.box (0) at (");
    assert!(
        frame_lines(&out, "Frame 3 at 0.1 seconds")
            .iter()
            .any(|l| l.starts_with(&created)),
        "{out}"
    );
    assert!(
        frame_lines(&out, "Frame 4 at 0.15 seconds").contains(&&*format!(" Destroy {spawned}")),
        "{out}"
    );
    // Without --all a frame is listed only for its events.
    for (i, line) in out.stdout.iter().enumerate() {
        if line.starts_with("Frame ") {
            assert!(
                out.stdout[i + 1].starts_with(' '),
                "{line} has no events:\n{out}"
            );
        }
    }
    let tail = &out.stdout[out.stdout.len() - 3..];
    assert_eq!(tail, ["", "Frames: 5", "Duration: 0.2 seconds"], "{out}");

    // --all: every frame, each with its positions.
    let all = world.cli(&["recorder", "info", text(&path), "--all", "--carla-text"]);
    all.assert_success();
    let titles: Vec<_> = all
        .stdout
        .iter()
        .filter(|l| l.starts_with("Frame "))
        .collect();
    assert_eq!(
        titles,
        [
            "Frame 1 at 0 seconds",
            "Frame 2 at 0.05 seconds",
            "Frame 3 at 0.1 seconds",
            "Frame 4 at 0.15 seconds",
            "Frame 5 at 0.2 seconds"
        ],
        "{all}"
    );
    let positions = all
        .stdout
        .iter()
        .filter(|l| l.starts_with(" Positions: "))
        .count();
    assert_eq!(positions, 5, "{all}");

    // simbus's own text stays the default; --json is not CARLA's text.
    let own = world.cli(&["recorder", "info", text(&path)]);
    own.assert_success();
    assert!(
        !own.stdout.iter().any(|l| l.starts_with("Version: ")),
        "{own}"
    );
    let both = world.cli(&["recorder", "info", text(&path), "--carla-text", "--json"]);
    both.assert_code(2);
    assert!(both.stderr.contains("--json"), "{both}");
    // A file that is not there is refused naming it.
    let missing = scratch.file("missing.mcap");
    let refused = world.cli(&["recorder", "info", text(&missing), "--carla-text"]);
    refused.assert_code(2);
    assert!(refused.stderr.contains(text(&missing)), "{refused}");
}
