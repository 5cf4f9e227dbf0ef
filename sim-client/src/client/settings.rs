//! The world's settings, read and applied, and loading or reloading its
//! scene.

use shared_types::{ControlRequest, RequestKind, ResponseStatus, WorldSettings};

use super::Client;
use crate::{ApplySettingsError, LoadWorldError, RequestError, Status};

impl Client {
    /// The settings in force for the next frame.
    ///
    /// # Errors
    ///
    /// Returns the [`RequestError`]s of [`Client::status`]:
    /// [`RequestError::Timeout`] if the server does not answer within the
    /// request timeout, [`RequestError::ServerGone`] if it has exited,
    /// [`RequestError::ProtocolMismatch`] for a server of another version, and
    /// so on.
    pub fn get_settings(&self) -> Result<WorldSettings, RequestError> {
        let response = self.request(ControlRequest::new(RequestKind::GetSettings))?;
        Ok(response.report.settings.into())
    }

    /// Applies `settings` and returns the first frame computed with them.
    /// Refused settings come back as [`ApplySettingsError::Invalid`] and
    /// leave the server's settings unchanged.
    ///
    /// # Errors
    ///
    /// Returns [`ApplySettingsError::Invalid`] if `settings` break a rule of
    /// [`WorldSettings::validate`] (checked here before anything is sent, and
    /// again by the server), [`ApplySettingsError::SyncNeedsTicker`] if they
    /// turn synchronous mode on (only a ticker enters it: see
    /// [`Ticker::apply_settings`](crate::Ticker::apply_settings)), [`ApplySettingsError::TickerHolds`] (naming
    /// the ticker) if a ticker holds the world, and
    /// [`ApplySettingsError::Request`] if the request fails as for
    /// [`Client::status`] (or the server answers with a status this client does
    /// not expect: [`RequestError::UnknownAnswer`]). Nothing changes on the
    /// server in any of these cases.
    pub fn apply_settings(&self, settings: WorldSettings) -> Result<u64, ApplySettingsError> {
        // Check here first: a clear error without a round trip. The server
        // checks again, since not every sender is this library.
        settings.validate()?;
        let response = self.request(ControlRequest::apply_settings(settings))?;
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response.effective_frame),
            Some(ResponseStatus::SyncNeedsTicker) => Err(ApplySettingsError::SyncNeedsTicker),
            Some(ResponseStatus::NotTicker) => Err(ApplySettingsError::TickerHolds {
                owner: response.report.ticker,
            }),
            Some(ResponseStatus::InvalidSettings) => match response.settings_error() {
                Some(error) => Err(ApplySettingsError::Invalid(error)),
                None => Err(RequestError::UnknownAnswer {
                    status: response.status,
                }
                .into()),
            },
            _ => Err(RequestError::UnknownAnswer {
                status: response.status,
            }
            .into()),
        }
    }

    /// Loads `scene` (`default`, `empty`, `boxes:N`) as a new episode that
    /// starts at frame 0; settings are kept unless `reset_settings`.
    ///
    /// # Errors
    ///
    /// Returns [`LoadWorldError::UnknownScene`] (with the rule it breaks) if
    /// `scene` is not a scene name, checked here before anything is sent, or if
    /// the server does not know it; [`LoadWorldError::TickerHolds`] if
    /// `reset_settings` is asked while a ticker holds the world;
    /// [`LoadWorldError::Failed`] if the server could not build the world (its
    /// log says why); and [`LoadWorldError::Request`] if the request fails as
    /// for [`Client::status`]. The world is unchanged in each case.
    pub fn load_world(&self, scene: &str, reset_settings: bool) -> Result<Status, LoadWorldError> {
        if let Err(reason) = scene.parse::<shared_types::scene::SceneName>() {
            return Err(LoadWorldError::UnknownScene {
                scene: scene.to_owned(),
                reason,
            });
        }
        self.load(
            ControlRequest::load_world(Some(scene), reset_settings),
            scene,
        )
    }

    /// Restores the current scene's initial state as a new episode.
    ///
    /// The actors and physics are the scene's first ones (the actors get new
    /// ids, never reused within the server's life); the episode starts at
    /// frame 0; settings are kept unless `reset_settings`.
    ///
    /// # Errors
    ///
    /// Returns [`LoadWorldError::TickerHolds`] if `reset_settings` is asked
    /// while a ticker holds the world, [`LoadWorldError::Failed`] if the server
    /// could not rebuild the world (its log says why), and
    /// [`LoadWorldError::Request`] if the request fails as for
    /// [`Client::status`]. The world is unchanged in each case.
    pub fn reload_world(&self, reset_settings: bool) -> Result<Status, LoadWorldError> {
        self.load(ControlRequest::load_world(None, reset_settings), "")
    }

    fn load(&self, request: ControlRequest, scene: &str) -> Result<Status, LoadWorldError> {
        let response = self.request(request)?;
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(Status::from(&response.report)),
            Some(ResponseStatus::UnknownScene) => Err(LoadWorldError::UnknownScene {
                scene: scene.to_owned(),
                reason: scene
                    .parse::<shared_types::scene::SceneName>()
                    .err()
                    .unwrap_or_else(|| {
                        shared_types::scene::SceneNameError::Unknown(scene.to_owned())
                    }),
            }),
            Some(ResponseStatus::LoadFailed) => Err(LoadWorldError::Failed {
                world: self.world.to_string(),
            }),
            Some(ResponseStatus::NotTicker) => Err(LoadWorldError::TickerHolds {
                owner: response.report.ticker,
            }),
            _ => Err(RequestError::UnknownAnswer {
                status: response.status,
            }
            .into()),
        }
    }
}
