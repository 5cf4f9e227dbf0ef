//! Latency histograms and their table rows.

use hdrhistogram::Histogram;

/// Latencies in nanoseconds.
pub(crate) struct Latencies(Histogram<u64>);

impl Latencies {
    pub(crate) fn new() -> Self {
        Self(Histogram::new_with_bounds(1, 60_000_000_000, 3).expect("valid histogram bounds"))
    }

    pub(crate) fn record(&mut self, nanos: u64) {
        self.0.saturating_record(nanos.max(1));
    }

    /// Times `exchange` `n` times, after `n / 10` untimed calls to warm
    /// up, and records each.
    pub(crate) fn time(
        &mut self,
        n: u64,
        mut exchange: impl FnMut() -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        for i in 0..n + n / 10 {
            let start = std::time::Instant::now();
            exchange()?;
            if i >= n / 10 {
                self.record(start.elapsed().as_nanos() as u64);
            }
        }
        Ok(())
    }

    pub(crate) fn quantile_us(&self, q: f64) -> f64 {
        self.0.value_at_quantile(q) as f64 / 1000.0
    }

    pub(crate) fn len(&self) -> u64 {
        self.0.len()
    }

    /// p50, p99, p999 in microseconds.
    pub(crate) fn percentiles_us(&self) -> [f64; 3] {
        [0.5, 0.99, 0.999].map(|q| self.quantile_us(q))
    }

    /// The distribution as (latency µs, fraction at or below it), one point
    /// per distinct recorded value (hdrhistogram's precision).
    pub(crate) fn cdf_us(&self) -> Vec<(f64, f64)> {
        let total = self.len().max(1) as f64;
        let mut below = 0u64;
        self.0
            .iter_recorded()
            .map(|v| {
                below += v.count_at_value();
                (v.value_iterated_to() as f64 / 1000.0, below as f64 / total)
            })
            .collect()
    }

    pub(crate) fn json(&self) -> serde_json::Value {
        let [p50, p99, p999] = self.percentiles_us();
        serde_json::json!({ "samples": self.len(), "p50_us": p50, "p99_us": p99, "p999_us": p999 })
    }

    /// `name  p50  p99  p999` with microsecond columns.
    pub(crate) fn row(&self, name: &str) -> String {
        let [p50, p99, p999] = self.percentiles_us();
        format!("{name:<40} {p50:>10.1} {p99:>10.1} {p999:>10.1}")
    }

    /// `name  p50  max` in milliseconds (for small samples).
    pub(crate) fn row_ms(&self, name: &str) -> String {
        let p50 = self.quantile_us(0.5) / 1000.0;
        let max = self.0.max() as f64 / 1e6;
        format!("{name:<28} {p50:>10.1} {max:>10.1}")
    }
}

/// The header matching [`Latencies::row`].
pub(crate) fn header(first: &str) -> String {
    format!(
        "{first:<40} {:>10} {:>10} {:>10}",
        "p50 µs", "p99 µs", "p999 µs"
    )
}
