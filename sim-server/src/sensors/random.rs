//! The sensors' seeded generator: the GNSS receiver's errors and the
//! radar's ray directions. The same seed draws the same numbers on every
//! run and machine (SplitMix64; normals by Box–Muller).

/// A seeded generator (SplitMix64).
#[derive(Debug, Clone)]
pub(super) struct Random {
    state: u64,
}

impl Random {
    pub(super) fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1].
    pub(super) fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    /// A normal error of standard deviation `stddev` (two draws each time,
    /// whatever the deviation, so one component's deviation does not move
    /// the others' errors).
    pub(super) fn normal(&mut self, stddev: f32) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        let standard = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        standard * f64::from(stddev)
    }
}
