//! Every error of the Rust client as an exception of `simbus/_errors.py`,
//! with the Rust error's message (and its sources, `: `-joined).

use iceoryx2::port::ReceiveError;
use pyo3::prelude::*;
use pyo3::types::PyType;
use shared_types::SensorEnd;
use sim_client::{
    ApplySettingsError, ConnectError, LoadWorldError, RequestError, TickError, WaitError,
};

use crate::gil;

/// The exception class `name` of `simbus._errors`.
fn class<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyType>> {
    Ok(py
        .import("simbus._errors")?
        .getattr(name)?
        .cast_into::<PyType>()?)
}

/// `error`'s message and its sources' messages.
pub(crate) fn message(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(&cause.to_string());
        source = cause.source();
    }
    text
}

/// A `simbus.<name>` exception with `message`.
pub(crate) fn raise(name: &str, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::attach(|py| match class(py, name) {
        Ok(class) => PyErr::from_type(class, message),
        Err(e) => e,
    })
}

/// Which exception a request error is.
fn request_kind(error: &RequestError) -> &'static str {
    match error {
        RequestError::Timeout { .. } => "TimeoutError",
        RequestError::ServerGone { .. } => "ServerGone",
        RequestError::ProtocolMismatch { .. } => "ProtocolMismatch",
        RequestError::Full { .. } => "Full",
        _ => "Error",
    }
}

/// A request error as its exception; an interrupted wait raises what the
/// signal handler raised (`KeyboardInterrupt`).
pub(crate) fn request(error: RequestError) -> PyErr {
    match error {
        RequestError::Interrupted { .. } => interrupted(),
        RequestError::WindowTooLarge { .. } => {
            pyo3::exceptions::PyValueError::new_err(message(&error))
        }
        _ => raise(request_kind(&error), message(&error)),
    }
}

fn interrupted() -> PyErr {
    gil::take_pending()
        .unwrap_or_else(|| pyo3::exceptions::PyKeyboardInterrupt::new_err("interrupted"))
}

/// A connect error as its exception; a connect that Ctrl-C cut short
/// raises what the signal handler raised.
pub(crate) fn connect(error: ConnectError) -> PyErr {
    if let Some(pending) = gil::take_pending() {
        return pending;
    }
    let kind = match &error {
        ConnectError::InvalidWorld(_) => {
            return pyo3::exceptions::PyValueError::new_err(message(&error))
        }
        ConnectError::NoServer { .. } | ConnectError::NotAnswering { .. } => "TimeoutError",
        ConnectError::ProtocolMismatch { .. } => "ProtocolMismatch",
        ConnectError::Full { .. } => "Full",
        _ => "Error",
    };
    raise(kind, message(&error))
}

/// The word `simbus.SensorEnded.reason` holds for `end`.
fn end_word(end: SensorEnd) -> &'static str {
    match end {
        SensorEnd::Destroyed => "destroyed",
        SensorEnd::ParentDestroyed => "parent destroyed",
        SensorEnd::EpisodeEnded => "episode ended",
        SensorEnd::ServerStopped => "server stopped",
    }
}

/// A wait error as its exception (`SensorEnded` carries the reason in a
/// word; a subscriber holding all it may is `Full`).
pub(crate) fn wait(error: WaitError) -> PyErr {
    let kind = match &error {
        WaitError::Interrupted { .. } => return interrupted(),
        WaitError::Timeout { .. } | WaitError::NoCapture { .. } => "TimeoutError",
        WaitError::ServerGone { .. } | WaitError::NotBack { .. } => "ServerGone",
        WaitError::ProtocolMismatch { .. } => "ProtocolMismatch",
        WaitError::SensorEnded { reason, .. } => {
            let (text, word) = (message(&error), end_word(*reason));
            return Python::attach(|py| match class(py, "SensorEnded") {
                Ok(class) => PyErr::from_type(class, (text, word)),
                Err(e) => e,
            });
        }
        WaitError::Transport { source, .. } if holds_all_it_may(source.as_ref()) => "Full",
        _ => "Error",
    };
    raise(kind, message(&error))
}

/// Whether a receive failed because the subscriber holds as many samples
/// as it may (frames or captures the caller did not release).
pub(crate) fn holds_all_it_may(source: &(dyn std::error::Error + 'static)) -> bool {
    matches!(
        source.downcast_ref::<ReceiveError>(),
        Some(ReceiveError::ExceedsMaxBorrows)
    )
}

/// A tick error as its exception.
pub(crate) fn tick(error: TickError) -> PyErr {
    match error {
        TickError::Request(e) => request(e),
        TickError::Frame(e) => wait(e),
        TickError::NotTicker { .. } | TickError::Revoked { .. } => {
            raise("NotTickerError", message(&error))
        }
        TickError::HeldUp { .. } | TickError::StandbyTimedOut { .. } => {
            raise("TimeoutError", message(&error))
        }
        TickError::StandbyFull { .. } => raise("Full", message(&error)),
        TickError::Restarted(r) => {
            let text = message(&error);
            Python::attach(|py| match class(py, "Restarted") {
                Ok(class) => PyErr::from_type(
                    class,
                    (text, r.resumed_at, r.episode, r.server_pid, r.previous_pid),
                ),
                Err(e) => e,
            })
        }
    }
}

/// A settings error as its exception.
pub(crate) fn settings(error: ApplySettingsError) -> PyErr {
    match error {
        ApplySettingsError::Request(e) => request(e),
        ApplySettingsError::NotTicker | ApplySettingsError::Revoked { .. } => {
            raise("NotTickerError", message(&error))
        }
        _ => raise("SettingsError", message(&error)),
    }
}

/// A load or reload error as its exception.
pub(crate) fn load(error: LoadWorldError) -> PyErr {
    match error {
        LoadWorldError::Request(e) => request(e),
        LoadWorldError::UnknownScene { .. } => {
            pyo3::exceptions::PyValueError::new_err(message(&error))
        }
        LoadWorldError::TickerHolds { .. } => raise("NotTickerError", message(&error)),
        _ => raise("Error", message(&error)),
    }
}
