//! What `recorder status`, `info`, `collisions` and `blocked` print as
//! text (their `--json` is the data itself).

use sim_client::RecorderStatus;
use simbus_recording::inspect;

use crate::cli::words::count;

pub(super) fn status(status: &RecorderStatus) {
    if status.recording {
        println!(
            "recording  {} ({} so far)",
            status.path,
            count(status.frames, "frame")
        );
    } else if status.recorded {
        println!(
            "recorder   stopped; last: {} ({}, {})",
            status.path,
            count(status.frames, "frame"),
            count(status.bytes, "byte")
        );
    } else {
        println!("recorder   idle (nothing recorded since the server started)");
    }
    let r = &status.replay;
    // Without a recording, the path is the replay's file.
    let file = if status.recorded || status.path.is_empty() {
        String::new()
    } else {
        format!(" of {}", status.path)
    };
    println!(
        "replay     {} ({}): {} of {}{file}, time factor {}",
        r.state,
        r.mode,
        r.frames,
        count(r.total, "frame"),
        r.time_factor
    );
    if r.mode == "resimulate" && r.frames > 0 {
        match r.mismatch {
            None => println!("verified   identical: {}", count(r.verified, "frame")),
            Some(m) => println!(
                "verified   differs at frame {} (actor {})",
                m.frame, m.actor
            ),
        }
    }
    if !status.message.is_empty() {
        println!("message    {}", status.message);
    }
}

pub(super) fn info(info: &inspect::FileInfo) {
    let h = &info.header;
    println!(
        "file         {} ({}, compression {:.1}x)",
        info.path,
        count(info.bytes, "byte"),
        info.compression_ratio
    );
    println!(
        "written by   simbus {} (recording version {}, protocol {})",
        h.simbus_version, h.recording_version, h.protocol_version
    );
    println!(
        "world        {} (scene {}, seed {})",
        h.world, h.scene, h.seed
    );
    let settings = shared_types::WorldSettings::from(h.settings);
    for (name, value) in crate::cli::describe::settings_lines(&settings) {
        println!("{name:<12} {value}");
    }
    // Frame ids start again with each episode: one range per episode.
    match &info.episode_list[..] {
        [] => println!("frames       0 (none in a complete chunk yet)"),
        [one] => println!(
            "frames       {} (frame {} to {}), {:.3} s",
            count(info.frames, "frame"),
            one.first_frame,
            one.last_frame,
            info.duration_seconds
        ),
        list => {
            println!(
                "frames       {} in {}, {:.3} s",
                count(info.frames, "frame"),
                count(list.len() as u64, "episode"),
                info.duration_seconds
            );
            for e in list {
                println!(
                    "  episode {:<4} {} (frame {} to {})",
                    e.episode,
                    count(e.frames, "frame"),
                    e.first_frame,
                    e.last_frame
                );
            }
        }
    }
    println!(
        "actors       {} spawned, {} destroyed, at most {} at once",
        info.actors_spawned, info.actors_destroyed, info.max_actors
    );
    println!("commands     {}", info.commands);
    println!("collisions   {}", info.collisions);
    println!(
        "sensors      {} ({} recorded)",
        info.sensors,
        count(info.captures, "capture")
    );
    println!("keyframes    {}", info.keyframes);
    match (&info.stopped, info.truncated) {
        (_, true) => println!(
            "closed       no: still being recorded, or cut short (its server was killed or its disk filled); readable up to frame {}, its last complete chunk",
            info.last_frame
        ),
        (Some(reason), false) => println!("closed       yes ({reason})"),
        (None, false) => println!("closed       no stop event"),
    }
    for f in &info.frame_list {
        println!(
            "  frame {:>8}  episode {:>3}  t {:>12.6} s  dt {:.6} s  substeps {:>2}  actors {}",
            f.frame, f.episode, f.elapsed_seconds, f.delta_seconds, f.substeps, f.actors
        );
    }
}

/// The convention of every time `recorder collisions` and `blocked` print.
const RECORDING_TIME: &str =
    "times are recording seconds: since the recording's start, as CARLA's recorder counts";

pub(super) fn collisions(list: &[inspect::Collision]) {
    println!(
        "{:>8} {:>10}  {:<18} {:<18} {:>10}",
        "frame", "time (s)", "actor", "actor", "impulse"
    );
    for c in list {
        println!(
            "{:>8} {:>10.3}  {:<18} {:<18} {:>10.3}",
            c.frame,
            c.time_seconds,
            format!("{} ({})", c.actor_a, c.kind_a),
            format!("{} ({})", c.actor_b, c.kind_b),
            c.impulse
        );
    }
    println!(
        "{} ({RECORDING_TIME})",
        count(list.len() as u64, "collision")
    );
}

pub(super) fn blocked(list: &[inspect::BlockedActor], min_time: f64, min_distance: f64) {
    for actor in list {
        println!(
            "actor {} ({}): blocked {}",
            actor.actor,
            actor.kind,
            count(actor.stretches.len() as u64, "time")
        );
        println!(
            "  {:>8} {:>10} {:>12} {:>10}",
            "frame", "from (s)", "for (s)", "moved (m)"
        );
        for b in &actor.stretches {
            println!(
                "  {:>8} {:>10.3} {:>12.3} {:>10.3}",
                b.frame, b.from_seconds, b.duration_seconds, b.distance
            );
        }
    }
    println!(
        "{} blocked for at least {min_time} s (moving less than {min_distance} m; {RECORDING_TIME})",
        count(list.len() as u64, "actor")
    );
}
