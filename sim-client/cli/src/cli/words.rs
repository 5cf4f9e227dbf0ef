//! Counts as people write them: `1 frame`, `2 frames`, `0 frames`.

use std::fmt;

/// `n` and `noun`, the noun in the plural unless `n` is 1: `count(1,
/// "frame")` shows `1 frame`, `count(3, "frame")` shows `3 frames`. Every
/// noun the commands count takes a plain `s`.
pub(crate) fn count<N: Into<u64>>(n: N, noun: &str) -> Count<'_> {
    Count { n: n.into(), noun }
}

/// A number and its noun; see [`count`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Count<'a> {
    n: u64,
    noun: &'a str,
}

impl fmt::Display for Count<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = if self.n == 1 { "" } else { "s" };
        write!(f, "{} {}{s}", self.n, self.noun)
    }
}

#[cfg(test)]
mod tests {
    use super::count;

    #[test]
    fn one_is_singular_every_other_count_plural() {
        assert_eq!(count(1u32, "frame").to_string(), "1 frame");
        assert_eq!(count(0u32, "frame").to_string(), "0 frames");
        assert_eq!(count(2u64, "capture").to_string(), "2 captures");
        assert_eq!(
            count(u64::MAX, "tick").to_string(),
            format!("{} ticks", u64::MAX)
        );
    }
}
