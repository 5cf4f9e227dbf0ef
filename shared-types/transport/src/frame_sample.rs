//! Sending a frame: the one place that writes a frame sample's slice, so
//! the server, the Zenoh mirror and the bench lay it out alike (the
//! actors, then their packed poses: [`shared_types::frame_slice_len`]).

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::{LoanError, SendError};
use shared_types::{fill_frame_slice, frame_slice_len, ActorState, FrameHeader};

use crate::bus::Bus;

/// The publisher of a world's frames.
pub type FramePublisher = Publisher<Bus, [ActorState], FrameHeader>;

/// Why [`send_frame`] sent nothing.
#[derive(Debug, thiserror::Error)]
pub enum FrameSendError {
    /// No sample could be loaned (the pool is spent or cannot grow).
    #[error("loaning the frame's sample")]
    Loan(#[from] LoanError),
    /// The sample could not be delivered.
    #[error("sending the frame")]
    Send(#[from] SendError),
    /// The loaned sample had another length than asked for.
    #[error("the loaned sample holds {got} elements, not the {wanted} asked for")]
    Length {
        /// Elements asked for.
        wanted: usize,
        /// Elements loaned.
        got: usize,
    },
}

/// Sends `header` with `actor(0..actor_count)` (and their poses), each
/// actor written once straight into the loaned sample: no copy, no
/// allocation. The header's `actor_count` is set to `actor_count`.
///
/// # Errors
///
/// Returns [`FrameSendError::Loan`] if no sample can be loaned (the publisher's
/// pool is spent or cannot grow to the frame's length),
/// [`FrameSendError::Length`] if the loaned sample is not the length asked for
/// (nothing is sent), and [`FrameSendError::Send`] if iceoryx2 cannot deliver
/// the sample.
pub fn send_frame(
    publisher: &FramePublisher,
    mut header: FrameHeader,
    actor_count: usize,
    actor: impl FnMut(usize) -> ActorState,
) -> Result<(), FrameSendError> {
    let wanted = frame_slice_len(actor_count);
    let mut sample = publisher.loan_slice_uninit(wanted)?;
    header.actor_count = u32::try_from(actor_count).unwrap_or(u32::MAX);
    *sample.user_header_mut() = header;
    let got = sample.payload_mut().len();
    if !fill_frame_slice(sample.payload_mut(), actor_count, actor) {
        return Err(FrameSendError::Length { wanted, got });
    }
    // SAFETY: `fill_frame_slice` returned true: it wrote every element of
    // the payload.
    let sample = unsafe { sample.assume_init() };
    sample.send()?;
    Ok(())
}
