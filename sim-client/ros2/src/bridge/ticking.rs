//! Ticking from ROS: one frame per message on the tick topic, the ticker
//! claimed while a ROS node publishes there and let go when it leaves.

use std::time::Instant;

use ros2_client::Subscription;
use shared_types::WorldSettings;
use sim_client::Ticker;
use tracing::debug;

use super::{sanitize, Run, PEER_CHECK};
use crate::msg::Empty;
use crate::{Event, Ros2Error};

/// Ticking from ROS: the tick topic and, while a ROS peer publishes on
/// it, the world's ticker.
pub(super) struct Ticking {
    pub(super) ticks: Subscription<Empty>,
    pub(super) ticker: Option<Ticker>,
    /// Whether a ROS peer was seen on the tick topic.
    pub(super) had_peer: bool,
    /// When the peers were last counted.
    pub(super) counted: Option<Instant>,
}

impl<F: FnMut(Event)> Run<F> {
    /// Takes the tick topic's messages: one frame each; claims or lets go
    /// of the ticker as the ROS peer comes and goes.
    pub(super) fn serve_ticks(&mut self) -> Result<(), Ros2Error> {
        let Some(ticking) = &mut self.ticking else {
            return Ok(());
        };
        if ticking.counted.is_some_and(|at| at.elapsed() < PEER_CHECK) {
            return self.take_tick();
        }
        ticking.counted = Some(Instant::now());
        let peers = self
            .dds
            .writers_of::<Empty>(&self.naming.world_topic("tick"));
        if peers > 0 {
            ticking.had_peer = true;
        }
        if peers == 0 && ticking.had_peer {
            if let Some(ticker) = ticking.ticker.take() {
                let _ = ticker.release();
                (self.on_event)(Event::TickerReleased {
                    reason: "the ROS node ticking the world left".into(),
                });
            }
            ticking.had_peer = false;
        }
        if peers > 0 && ticking.ticker.is_none() {
            let mut ticker = self.client.claim_ticker_as(&format!(
                "ros2-simbus_{}",
                sanitize(self.client.world().as_str())
            ))?;
            ticker.apply_settings(WorldSettings {
                synchronous_mode: true,
                fixed_delta_seconds: Some(self.config.delta_seconds),
                ..self.client.get_settings()?
            })?;
            ticking.ticker = Some(ticker);
            (self.on_event)(Event::TickerClaimed);
        }
        self.take_tick()
    }

    /// One tick per message; messages beyond the first wait for the next
    /// turn, after this frame is published.
    fn take_tick(&mut self) -> Result<(), Ros2Error> {
        let Some(ticking) = &mut self.ticking else {
            return Ok(());
        };
        match ticking.ticks.take() {
            Ok(Some(_)) => {
                if let Some(ticker) = &mut ticking.ticker {
                    ticker.tick(self.config.timeout)?;
                    self.published.ticks += 1;
                }
            }
            Ok(None) => {}
            Err(e) => debug!("a tick message could not be read: {e:?}"),
        }
        Ok(())
    }
}
