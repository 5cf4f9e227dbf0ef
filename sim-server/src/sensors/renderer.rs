//! Where cameras and lidars render: rayon's global pool (one thread per
//! CPU), or a pool of `--render-threads` of the server's own.
//!
//! A reader that spins on a sensor needs a CPU of its own: when every CPU
//! renders, a worker finishing its share (rayon's workers spin a while
//! before they sleep) holds the reader's CPU just as the capture is
//! published, and the reader's wake-up waits for it. Fewer render threads
//! than CPUs leave the reader one (`simbus-bench sensors` shows the tail).

use std::num::NonZeroUsize;

/// The render threads: rayon's global pool unless a count was given.
#[derive(Debug)]
pub(crate) struct Renderer {
    pool: Option<rayon::ThreadPool>,
}

/// Why the render threads could not be started.
#[derive(Debug, thiserror::Error)]
#[error("cannot start {threads} render threads")]
pub struct RenderThreadsError {
    threads: usize,
    #[source]
    source: rayon::ThreadPoolBuildError,
}

impl Renderer {
    /// Renders on `threads` threads of its own (`None`: rayon's global
    /// pool, one thread per CPU).
    pub(crate) fn new(threads: Option<NonZeroUsize>) -> Result<Self, RenderThreadsError> {
        let Some(threads) = threads else {
            return Ok(Self { pool: None });
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.get())
            .thread_name(|i| format!("simbus-render-{i}"))
            .build()
            .map_err(|source| RenderThreadsError {
                threads: threads.get(),
                source,
            })?;
        Ok(Self { pool: Some(pool) })
    }

    /// Runs `render` (which renders with rayon's parallel iterators) on
    /// the render threads; the loop's thread waits for it.
    pub(crate) fn run<R: Send>(&self, render: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(render),
            None => render(),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::mem::MaybeUninit;

    use shared_types::SensorSpec;

    use super::*;

    /// A depth image rendered by `renderer`, as bits.
    fn depth_bits(renderer: &Renderer) -> Vec<u32> {
        let (world, _) = super::super::default_world_in_motion();
        let spec = SensorSpec::depth([-4.0, 3.0, 0.0], 160, 120, 90.0, 100.0);
        let pose = super::super::capture::sensor_pose(&world, &spec).expect("a pose");
        let mut slots = vec![MaybeUninit::new(f32::NAN); 160 * 120];
        renderer.run(|| super::super::camera::depth_into(&world, &spec, pose, &mut slots));
        // SAFETY: every slot started initialised.
        slots
            .iter()
            .map(|s| unsafe { s.assume_init() }.to_bits())
            .collect()
    }

    #[test]
    fn an_image_is_the_same_bits_on_any_number_of_render_threads() {
        let everywhere = depth_bits(&Renderer::new(None).unwrap());
        assert!(everywhere.iter().any(|&d| d != 100f32.to_bits()), "hits");
        for threads in [1, 3] {
            let renderer = Renderer::new(NonZeroUsize::new(threads)).unwrap();
            assert_eq!(depth_bits(&renderer), everywhere, "{threads} threads");
        }
    }

    #[test]
    fn a_pool_of_its_own_renders_on_that_many_threads() {
        let two = Renderer::new(NonZeroUsize::new(2)).expect("two render threads");
        assert_eq!(two.run(rayon::current_num_threads), 2);
        let name = two.run(|| std::thread::current().name().map(str::to_owned));
        assert!(name.unwrap_or_default().starts_with("simbus-render-"));
        let global = Renderer::new(None).expect("the global pool");
        assert_eq!(
            global.run(rayon::current_num_threads),
            rayon::current_num_threads()
        );
    }
}
