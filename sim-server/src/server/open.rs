//! How a server starts: fresh (the scene's initial state) or resumed from
//! a journal, its domains opened, its first frame published and its
//! journal begun.

use std::time::Instant;

use shared_types::FrameHeader;
use tracing::{info, warn};

use super::error::ServerError;
use super::{check_keyframe_seconds, Domains, Server, Timers};
use crate::batches::Batches;
use crate::clock::Clock;
use crate::config::ServerConfig;
use crate::control::Control;
use crate::journal::resume::{resume, ResumeOptions, Resumed};
use crate::journal::Journal;
use crate::liveness::PidWatch;
use crate::lockstep::Lockstep;
use crate::ports::Transport;
use crate::publication::Publication;
use crate::recorder::{Recorder, RecorderPort};
use crate::replayer::Replayer;
use crate::sensors::{Renderer, Sensors};
use crate::state::Runtime;
use crate::ticker::Ticker;
use crate::world::World;

impl Server {
    /// Validates the settings, loads the scene, opens the world's services
    /// (cleaning up after a crashed predecessor) and publishes frame 0;
    /// starts the journal when the config asks for one.
    ///
    /// # Errors
    ///
    /// Returns [`ServerError::Settings`] if the config's settings break a rule
    /// of [`WorldSettings::validate`](shared_types::WorldSettings::validate);
    /// [`ServerError::KeyframeSeconds`] if `keyframe_seconds` is out of range;
    /// [`ServerError::Port`] with
    /// [`PortError::AlreadyRunning`](crate::PortError::AlreadyRunning) if
    /// another live server owns the world,
    /// [`PortError::SharedDirectory`](crate::PortError::SharedDirectory) if
    /// iceoryx2 cannot be used as configured, or
    /// [`PortError::Transport`](crate::PortError::Transport) if iceoryx2
    /// refuses to create a service; [`ServerError::RenderThreads`] if the
    /// render threads cannot be started; and [`ServerError::Journal`] if the
    /// journal cannot be started (its directory cannot be made, or already
    /// holds a journal).
    pub fn start(config: ServerConfig) -> Result<Self, ServerError> {
        Self::open(config, None)
    }

    /// Rebuilds the world a journal describes and serves it live from the next frame.
    ///
    /// The world is the journal's last complete frame, or `options.at`'s frame
    /// for a fork: the same world name (unless forked under another), actor
    /// and sensor ids, episode and settings; frame ids go on. The journal
    /// continues into `config.journal` when set. A journal that cannot be
    /// resumed is refused, and nothing starts.
    ///
    /// # Errors
    ///
    /// Returns [`ServerError::Resume`] if the journal cannot be resumed (its
    /// directory cannot be read, holds no segment or no usable one, lacks the
    /// frame a fork asks for, or a re-simulated frame differs from it);
    /// [`ServerError::ForkIntoOriginal`] if a fork would journal into the
    /// journal it forks; [`ServerError::OtherWorld`] if a resume (not a fork)
    /// names another world than the journal's; and otherwise the errors of
    /// [`Server::start`].
    pub fn resume(mut config: ServerConfig, options: &ResumeOptions) -> Result<Self, ServerError> {
        if let Some(journal) = &config.journal {
            if options.at.is_some() && journal.dir == options.dir {
                return Err(ServerError::ForkIntoOriginal {
                    dir: options.dir.clone(),
                });
            }
        }
        let mut resumed = resume(options)?;
        if options.at.is_some() {
            // A fork begins a run of its own.
            resumed.header.run_pid = 0;
        }
        if options.at.is_none() && resumed.header.world != config.world.as_str() {
            return Err(ServerError::OtherWorld {
                dir: options.dir.clone(),
                journal: resumed.header.world.clone(),
                asked: config.world.to_string(),
            });
        }
        config.seed = resumed.header.seed;
        config.scene = resumed.scene;
        config.settings = resumed.settings;
        Self::open(config, Some(resumed))
    }

    fn open(config: ServerConfig, mut resumed: Option<Resumed>) -> Result<Self, ServerError> {
        let settings = config.settings.normalized();
        settings.validate()?;
        check_keyframe_seconds(config.keyframe_seconds)?;
        for warning in settings.warnings() {
            warn!("{warning}");
        }
        let now = Instant::now();
        let taken = resumed
            .as_mut()
            .and_then(|r| r.world.take().map(|world| (world, r.clock.clone())));
        let (world, clock) = match taken {
            Some(taken) => taken,
            None => (
                World::new(&config.scene.placements(config.seed), 1),
                Clock::new(now),
            ),
        };
        let transport = Transport::open(&config.world)?;
        let limits = config.limits;
        // Control first: it refuses a second live server on the world.
        let control = Control::open(&transport, &config.world, &limits)?;
        let publication = Publication::open(&transport, world.actor_count(), &limits)?;
        let ticker = Ticker::open(&transport, &limits)?;
        let batches = Batches::open(&transport, &limits)?;
        let lockstep = Lockstep::open(&transport, &limits)?;
        let renderer = Renderer::new(config.render_threads)?;
        let sensors = Sensors::open(&transport, &limits, renderer)?;
        let debug = crate::debug_shapes::DebugShapes::open(&transport, &limits)?;
        let recorder = RecorderPort::open(&transport, &limits)?;
        let mut runtime = Runtime::new(&config, settings);
        if let Some(r) = &resumed {
            runtime.episode = r.episode;
            if r.header.run_pid != 0 {
                runtime.run_pid = r.header.run_pid;
            }
            if r.frame.flags & FrameHeader::RESTORED != 0 {
                runtime.source_offset = Some(
                    r.frame
                        .timestamp
                        .frame
                        .saturating_sub(r.frame.recorded_frame),
                );
            }
        }
        let mut domains = Domains {
            runtime,
            transport,
            world,
            clock,
            publication,
            ticker,
            batches,
            lockstep,
            sensors,
            debug,
            recorder: Recorder::default(),
            replayer: Replayer::default(),
            timers: Timers {
                full_pass: now,
                cleanup: now,
                liveness: now,
                connections: now,
                probe: now,
            },
            journal: None,
            snapshots: Default::default(),
            pidwatch: PidWatch::default(),
            timings: None,
            config,
        };
        if let Some(r) = &resumed {
            domains.resume_sensors(r);
        }
        // A resumed world publishes its frame again as it was first
        // published (its substeps and how physics was cut), not stepped.
        let (substeps, flags) = resumed.as_ref().map_or((0, 0), |r| {
            let kept = FrameHeader::SUBSTEPS_CAPPED | FrameHeader::PHYSICS_CLAMPED;
            (r.frame.physics_substeps, r.frame.flags & kept)
        });
        domains.publish(substeps, flags)?;
        domains.publication.notify()?;
        if let Some(options) = domains.config.journal.clone() {
            // A resumed journal goes on in its directory; any other is new.
            let fresh = resumed
                .as_ref()
                .is_none_or(|r| r.segment.parent() != Some(options.dir.as_path()));
            let header = domains.recording_header(false);
            let frame = domains.frame_header(substeps, flags);
            let sensors = domains.sensors.recorded_spawns(domains.clock.frame());
            let scene = domains.runtime.scene.to_string();
            let journal = Journal::start(
                &options,
                fresh,
                header,
                sensors,
                (&frame, &domains.world),
                scene,
            )?;
            domains.journal = Some(journal);
        }
        info!(
            world = %domains.config.world,
            scene = %domains.runtime.scene,
            actors = domains.world.actor_count(),
            frame = domains.clock.frame(),
            episode = domains.runtime.episode,
            "server up{}: {}",
            if resumed.is_some() { " (resumed from its journal)" } else { "" },
            domains.runtime.settings
        );
        Ok(Self {
            control,
            recorder,
            domains,
        })
    }
}
