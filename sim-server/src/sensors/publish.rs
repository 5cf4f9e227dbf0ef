//! Writing a capture into a loaned sample and sending it; the empty last
//! capture that ends a stream.

use std::mem::MaybeUninit;

use iceoryx2::prelude::*;
use shared_types::SensorHeader;

use super::Port;
use crate::error::PortError;

/// Sends an empty sample with `header` (an end-of-stream marker).
pub(super) fn send_end<T: std::fmt::Debug + ZeroCopySend + 'static>(
    port: &Port<T>,
    header: SensorHeader,
) -> Result<(), PortError> {
    let mut sample = port
        .loan_slice_uninit(0)
        .map_err(|e| PortError::transport("sensor loan", e))?;
    *sample.user_header_mut() = header;
    // SAFETY: the slice has no elements, so there is nothing to initialise.
    let sample = unsafe { sample.assume_init() };
    sample
        .send()
        .map_err(|e| PortError::transport("sensor send", e))?;
    Ok(())
}

/// Loans a sample, lets `fill` write every element in place, and sends it.
///
/// # Safety
///
/// `fill` must initialise every element of the slice it is given (the
/// sample is sent as initialised memory that readers read in place).
pub(super) unsafe fn publish<T: std::fmt::Debug + ZeroCopySend + bytemuck::Pod + 'static>(
    port: &Port<T>,
    header: SensorHeader,
    record: Option<&mut Vec<(SensorHeader, Vec<u8>)>>,
    fill: impl FnOnce(&mut [MaybeUninit<T>], &mut SensorHeader),
) -> Result<(), PortError> {
    let elements = port.initial_max_slice_len();
    let mut sample = port
        .loan_slice_uninit(elements)
        .map_err(|e| PortError::transport("sensor loan", e))?;
    let mut header = header;
    fill(sample.payload_mut(), &mut header);
    header.platform_timestamp = crate::clock::platform_timestamp();
    *sample.user_header_mut() = header;
    // SAFETY: the caller guarantees `fill` wrote every element.
    let sample = unsafe { sample.assume_init() };
    if let Some(record) = record {
        record.push((header, bytemuck::cast_slice(sample.payload()).to_vec()));
    }
    sample
        .send()
        .map_err(|e| PortError::transport("sensor send", e))?;
    Ok(())
}
