//! Ticks as Zenoh publications, tagged with the mirror and the request
//! id: a mirror puts its tick requests on `tick/ask`; the exporter puts
//! the answers on `tick/answer`, or attaches an OK answer to the
//! publication of the frame it produced, so the mirror gets the frame and
//! its tick's answer in one Zenoh message. (A tick query's OK answer is
//! attached to its frame too, the query's own reply following.)
//!
//! A message is a sequence of entries, each
//! `[mirror id length: u8][mirror id][request id: u64 LE][value]`, the value
//! a [`shared_types::TickRequest`] or [`shared_types::TickResponse`]; the
//! mirror id is the mirror's Zenoh id (a query's `mirror` parameter), the
//! request id the mirror's (a query's `id` parameter).

use bytemuck::Pod;

use crate::wire::{decode_fixed, PayloadError};

/// One tagged value.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tagged<'a, T> {
    /// The mirror that asked (its Zenoh id).
    pub mirror: &'a [u8],
    /// The mirror's id of the request.
    pub id: u64,
    /// The request or the server's answer.
    pub value: T,
}

/// Appends one entry to `out`; a mirror id longer than 255 bytes is not
/// encoded (`false`).
pub(crate) fn encode<T: Pod>(mirror: &str, id: u64, value: &T, out: &mut Vec<u8>) -> bool {
    let Ok(len) = u8::try_from(mirror.len()) else {
        return false;
    };
    out.push(len);
    out.extend_from_slice(mirror.as_bytes());
    out.extend_from_slice(&id.to_le_bytes());
    out.extend_from_slice(bytemuck::bytes_of(value));
    true
}

/// Every entry of a message of `what`s, checked (lengths, protocol
/// version).
pub(crate) fn decode<'a, T: Pod>(
    mut bytes: &'a [u8],
    what: &'static str,
) -> Result<Vec<Tagged<'a, T>>, PayloadError> {
    let answer_len = std::mem::size_of::<T>();
    let mut entries = Vec::new();
    while let Some((&len, rest)) = bytes.split_first() {
        let need = len as usize + 8 + answer_len;
        if rest.len() < need {
            return Err(PayloadError::TooShort {
                what,
                len: rest.len(),
                need,
            });
        }
        let (mirror, rest) = rest.split_at(len as usize);
        let (id, rest) = rest.split_at(8);
        let (answer, rest) = rest.split_at(answer_len);
        entries.push(Tagged {
            mirror,
            id: u64::from_le_bytes(id.try_into().unwrap_or_default()),
            value: decode_fixed(answer, what)?,
        });
        bytes = rest;
    }
    Ok(entries)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::{ResponseStatus, TickRequest, TickRequestKind, TickResponse, TickerInfo};

    fn answers(bytes: &[u8]) -> Result<Vec<Tagged<'_, TickResponse>>, PayloadError> {
        decode(bytes, "tick answers")
    }

    fn answer(frame: u64) -> TickResponse {
        TickResponse::new(ResponseStatus::Ok, frame, 0, TickerInfo::none())
    }

    #[test]
    fn entries_round_trip() {
        let mut bytes = Vec::new();
        assert!(encode("a1b2", 7, &answer(3), &mut bytes));
        assert!(encode("", u64::MAX, &answer(4), &mut bytes));
        let entries = answers(&bytes).unwrap();
        assert_eq!(entries.len(), 2);
        assert_eq!((entries[0].mirror, entries[0].id), (&b"a1b2"[..], 7));
        assert_eq!(entries[0].value.frame, 3);
        assert_eq!((entries[1].mirror, entries[1].id), (&b""[..], u64::MAX));
        assert_eq!(entries[1].value.frame, 4);
        assert!(answers(&[]).unwrap().is_empty());
        let mut bytes = Vec::new();
        let request = TickRequest::new(TickRequestKind::Tick, "host/node");
        assert!(encode("m", 9, &request, &mut bytes));
        let asked = decode::<TickRequest>(&bytes, "tick request").unwrap();
        assert_eq!(
            (asked.len(), asked[0].mirror, asked[0].id),
            (1, &b"m"[..], 9)
        );
        assert_eq!(asked[0].value.kind, TickRequestKind::Tick as u32);
    }

    #[test]
    fn a_short_or_garbled_attachment_is_refused() {
        let mut bytes = Vec::new();
        encode("mirror", 1, &answer(1), &mut bytes);
        for cut in 1..bytes.len() {
            assert!(answers(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        assert!(answers(b"garbage").is_err());
        // Another protocol version in the answer.
        let mut other = bytes.clone();
        let at = 1 + "mirror".len() + 8;
        other[at..at + 4].copy_from_slice(&99u32.to_le_bytes());
        assert!(matches!(
            answers(&other),
            Err(PayloadError::ProtocolMismatch { peer: 99, .. })
        ));
        assert!(!encode(&"x".repeat(256), 1, &answer(1), &mut Vec::new()));
    }
}
