//! A client's sensors: the sensor-request port, spawning, listing and
//! destroying sensors, and opening a reader of one.

use iceoryx2::prelude::*;
use shared_types::{
    ResponseStatus, SensorInfo, SensorRefusal, SensorRequest, SensorRequestKind, SensorSpec,
};
use simbus_transport::spec::{RequestSpec, WorldServices};

use crate::rpc::{client_error, Answer, PortNames, RequestPort};
use crate::sensor::SensorRequestClient;
use crate::wait::Wait;
use crate::{Client, RequestError, Sensor, SensorError};

impl Client {
    /// The sensor-request port, opened on first use and kept.
    fn sensor_port(&self) -> Result<&SensorRequestClient, RequestError> {
        if let Some(port) = self.sensor_port.get() {
            return Ok(port);
        }
        let specs = WorldServices::new(&self.names)
            .map_err(|e| RequestError::transport("service name", e))?;
        let names = PortNames {
            service: "sensor service",
            client: "sensor client",
            send: "sensor send",
            clients: "clients sending sensor requests",
        };
        let port = self.slice_answer_port(&specs.sensors, names)?;
        Ok(self.sensor_port.get_or_init(|| port))
    }

    /// A request port of `spec`, a service answering slices, its errors
    /// saying `names`.
    pub(crate) fn slice_answer_port<Req, Resp, Header>(
        &self,
        spec: &RequestSpec<Req, (), [Resp], Header>,
        names: PortNames,
    ) -> Result<RequestPort<Req, [Resp], (), Header>, RequestError>
    where
        Req: std::fmt::Debug + ZeroCopySend + 'static,
        Resp: std::fmt::Debug + ZeroCopySend + 'static,
        Header: std::fmt::Debug + ZeroCopySend + 'static,
        [Resp]: Answer<Header>,
    {
        let service = spec
            .open(&self.node)
            .map_err(|e| RequestError::transport(names.service, e))?;
        let client = service.client_builder().create().map_err(|e| {
            let max = service.static_config().max_clients();
            client_error(e, max, names.clients, names.client)
        })?;
        Ok(RequestPort::new(
            client,
            None,
            spec.doorbell,
            names.send,
            self.world.as_str(),
            self.server_pid,
        ))
    }

    fn sensor_request(&self, request: SensorRequest) -> Result<Vec<SensorInfo>, SensorError> {
        let answer = self.sensor_port()?.request_waking(
            request,
            self,
            self.request_timeout,
            Wait::Backoff,
        )?;
        let header = answer.header;
        match ResponseStatus::from_u32(header.status) {
            Some(ResponseStatus::Ok) => {}
            Some(ResponseStatus::Refused) => {
                let refusal =
                    SensorRefusal::from_u32(header.error).ok_or(RequestError::UnknownAnswer {
                        status: header.status,
                    })?;
                return Err(SensorError::Refused(refusal));
            }
            _ => {
                return Err(RequestError::UnknownAnswer {
                    status: header.status,
                }
                .into())
            }
        }
        Ok(answer.items)
    }

    /// Builds a sensor from `spec` and subscribes to it.
    ///
    /// # Errors
    ///
    /// Returns the errors of [`Client::create_sensor`]
    /// ([`SensorError::InvalidSpec`], [`SensorError::Refused`],
    /// [`SensorError::Request`]), and [`SensorError::Request`] if subscribing
    /// fails ([`RequestError::Full`] if the sensor admits no more readers,
    /// `--max-sensor-readers`; [`RequestError::Transport`]).
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    /// use shared_types::{SensorSpec, WorldSettings};
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "sensor", std::process::id());
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
    /// let client = Client::connect(&name, Duration::from_secs(5))?;
    /// let mut ticker = client.claim_ticker()?;
    /// let sync = WorldSettings { synchronous_mode: true, ..client.get_settings()? };
    /// ticker.apply_settings(sync)?;
    /// // A 32 x 24 depth camera 2 m up, looking along +x.
    /// let mut camera = client.spawn_sensor(SensorSpec::depth([0.0, 2.0, 0.0], 32, 24, 90.0, 100.0))?;
    /// let frame = ticker.tick(Duration::from_secs(1))?;
    /// let capture = camera.recv(Duration::from_secs(5))?; // borrowed from shared memory
    /// assert_eq!(capture.header().frame, frame);
    /// assert_eq!(capture.header().size, [32, 24]);
    /// assert_eq!(capture.depth().map(<[f32]>::len), Some(32 * 24));
    /// assert_eq!(capture.bytes().len(), 32 * 24 * 4);
    /// # drop(capture);
    /// # drop(camera);
    /// # drop(ticker);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn spawn_sensor(&self, spec: SensorSpec) -> Result<Sensor, SensorError> {
        let info = self.create_sensor(spec)?;
        self.open_sensor(info)
    }

    /// Builds a sensor from `spec` without subscribing to it (read it
    /// later with [`Client::sensor`]).
    ///
    /// # Errors
    ///
    /// Returns [`SensorError::InvalidSpec`] if `spec` breaks a rule of
    /// [`SensorSpec::check`] (checked before anything is sent);
    /// [`SensorError::Refused`] with the server's [`SensorRefusal`]
    /// (`UnknownActor` if `attach_to` names no actor, `NoMemory` if the shared
    /// memory for its captures cannot be had, `InvalidSpec`); and
    /// [`SensorError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// [`RequestError::Full`], ...).
    pub fn create_sensor(&self, spec: SensorSpec) -> Result<SensorInfo, SensorError> {
        spec.check()?;
        let info = self
            .sensor_request(SensorRequest::new(SensorRequestKind::Spawn, 0, spec))?
            .first()
            .copied()
            .ok_or(RequestError::UnknownAnswer {
                status: ResponseStatus::Ok as u32,
            })?;
        Ok(info)
    }

    /// Subscribes to the existing sensor `id`.
    ///
    /// # Errors
    ///
    /// Returns [`SensorError::UnknownSensor`] if the world has no sensor `id`
    /// (never spawned, or it has ended), and [`SensorError::Request`] if
    /// listing the sensors or subscribing fails ([`RequestError::Full`] if the
    /// sensor admits no more readers, [`RequestError::Timeout`], ...).
    pub fn sensor(&self, id: u64) -> Result<Sensor, SensorError> {
        self.open_sensor(self.sensor_info(id)?)
    }

    /// Subscribes to sensor `info` of this client's world.
    fn open_sensor(&self, info: SensorInfo) -> Result<Sensor, SensorError> {
        Ok(Sensor::open(
            &self.world,
            self.server_pid,
            self.request_timeout,
            info,
        )?)
    }

    fn sensor_info(&self, id: u64) -> Result<SensorInfo, SensorError> {
        self.list_sensors()?
            .into_iter()
            .find(|s| s.id == id)
            .ok_or_else(|| self.unknown_sensor(id))
    }

    /// Every sensor of the world.
    ///
    /// # Errors
    ///
    /// Returns [`SensorError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// [`RequestError::Full`] if the world admits no more clients sending
    /// sensor requests, ...).
    pub fn list_sensors(&self) -> Result<Vec<SensorInfo>, SensorError> {
        self.sensor_request(SensorRequest::new(
            SensorRequestKind::List,
            0,
            SensorSpec::default(),
        ))
    }

    /// Removes sensor `id` from the world (CARLA's `sensor.stop()` + destroy).
    ///
    /// # Errors
    ///
    /// Returns [`SensorError::UnknownSensor`] if the world has no sensor `id`
    /// (never spawned, or it has ended already), [`SensorError::Refused`] if
    /// the server refuses otherwise, and [`SensorError::Request`] if the
    /// request fails.
    pub fn destroy_sensor(&self, id: u64) -> Result<(), SensorError> {
        match self.sensor_request(SensorRequest::new(
            SensorRequestKind::Destroy,
            id,
            SensorSpec::default(),
        )) {
            Ok(_) => Ok(()),
            Err(SensorError::Refused(SensorRefusal::UnknownSensor)) => Err(self.unknown_sensor(id)),
            Err(e) => Err(e),
        }
    }

    /// [`SensorError::UnknownSensor`] for `id` in this client's world.
    fn unknown_sensor(&self, id: u64) -> SensorError {
        SensorError::UnknownSensor {
            id,
            world: self.world.as_str().to_owned(),
        }
    }
}
