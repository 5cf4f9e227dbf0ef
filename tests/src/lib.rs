//! The fixture of simbus's multi-process tests (ripgrep's `tests/util.rs`
//! is the model): [`TestWorld`] starts a real `sim-server` on a world no
//! other test uses and runs the real binaries against it; every process is
//! killed and reaped on drop, whatever the test did; a failed command
//! prints its command line, status, stdout and stderr.

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

pub use sim_client::process_alive;
pub use simbus_process::{send_signal, ChildGuard};

mod hosts;
mod python;
pub mod raw;
mod root;
mod tmpfs;
pub use hosts::{Host, Mirrored, TwoHosts};
pub use python::{python, python_requirements, python_with_simbus};
pub use root::PrivateRoot;
pub use tmpfs::Tmpfs;

/// A binary of the workspace (`sim-server`, `sim-client`), from the same
/// target directory as the running test (override with `SIMBUS_BIN_DIR`).
pub fn bin(name: &str) -> PathBuf {
    let dir = std::env::var_os("SIMBUS_BIN_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            // target/<profile>/deps/<test-binary>
            let exe = std::env::current_exe().expect("test binary path");
            exe.parent()
                .and_then(|deps| deps.parent())
                .expect("test binary lives in target/<profile>/deps")
                .to_path_buf()
        });
    let path = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.exists(),
        "{} not found: run the suite with `cargo test --workspace` (it builds the binaries)",
        path.display()
    );
    path
}

/// Sends `signal` to every process of the process group `pgid`.
///
/// # Errors
///
/// Returns an error of kind [`InvalidInput`](std::io::ErrorKind::InvalidInput)
/// if `pgid` does not fit a `pid_t`, and the OS error of `kill(2)` otherwise
/// (`ESRCH` if no process is in the group, `EPERM` if this process may not
/// signal it).
pub fn send_signal_to_group(pgid: u32, signal: i32) -> std::io::Result<()> {
    let pgid = libc::pid_t::try_from(pgid)
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
    // SAFETY: kill(2) with a negative pid signals a process group; it has no
    // memory-safety preconditions, a stale group yields ESRCH.
    if unsafe { libc::kill(-pgid, signal) } == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// A world name no other test (or test run) uses.
pub fn unique_world(tag: &str) -> String {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("t-{tag}-{}-{n}", std::process::id())
}

/// A running process whose stdout lines arrive on a channel. Killed and
/// reaped on drop, whatever the test did.
pub struct Proc {
    /// The child, killed and reaped on drop.
    pub guard: ChildGuard,
    command: String,
    /// Stdout, line by line (in a mutex so that a `&Proc` can be shared
    /// with the threads of a scope).
    lines: std::sync::Mutex<mpsc::Receiver<String>>,
    /// Everything written to stderr so far, and a signal for each piece.
    stderr: std::sync::Arc<(std::sync::Mutex<String>, std::sync::Condvar)>,
    stderr_reader: Option<std::thread::JoinHandle<()>>,
}

impl Proc {
    /// Starts `program` with `args`, stdout and stderr captured.
    pub fn spawn(program: &str, args: &[&str]) -> Self {
        Self::spawn_env(program, args, &[])
    }

    /// [`Proc::spawn`] with extra environment variables.
    pub fn spawn_env(program: &str, args: &[&str], env: &[(&str, &std::ffi::OsStr)]) -> Self {
        Self::spawn_wrapped(&[], program, args, env)
    }

    /// [`Proc::spawn_env`] run through `wrapper` (e.g. `ip netns exec NS`,
    /// which execs the program in place: the pid stays the program's).
    pub fn spawn_wrapped(
        wrapper: &[&str],
        program: &str,
        args: &[&str],
        env: &[(&str, &std::ffi::OsStr)],
    ) -> Self {
        let mut command = match wrapper.split_first() {
            Some((first, rest)) => {
                let mut command = Command::new(first);
                command.args(rest).arg(bin(program));
                command
            }
            None => Command::new(bin(program)),
        };
        let mut child = command
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .env(
                "RUST_LOG",
                std::env::var("RUST_LOG").unwrap_or_else(|_| "info".into()),
            )
            // After the default: a caller's RUST_LOG wins.
            .envs(env.iter().copied())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {program}: {e}"));
        let command = format!("{program} {}", args.join(" "));
        let stdout = child.stdout.take().expect("piped stdout");
        let mut stderr_pipe = child.stderr.take().expect("piped stderr");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = std::sync::Arc::new((
            std::sync::Mutex::new(String::new()),
            std::sync::Condvar::new(),
        ));
        let sink = stderr.clone();
        let stderr_reader = std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = stderr_pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                let (text, written) = &*sink;
                text.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
                written.notify_all();
            }
        });
        Self {
            guard: ChildGuard::new(child, Duration::from_secs(5)),
            command,
            lines: std::sync::Mutex::new(lines),
            stderr,
            stderr_reader: Some(stderr_reader),
        }
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.guard.id()
    }

    /// The next stdout line, waiting up to `timeout`.
    pub fn line(&self, timeout: Duration) -> Option<String> {
        self.lines.lock().unwrap().recv_timeout(timeout).ok()
    }

    /// What the process wrote to stderr so far.
    pub fn stderr(&self) -> String {
        self.stderr.0.lock().unwrap().clone()
    }

    /// Waits (at most `timeout`) for a stdout line containing `needle` and
    /// returns it; the lines before it are consumed. Panics, showing
    /// stderr, if none comes.
    pub fn wait_line(&self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        while let Some(line) = self.line(deadline.saturating_duration_since(Instant::now())) {
            if line.contains(needle) {
                return line;
            }
        }
        panic!(
            "{}: no stdout line with '{needle}' within {timeout:?}; stderr:\n{}",
            self.command,
            self.stderr()
        );
    }

    /// Waits (at most `timeout`) until the process has written `needle` to
    /// stderr (a log line: the fixture runs it at `RUST_LOG=info`) and
    /// returns the line that holds it. Panics, showing stderr, if it does
    /// not.
    pub fn wait_stderr(&self, needle: &str, timeout: Duration) -> String {
        let (text, written) = &*self.stderr;
        let (text, waited) = written
            .wait_timeout_while(text.lock().unwrap(), timeout, |text| !text.contains(needle))
            .unwrap();
        assert!(
            !waited.timed_out(),
            "{}: nothing on stderr with '{needle}' within {timeout:?}; stderr:\n{}",
            self.command,
            *text
        );
        let line = text.lines().find(|line| line.contains(needle));
        line.unwrap_or(needle).to_owned()
    }

    /// Waits up to `timeout` for the process to exit by itself, then returns
    /// its status and every stdout line. Panics (after killing it) if it did not.
    pub fn finish(mut self, timeout: Duration) -> Finished {
        let status = self.guard.wait_timeout(timeout).expect("waiting for child");
        let status = match status {
            Some(status) => status,
            None => {
                self.guard.kill().ok();
                panic!(
                    "process {} did not exit within {timeout:?}; stderr:\n{}",
                    self.pid(),
                    self.stderr()
                );
            }
        };
        // The pipes close when the process exits: read them to the end.
        let mut stdout = Vec::new();
        let lines = self.lines.get_mut().unwrap();
        while let Ok(line) = lines.recv_timeout(Duration::from_secs(10)) {
            stdout.push(line);
        }
        if let Some(reader) = self.stderr_reader.take() {
            reader.join().expect("stderr reader");
        }
        Finished {
            command: self.command.clone(),
            status,
            stdout,
            stderr: self.stderr(),
        }
    }
}

/// A process that has exited.
#[derive(Debug)]
pub struct Finished {
    /// The command line that ran.
    pub command: String,
    /// How it exited.
    pub status: ExitStatus,
    /// Every line it wrote to stdout.
    pub stdout: Vec<String>,
    /// Everything it wrote to stderr.
    pub stderr: String,
}

impl Finished {
    /// Each stdout line parsed as JSON.
    pub fn json(&self) -> Vec<serde_json::Value> {
        self.stdout
            .iter()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
            .collect()
    }

    /// Asserts a zero exit status, showing the command, its status, stdout
    /// and stderr if not.
    pub fn assert_success(&self) -> &Self {
        assert!(self.status.success(), "{self}");
        self
    }

    /// Asserts exit code `code` (2: refused input, 1: runtime failure).
    pub fn assert_code(&self, code: i32) -> &Self {
        assert_eq!(self.status.code(), Some(code), "{self}");
        self
    }

    /// The first stdout line starting with `prefix`; panics showing the
    /// whole run if there is none.
    pub fn line_starting(&self, prefix: &str) -> &str {
        self.stdout
            .iter()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no stdout line starts with {prefix:?}:\n{self}"))
    }
}

impl std::fmt::Display for Finished {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "command: {}", self.command)?;
        writeln!(f, "status: {}", self.status)?;
        writeln!(f, "stdout:\n{}", self.stdout.join("\n"))?;
        write!(f, "stderr:\n{}", self.stderr)
    }
}

/// Runs `sim-client --world <world> <args>` to completion (at most 60 s).
pub fn client(world: &str, args: &[&str]) -> Finished {
    let mut all = vec!["--world", world];
    all.extend_from_slice(args);
    Proc::spawn("sim-client", &all).finish(Duration::from_secs(60))
}

/// A `sim-server` on `world` with `args`, up and answering when returned.
pub fn server(world: &str, args: &[&str]) -> Proc {
    let mut all = vec!["--world", world];
    all.extend_from_slice(args);
    let proc = Proc::spawn("sim-server", &all);
    wait_until_up(world, &proc);
    proc
}

/// Waits until the server of `world` answers `status` (at most 30 s).
pub fn wait_until_up(world: &str, proc: &Proc) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if sim_client::Client::connect(world, Duration::from_millis(500)).is_ok() {
            return;
        }
        assert!(
            Instant::now() < deadline && process_alive(proc.pid()),
            "server on {world} did not come up; stderr:\n{}",
            proc.stderr()
        );
    }
}

/// `status --json` of `world`.
pub fn status(world: &str) -> serde_json::Value {
    let out = client(world, &["status", "--json"]);
    out.assert_success();
    out.json().pop().expect("one status object")
}

/// Runs `sim-client --world <world> --timeout 1 <args>` where no server
/// runs, and asserts it ends by itself (no hang: it is killed and the test
/// fails after 30 s) with exit code 1 and a message naming the problem.
pub fn assert_fails_without_server(world: &str, args: &[&str]) {
    let mut all = vec!["--world", world, "--timeout", "1"];
    all.extend_from_slice(args);
    let out = Proc::spawn("sim-client", &all).finish(Duration::from_secs(30));
    assert_eq!(out.status.code(), Some(1), "{args:?}: {}", out.stderr);
    assert!(
        out.stderr.contains(&format!(
            "no simbus server answered on world '{world}' within 1s"
        )),
        "{args:?}: {}",
        out.stderr
    );
}

impl std::fmt::Debug for Proc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Proc")
            .field("pid", &self.pid())
            .finish_non_exhaustive()
    }
}

/// One world for one test: a unique name and its `sim-server`, up and
/// answering, killed and reaped on drop.
#[derive(Debug)]
pub struct TestWorld {
    name: String,
    /// The server process.
    pub server: Proc,
}

impl TestWorld {
    /// Starts `sim-server --world <unique> <args>` and waits until it answers.
    pub fn start(tag: &str, args: &[&str]) -> Self {
        let name = unique_world(tag);
        let server = server(&name, args);
        Self { name, server }
    }

    /// The world's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// A client of this world.
    pub fn connect(&self) -> sim_client::Client {
        sim_client::Client::connect(&self.name, Duration::from_secs(20))
            .unwrap_or_else(|e| panic!("connecting to {}: {e}", self.name))
    }

    /// Runs `sim-client --world <this> <args>` to completion.
    pub fn cli(&self, args: &[&str]) -> Finished {
        client(&self.name, args)
    }

    /// Starts `sim-client --world <this> <args>` in the background.
    pub fn spawn_cli(&self, args: &[&str]) -> Proc {
        let mut all = vec!["--world", self.name.as_str()];
        all.extend_from_slice(args);
        Proc::spawn("sim-client", &all)
    }

    /// `sim-client carla-gateway --port 0 --json <args>` on this world, and
    /// the JSON line it prints once it listens (its ports, host, world).
    pub fn spawn_gateway(&self, args: &[&str]) -> (Proc, serde_json::Value) {
        let mut all = vec!["carla-gateway", "--port", "0", "--json"];
        all.extend_from_slice(args);
        let gateway = self.spawn_cli(&all);
        let line = gateway
            .line(Duration::from_secs(30))
            .unwrap_or_else(|| panic!("the gateway said nothing; stderr:\n{}", gateway.stderr()));
        let json = serde_json::from_str(&line).unwrap_or_else(|e| panic!("not JSON ({e}): {line}"));
        (gateway, json)
    }

    /// `status --json` of this world.
    pub fn status(&self) -> serde_json::Value {
        status(&self.name)
    }

    /// Asserts the world's time settings, what a change of them touches:
    /// synchronous or not, its fixed step (`None`: a variable step), and
    /// nobody ticking it; `context` leads the message shown if not.
    pub fn assert_time_settings(&self, sync: bool, step: Option<f64>, context: &str) {
        let status = self.status();
        let want = (
            serde_json::Value::from(sync),
            step.map_or(serde_json::Value::Null, serde_json::Value::from),
            serde_json::Value::Null,
        );
        let got = (
            status["synchronous_mode"].clone(),
            status["fixed_delta_seconds"].clone(),
            status["ticker"].clone(),
        );
        assert_eq!(
            got, want,
            "{context}(synchronous_mode, fixed_delta_seconds, ticker) of {status}"
        );
    }
}

impl std::ops::Deref for TestWorld {
    type Target = str;

    /// The world's name, so a `&TestWorld` goes wherever a world name does.
    fn deref(&self) -> &str {
        &self.name
    }
}

impl std::fmt::Display for TestWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name)
    }
}

/// A world in synchronous mode with a fixed step of 0.02 s (and `args`),
/// a client of it, and that client's claim on the ticker.
pub fn sync_world(tag: &str, args: &[&str]) -> (TestWorld, sim_client::Client, sim_client::Ticker) {
    sync_world_at(tag, "0.02", args)
}

/// [`sync_world`] with a fixed step of `delta_seconds`.
pub fn sync_world_at(
    tag: &str,
    delta_seconds: &str,
    args: &[&str],
) -> (TestWorld, sim_client::Client, sim_client::Ticker) {
    let mut all = vec!["--sync", "--delta-seconds", delta_seconds];
    all.extend_from_slice(args);
    let world = TestWorld::start(tag, &all);
    let client = world.connect();
    let ticker = client.claim_ticker().expect("claiming the ticker");
    (world, client, ticker)
}

/// A directory for one test's files, removed when dropped.
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl Scratch {
    /// A new, empty directory under the system's temporary directory.
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(unique_world(tag));
        std::fs::create_dir_all(&dir).expect("creating a scratch directory");
        Self(dir)
    }

    /// The directory.
    pub fn path(&self) -> &std::path::Path {
        &self.0
    }

    /// The path of `name` in it.
    pub fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to `name` in it and returns its path.
    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.file(name);
        std::fs::write(&path, bytes).expect("writing a scratch file");
        path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Ticks until the replay running in `client`'s world ends and returns
/// every replayed frame, one per tick (frames queued from before the
/// replay are skipped). Fails unless the replay finished.
pub fn replayed_frames(
    client: &mut sim_client::Client,
    ticker: &mut sim_client::Ticker,
) -> Vec<sim_client::WorldSnapshot> {
    let timeout = Duration::from_secs(20);
    let mut frames = Vec::new();
    loop {
        let ticked = ticker.tick(timeout).expect("tick");
        let snapshot = loop {
            let snapshot = client.wait_for_tick(timeout).expect("replayed frame");
            if snapshot.header.flags & shared_types::FrameHeader::REPLAY != 0
                && snapshot.frame() == ticked
            {
                break snapshot;
            }
        };
        frames.push(snapshot);
        let status = client.recorder_status().expect("recorder status");
        if status.replay.state != "running" {
            assert_eq!(status.replay.state, "finished", "{status:?}");
            return frames;
        }
    }
}

/// Waits (at most 60 s) until the world of `client` has `count` lockstep
/// participants. Joining has no event of its own, so this asks the
/// server's status, which answers in microseconds; a status that times
/// out (a debug-build server while dozens of processes start on two
/// cores) is asked again within the same 60 s.
pub fn wait_for_participants(client: &sim_client::Client, count: u32) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let joined = match client.status() {
            Ok(status) => status.participants,
            Err(sim_client::RequestError::Timeout { .. }) if Instant::now() < deadline => continue,
            Err(e) => panic!("status: {e}"),
        };
        if joined >= count {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "only {joined} of {count} lockstep participants joined"
        );
        std::thread::yield_now();
    }
}

/// Rewrites `from` into `to` through the `mcap` crate, renaming schema
/// `rename.0` to `rename.1`.
pub fn rewrite(from: &std::path::Path, to: &std::path::Path, rename: (&str, &str)) {
    let bytes = std::fs::read(from).unwrap();
    let mut writer =
        mcap::Writer::new(std::io::BufWriter::new(std::fs::File::create(to).unwrap())).unwrap();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        let mut channel = (*message.channel).clone();
        if let Some(schema) = &channel.schema {
            if schema.name == rename.0 {
                let mut schema = (**schema).clone();
                schema.name = rename.1.to_string();
                channel.schema = Some(std::sync::Arc::new(schema));
            }
        }
        writer
            .write(&mcap::Message {
                channel: std::sync::Arc::new(channel),
                ..message
            })
            .unwrap();
    }
    writer.finish().unwrap();
}
