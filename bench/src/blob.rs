//! The floor under the sensor delivery rows: raw iceoryx2 moving a blob of
//! the same size from a writer to a reader process spinning on it, on the
//! service of a simbus depth camera (its description,
//! `WorldServices::sensor`), with no simbus server or client.
//!
//! Each sample is written whole first, element by element as a capture is
//! rendered into its sample, then stamped and sent; the reader reads its
//! first and last element.

use std::io::{BufRead, BufReader};
use std::mem::MaybeUninit;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::Context;
use shared_types::limits::WorldLimits;
use shared_types::{SensorHeader, ServiceNames, WorldName};
use simbus_process::ChildGuard;
use simbus_transport::spec::{SensorSpec, WorldServices};

use crate::stats::Latencies;
use crate::support::now_ns;

/// The service a depth camera of the world `world` would have.
fn service(world: &str) -> anyhow::Result<SensorSpec<f32>> {
    let names = ServiceNames::new(&WorldName::new(world)?);
    Ok(WorldServices::new(&names)?.sensor::<f32>(1)?)
}

/// `samples` blobs of `bytes`, paced `pace` apart, each written whole, then
/// stamped and sent; the latency from the stamp to a spinning reader
/// process holding it (its first and last element read).
pub(crate) fn floor(bytes: usize, samples: u64, pace: Duration) -> anyhow::Result<Latencies> {
    let name = format!("bench-blob-{}-{bytes}", std::process::id());
    let spec = service(&name)?;
    let node = simbus_transport::node("simbus-bench-blob")?;
    let factory = spec
        .create(&node, &WorldLimits::default())
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let publisher = spec
        .publisher(&factory, bytes / 4)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let warmup = samples / 10;
    let total = samples + warmup;
    let mut child = Command::new(std::env::current_exe()?)
        .args(["peer", "--kind", "blob-reader", "--name", &name])
        .args(["--samples", &total.to_string()])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("starting the blob reader")?;
    let stdout = child.stdout.take().context("blob reader stdout")?;
    let mut guard = ChildGuard::new(child, Duration::from_secs(2));
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let ready = lines.recv_timeout(Duration::from_secs(30))?;
    anyhow::ensure!(ready == "ready", "the blob reader did not start: {ready}");
    for i in 0..total {
        std::thread::sleep(pace);
        let mut sample = publisher
            .loan_slice_uninit(bytes / 4)
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        // Written as a renderer writes, element by element (not memset's
        // stores, which go around the caches).
        for (j, slot) in sample.payload_mut().iter_mut().enumerate() {
            *slot = MaybeUninit::new((i as usize ^ j) as f32);
        }
        // SAFETY: every element was written just above.
        let mut sample = unsafe { sample.assume_init() };
        *sample.user_header_mut() = SensorHeader {
            frame: i,
            platform_timestamp: now_ns() as f64 * 1e-9,
            ..SensorHeader::default()
        };
        sample.send().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    }
    let report = lines
        .recv_timeout(Duration::from_secs(60))
        .context("the blob reader's report")?;
    guard.wait_timeout(Duration::from_secs(10))?;
    let mut latencies = Latencies::new();
    let all: Vec<u64> = report
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    anyhow::ensure!(
        all.len() as u64 == total,
        "the blob reader lost {} samples",
        total.saturating_sub(all.len() as u64)
    );
    for latency in all.into_iter().skip(warmup as usize) {
        latencies.record(latency);
    }
    Ok(latencies)
}

/// The reader (`peer --kind blob-reader`): spins on `name` until it held
/// `samples` blobs, then prints each one's latency on one line.
pub(crate) fn reader(name: &str, samples: u64) -> anyhow::Result<()> {
    let spec = service(name)?;
    let node = simbus_transport::node("simbus-bench-blob-reader")?;
    let factory = spec.open(&node).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let subscriber = spec
        .subscriber(&factory)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    println!("ready");
    let mut out = Vec::with_capacity(samples as usize);
    let give_up = std::time::Instant::now() + Duration::from_secs(60 + samples / 100);
    while (out.len() as u64) < samples {
        anyhow::ensure!(std::time::Instant::now() < give_up, "no blob for too long");
        let Some(sample) = subscriber.receive().map_err(|e| anyhow::anyhow!("{e:?}"))? else {
            std::hint::spin_loop();
            continue;
        };
        let payload = sample.payload();
        // Hold it: the first and last element read.
        let (first, last) = (payload[0], payload[payload.len() - 1]);
        let held = now_ns();
        anyhow::ensure!(first.is_finite() && last.is_finite(), "a torn blob");
        let sent = (sample.user_header().platform_timestamp * 1e9) as u64;
        out.push(held.saturating_sub(sent));
    }
    let line: Vec<String> = out.iter().map(u64::to_string).collect();
    println!("{}", line.join(" "));
    Ok(())
}
