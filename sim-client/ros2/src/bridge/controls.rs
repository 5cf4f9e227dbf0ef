//! Vehicles' controls from ROS: each vehicle's newest valid message of a
//! frame, applied in one batch; the others dropped, counted and named.

use ros2_client::Subscription;
use shared_types::Command;
use tracing::warn;

use super::Run;
use crate::control::{self, ControlError};
use crate::Event;

impl<F: FnMut(Event)> Run<F> {
    /// Each vehicle's newest valid control from ROS, applied in one batch
    /// (before this frame's `done`: it lands in the next step).
    pub(super) fn apply_controls(&mut self) {
        let mut commands: Vec<Command> = Vec::new();
        let mut refused: Vec<(u64, String)> = Vec::new();
        for (&id, vehicle) in &self.vehicles {
            let mut parsed: Vec<Result<Command, ControlError>> = Vec::new();
            if let Some(control) = &vehicle.control {
                drain(control, |m| control::from_array(id, m), &mut parsed);
            }
            drain(&vehicle.carla, |m| control::from_carla(id, m), &mut parsed);
            drain(
                &vehicle.ackermann,
                |m| control::from_ackermann(id, m),
                &mut parsed,
            );
            let mut newest = None;
            for result in parsed {
                match result {
                    Ok(command) => newest = Some(command),
                    Err(reason) => refused.push((id, reason.to_string())),
                }
            }
            commands.extend(newest);
        }
        if !commands.is_empty() {
            match self.client.apply_batch_sync(&commands, false) {
                Ok(response) => {
                    for (i, status) in response.errors() {
                        let vehicle = commands.get(i).map_or(0, |c| c.actor);
                        refused.push((vehicle, format!("simbus refused it: {status}")));
                    }
                    let applied = commands.len() - response.errors().len();
                    self.published.controls_applied += applied as u64;
                }
                Err(e) => warn!("vehicle controls from ROS not applied: {e}"),
            }
        }
        for (vehicle, reason) in refused {
            self.published.controls_dropped += 1;
            warn!(vehicle, "control from ROS dropped: {reason}");
            (self.on_event)(Event::ControlDropped {
                vehicle,
                reason,
                dropped: self.published.controls_dropped,
            });
        }
    }
}

/// Every message waiting on `subscription`, each as `parse` reads it; a
/// message that cannot be read (malformed CDR) is refused.
fn drain<M: crate::msg::Message>(
    subscription: &Subscription<M>,
    parse: impl Fn(&M) -> Result<Command, ControlError>,
    parsed: &mut Vec<Result<Command, ControlError>>,
) {
    loop {
        match subscription.take() {
            Ok(Some((message, _))) => parsed.push(parse(&message)),
            Ok(None) => return,
            Err(e) => parsed.push(Err(ControlError::Malformed {
                message: M::NAME,
                reason: format!("{e:?}"),
            })),
        }
    }
}
