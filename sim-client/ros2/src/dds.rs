//! The adapter's ROS 2 node on DDS (`ros2-client` over RustDDS): joining a
//! domain, topics by their ROS names, the QoS each kind of data takes, and
//! the node's background tasks (discovery, matching) on a thread.

use std::thread::JoinHandle;
use std::time::Duration;

use ros2_client::dds::rustdds::Topic;
use ros2_client::qos::{Durability, History, QosProfile, Reliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Node, NodeName, NodeOptions, Publisher, Subscription,
};

use crate::msg::Message;
use crate::Ros2Error;

/// How long a reliable publication waits for room in its send window
/// (readers acknowledge what they got when the writer's heartbeat asks,
/// every 100 ms while one is behind): past it the message is dropped and
/// counted. A reader that is gone holds the adapter this long per message
/// until DDS notices (its lease).
const ACK_WAIT: Duration = Duration::from_millis(500);

/// The QoS of one publication.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qos {
    /// Sensor data: best effort, volatile, the last 5 (rclpy's
    /// `qos_profile_sensor_data`); with `--lockstep`, reliable and
    /// blocking instead, so a slow reader holds the world.
    SensorData,
    /// `/clock`: reliable, volatile, the last 16384 (rclpy's time source
    /// reads it best effort, depth 1; a reliable reader gets every tick).
    Clock,
    /// `/tf`, odometry, markers, events: reliable, volatile, the last 100
    /// (tf2's broadcaster).
    Reliable,
    /// `/tf_static`: reliable, transient local, the last 1 (tf2's static
    /// broadcaster: a late reader gets every mount).
    Latched,
    /// CARLA 0.9.16's (Fast DDS's defaults): reliable, transient local,
    /// the last 1, for every topic of its native ROS 2.
    Carla,
    /// What ROS sends simbus (controls, ticks): reliable, volatile, the
    /// last 10 (rclpy's default publisher matches it).
    Command,
}

impl Qos {
    fn profile(self, lockstep: bool) -> QosProfile {
        let keep = |depth| History::KeepLast { depth };
        let base = QosProfile::publisher_default().durability(Durability::Volatile);
        let reliable = |when_full| Reliability::Reliable { when_full };
        match self {
            Self::SensorData if lockstep => base
                .reliability(reliable(WhenFull::Block))
                .history(History::KeepAll),
            Self::SensorData => base.reliability_best_effort().history(keep(5)),
            Self::Clock | Self::Reliable if lockstep => base
                .reliability(reliable(WhenFull::Block))
                .history(History::KeepAll),
            // A reader acknowledges in batches (a heartbeat apart): at
            // ten thousand ticks a second the clock keeps over a second's
            // worth, so that a reliable reader misses none.
            Self::Clock => base
                .reliability(reliable(WhenFull::Wait(ACK_WAIT)))
                .history(keep(16384)),
            Self::Reliable => base
                .reliability(reliable(WhenFull::Wait(ACK_WAIT)))
                .history(keep(100)),
            Self::Latched => base
                .reliability(reliable(WhenFull::Wait(Duration::from_millis(100))))
                .durability(Durability::TransientLocal)
                .history(keep(1)),
            Self::Carla => base
                .reliability(reliable(WhenFull::Wait(Duration::from_millis(100))))
                .durability(Durability::TransientLocal)
                .history(keep(1)),
            Self::Command => base
                .reliability(reliable(WhenFull::DEFAULT))
                .history(keep(10)),
        }
    }
}

/// A ROS 2 node of the adapter's, with its background tasks running.
pub struct Dds {
    context: Context,
    /// `None` only while dropping.
    node: Option<Node>,
    lockstep: bool,
    spinner: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Dds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Dds")
            .field("domain_id", &self.context.domain_id())
            .finish_non_exhaustive()
    }
}

impl Dds {
    /// Joins DDS domain `domain_id` as the node `name` (in `/`).
    /// `lockstep`: sensor data and the clock are reliable and blocking.
    ///
    /// # Errors
    ///
    /// [`Ros2Error::Dds`] if DDS cannot join the domain (its ports are
    /// taken, the id is out of range) or make the node.
    pub fn join(domain_id: u16, name: &str, lockstep: bool) -> Result<Self, Ros2Error> {
        let dds = |what: &str| {
            let what = what.to_owned();
            move |e: String| Ros2Error::Dds { what, reason: e }
        };
        let context = Context::with_options(ContextOptions::new().domain_id(domain_id))
            .map_err(|e| dds(&format!("joining DDS domain {domain_id}"))(e.to_string()))?;
        let node_name = NodeName::new("/", name)
            .map_err(|e| dds(&format!("the node name {name:?}"))(format!("{e:?}")))?;
        let mut node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| dds("creating the node")(format!("{e:?}")))?;
        let spinner = node
            .spinner()
            .map_err(|e| dds("starting the node's spinner")(e.to_string()))?;
        // Discovery and matching run on their own thread until the node
        // is dropped (its drop tells the spinner to stop).
        let spinner = std::thread::Builder::new()
            .name("ros2-spinner".into())
            .spawn(move || {
                if let Err(e) = futures::executor::block_on(spinner.spin()) {
                    tracing::warn!("the ROS 2 node's spinner stopped: {e}");
                }
            })
            .map_err(|e| dds("starting the node's spinner")(e.to_string()))?;
        Ok(Self {
            context,
            node: Some(node),
            lockstep,
            spinner: Some(spinner),
        })
    }

    /// The domain joined.
    pub fn domain_id(&self) -> u16 {
        self.context.domain_id()
    }

    /// A publisher of `M` on the ROS topic `name` (absolute: `/clock`).
    ///
    /// # Errors
    ///
    /// [`Ros2Error::Topic`] if DDS refuses the topic (the domain has it
    /// with another type) or the publisher.
    pub fn publisher<M: Message>(
        &mut self,
        name: &str,
        qos: Qos,
    ) -> Result<Publisher<M>, Ros2Error> {
        let profile = qos.profile(self.lockstep);
        let topic = self.topic::<M>(name, &profile)?;
        self.node_mut()
            .create_publisher(&topic, Some(profile))
            .map_err(|e| refused(name, &e))
    }

    /// A subscription to `M` on the ROS topic `name`.
    ///
    /// # Errors
    ///
    /// [`Ros2Error::Topic`] if DDS refuses the topic or the subscription.
    pub fn subscription<M: Message>(&mut self, name: &str) -> Result<Subscription<M>, Ros2Error> {
        let profile = Qos::Command.profile(false);
        let topic = self.topic::<M>(name, &profile)?;
        self.node_mut()
            .create_subscription(&topic, Some(profile))
            .map_err(|e| refused(name, &e))
    }

    /// The DDS topic of ROS topic `name` (`rt` + the name) carrying `M`.
    fn topic<M: Message>(&self, name: &str, profile: &QosProfile) -> Result<Topic, Ros2Error> {
        self.context
            .create_topic(
                format!("rt{name}"),
                MessageTypeName::new(M::PACKAGE, M::NAME),
                profile,
            )
            .map_err(|e| refused(name, &e))
    }

    /// How many writers of `M` on the ROS topic `name` the domain has now
    /// (from discovery: a writer whose participant left, or went silent
    /// past its lease, is gone).
    pub fn writers_of<M: Message>(&self, name: &str) -> usize {
        let topic = format!("rt{name}");
        let type_name = MessageTypeName::new(M::PACKAGE, M::NAME).dds_msg_type();
        self.context
            .domain_participant()
            .discovered_writers()
            .iter()
            .filter(|w| {
                w.publication_topic_data.topic_name == topic
                    && w.publication_topic_data.type_name == type_name
            })
            .count()
    }

    fn node_mut(&mut self) -> &mut Node {
        self.node
            .as_mut()
            .expect("the node lives until the adapter is dropped")
    }
}

/// DDS's refusal of topic `name`.
fn refused(name: &str, error: &dyn std::fmt::Display) -> Ros2Error {
    Ros2Error::Topic {
        topic: name.to_owned(),
        reason: error.to_string(),
    }
}

impl Drop for Dds {
    fn drop(&mut self) {
        self.node = None; // tells the spinner to stop
        if let Some(spinner) = self.spinner.take() {
            let _ = spinner.join();
        }
    }
}
