//! How a process waits for something another process announces: the same
//! three words for clients waiting for frames, captures and answers, and for
//! the server waiting for ticks.

use std::fmt;
use std::str::FromStr;

/// How a process waits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WaitMode {
    /// Sleep on the event until the other side announces (no CPU burnt
    /// while waiting). The default for clients.
    #[default]
    Block,
    /// Poll the shared memory in a tight loop: lowest latency, one core
    /// busy while waiting.
    Spin,
    /// Poll for a short window (100 µs for clients; the server's
    /// `--hybrid-window-us` after each frame), yielding the CPU between
    /// polls, then sleep on the event: an answer that comes quickly (a tick
    /// in a tight loop) costs no kernel wake-up, a long wait burns no CPU,
    /// and a peer on the same CPU runs while this side polls. The default
    /// for the server.
    Hybrid,
}

impl WaitMode {
    /// Every mode, in the order `--help` lists them.
    pub const ALL: [Self; 3] = [Self::Block, Self::Spin, Self::Hybrid];

    /// The word used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            Self::Block => "block",
            Self::Spin => "spin",
            Self::Hybrid => "hybrid",
        }
    }
}

impl fmt::Display for WaitMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for WaitMode {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == text)
            .ok_or_else(|| format!("'{text}' is not a wait mode: block, spin or hybrid"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_round_trip_through_their_names() {
        for mode in WaitMode::ALL {
            assert_eq!(mode.name().parse::<WaitMode>(), Ok(mode));
        }
        assert!("busy".parse::<WaitMode>().is_err());
    }
}
