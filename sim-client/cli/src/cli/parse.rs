//! Numbers given as one comma-separated flag (`--at 1,2,3`).

use anyhow::anyhow;

use super::failure::Failure;

/// `N` comma-separated finite numbers, as a flag like `--at x,y,z` takes them.
pub(crate) fn numbers<const N: usize>(text: &str, flag: &str) -> Result<[f32; N], Failure> {
    let values: Vec<f32> = text
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or(())
        })
        .collect::<Result<_, _>>()
        .map_err(|_| {
            Failure::Refused(anyhow!(
                "{flag} takes {N} comma-separated finite numbers, got '{text}'"
            ))
        })?;
    values.try_into().map_err(|_| {
        Failure::Refused(anyhow!(
            "{flag} takes {N} comma-separated finite numbers, got '{text}'"
        ))
    })
}
