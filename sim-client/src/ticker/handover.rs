//! The ticker changing the world's settings, and giving tick ownership
//! back.

use shared_types::{ResponseStatus, TickRequestKind, WorldSettings};
use tracing::info;

use crate::{ApplySettingsError, TickError};

use super::{unexpected, Ticker};

impl Ticker {
    /// Applies `settings`, which may enter synchronous mode (only the ticker
    /// may). Returns the first frame computed with them.
    ///
    /// # Errors
    ///
    /// Returns [`ApplySettingsError::Invalid`] if `settings` break a rule of
    /// [`WorldSettings::validate`] (checked here first, and by the server),
    /// [`ApplySettingsError::NotTicker`] if this client is no longer the
    /// ticker, [`ApplySettingsError::Revoked`] (naming who) if another client
    /// left synchronous mode, and [`ApplySettingsError::Request`] if the
    /// request fails ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// ...). Nothing changes on the server in any of these cases.
    pub fn apply_settings(&mut self, settings: WorldSettings) -> Result<u64, ApplySettingsError> {
        settings.validate()?;
        let response = self.send(
            TickRequestKind::ApplySettings,
            Some(settings),
            self.request_timeout,
        )?;
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response.effective_frame),
            Some(ResponseStatus::SyncNeedsTicker) => Err(ApplySettingsError::SyncNeedsTicker),
            Some(ResponseStatus::InvalidSettings) => match response.settings_error() {
                Some(error) => Err(error.into()),
                None => Err(unexpected(response.status).into()),
            },
            Some(ResponseStatus::NotTicker) => Err(ApplySettingsError::NotTicker),
            Some(ResponseStatus::Revoked) => Err(ApplySettingsError::Revoked {
                by: response.revoked_by,
            }),
            _ => Err(unexpected(response.status).into()),
        }
    }

    /// Gives up tick ownership; another client may then claim it. The world
    /// keeps its mode: leave synchronous mode first if nobody will tick.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::Request`] if the server does not answer within the
    /// request timeout ([`RequestError::Timeout`]) or is gone
    /// ([`RequestError::ServerGone`]), and [`TickError::NotTicker`] or
    /// [`TickError::Revoked`] if this client was no longer the ticker.
    pub fn release(mut self) -> Result<(), TickError> {
        self.released = true;
        let response = self.send(TickRequestKind::Release, None, self.request_timeout)?;
        self.expect_ok(response)?;
        info!(world = %self.world, "released tick ownership");
        Ok(())
    }
}
