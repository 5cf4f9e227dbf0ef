//! [`ClientBuilder`]: a [`Client`] with its options set before it connects.

use std::time::Duration;

use crate::client::DEFAULT_REQUEST_TIMEOUT;
use crate::{Client, ConnectError, WaitMode};

/// How long [`ClientBuilder::connect`] waits for the server unless told
/// otherwise.
pub const DEFAULT_CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// Options for a [`Client`], from [`Client::builder`]; [`ClientBuilder::connect`]
/// connects with them.
///
/// A server runs on a thread here, so the example runs as a test:
///
/// ```
/// use std::time::Duration;
/// use sim_client::prelude::*;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
/// # let name = format!("doc-{}-{}", "builder", std::process::id());
/// # let stop = Arc::new(AtomicBool::new(false));
/// # let server = {
/// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
/// #     std::thread::spawn(move || {
/// #         let mut config = sim_server::ServerConfig::new(world);
/// #         config.settings.fixed_delta_seconds = Some(0.01);
/// #         config.realtime = true;
/// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
/// #     })
/// # };
/// let mut client = Client::builder(&name)
///     .timeout(Duration::from_secs(5))
///     .wait_mode(WaitMode::Spin)
///     .request_timeout(Duration::from_secs(1))
///     .every_frame(true)
///     .connect()?;
/// assert_eq!(client.world().as_str(), name);
/// // Every frame, in order: each next frame is the one after the last.
/// let first = client.wait_for_tick(Duration::from_secs(1))?;
/// let second = client.wait_for_tick(Duration::from_secs(1))?;
/// assert_eq!((second.frame(), second.missed), (first.frame() + 1, 0));
/// # drop(client);
/// # stop.store(true, Ordering::Relaxed);
/// # server.join().expect("server thread")?;
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone)]
#[must_use = "a builder does nothing until `connect`"]
pub struct ClientBuilder {
    world: String,
    timeout: Duration,
    wait_mode: WaitMode,
    request_timeout: Duration,
    every_frame: bool,
}

impl ClientBuilder {
    /// Options for connecting to `world`, all at their defaults.
    pub fn new(world: impl Into<String>) -> Self {
        Self {
            world: world.into(),
            timeout: DEFAULT_CONNECT_TIMEOUT,
            wait_mode: WaitMode::default(),
            request_timeout: DEFAULT_REQUEST_TIMEOUT,
            every_frame: false,
        }
    }

    /// How long to wait for the server to appear and publish its current
    /// frame ([`DEFAULT_CONNECT_TIMEOUT`] unless set).
    pub fn timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// How waits for frames wait ([`Client::set_wait_mode`]; blocking
    /// unless set).
    pub fn wait_mode(mut self, mode: WaitMode) -> Self {
        self.wait_mode = mode;
        self
    }

    /// How long requests wait for an answer
    /// ([`Client::set_request_timeout`]; [`DEFAULT_REQUEST_TIMEOUT`] unless set).
    pub fn request_timeout(mut self, timeout: Duration) -> Self {
        self.request_timeout = timeout;
        self
    }

    /// In asynchronous mode, hand out every queued frame in order
    /// ([`Client::set_every_frame`]; off unless set).
    pub fn every_frame(mut self, every_frame: bool) -> Self {
        self.every_frame = every_frame;
        self
    }

    /// Connects with these options (see [`Client::connect`]).
    ///
    /// # Errors
    ///
    /// Returns the [`ConnectError`]s of [`Client::connect`]:
    /// [`ConnectError::InvalidWorld`] for a name that is not a world name,
    /// [`ConnectError::NoServer`] if no server owns the world within the
    /// [`timeout`](ClientBuilder::timeout), [`ConnectError::NotAnswering`],
    /// [`ConnectError::ProtocolMismatch`], [`ConnectError::Full`], and so on.
    pub fn connect(self) -> Result<Client, ConnectError> {
        let mut client = Client::connect(&self.world, self.timeout)?;
        client.set_wait_mode(self.wait_mode);
        client.set_request_timeout(self.request_timeout);
        client.set_every_frame(self.every_frame);
        Ok(client)
    }
}

impl Client {
    /// Options for connecting to `world`; [`ClientBuilder::connect`]
    /// connects. [`Client::connect`] is the short form.
    pub fn builder(world: impl Into<String>) -> ClientBuilder {
        ClientBuilder::new(world)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_those_of_connect() {
        let builder = Client::builder("lab");
        assert_eq!(builder.world, "lab");
        assert_eq!(builder.timeout, DEFAULT_CONNECT_TIMEOUT);
        assert_eq!(builder.wait_mode, WaitMode::default());
        assert_eq!(builder.request_timeout, DEFAULT_REQUEST_TIMEOUT);
        assert!(!builder.every_frame);
        let builder = builder
            .timeout(Duration::from_secs(9))
            .wait_mode(WaitMode::Spin)
            .request_timeout(Duration::from_millis(250))
            .every_frame(true);
        assert_eq!(builder.timeout, Duration::from_secs(9));
        assert_eq!(builder.wait_mode, WaitMode::Spin);
        assert_eq!(builder.request_timeout, Duration::from_millis(250));
        assert!(builder.every_frame);
    }

    #[test]
    fn a_bad_world_name_is_refused_before_connecting() {
        let error = Client::builder("no/slashes")
            .timeout(Duration::from_millis(1))
            .connect()
            .expect_err("an invalid name");
        assert!(matches!(error, ConnectError::InvalidWorld(_)), "{error:?}");
    }
}
