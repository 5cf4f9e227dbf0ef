//! Where cameras and lidars render: rayon's global pool (one thread per
//! CPU), or a pool of `--render-threads` of the server's own.
//!
//! A reader that spins on a sensor needs a CPU of its own: when every CPU
//! renders, a worker finishing its share (rayon's workers spin a while
//! before they sleep) holds the reader's CPU just as the capture is
//! published, and the reader's wake-up waits for it. Fewer render threads
//! than CPUs leave the reader one (`simbus-bench sensors` shows the tail).
//!
//! The server's own pool counts the loop's thread as its first render
//! thread: the loop renders its share instead of sleeping until the
//! workers are done, so the end of a cast wakes nobody (a woken loop
//! thread took the CPU of a reader spinning on the capture just as it was
//! published), and `--render-threads 1` renders on the loop's thread
//! alone.

use std::cell::RefCell;
use std::num::NonZeroUsize;
use std::sync::{Arc, OnceLock};
use std::thread::ThreadId;

/// The render threads: rayon's global pool unless a count was given.
#[derive(Debug)]
pub(crate) struct Renderer {
    own: Option<OwnPool>,
}

/// `--render-threads`' pool.
#[derive(Debug)]
struct OwnPool {
    pool: Arc<rayon::ThreadPool>,
    /// The thread that is the pool's first (the server's loop), if it has
    /// one: it renders only what it asks itself.
    home: Option<ThreadId>,
    /// For a render asked from another thread than `home` (a server moved
    /// after it opened): `threads` workers of their own.
    elsewhere: OnceLock<Result<rayon::ThreadPool, RenderThreadsError>>,
    threads: usize,
}

thread_local! {
    /// The pool this thread is the first thread of, and its size: a thread
    /// belongs to one pool for its life (rayon leaks such a pool), so a
    /// later server on this thread with as many render threads shares it.
    static HOME_POOL: RefCell<Option<(usize, Arc<rayon::ThreadPool>)>> =
        const { RefCell::new(None) };
}

/// Why the render threads could not be started.
#[derive(Debug, thiserror::Error)]
#[error("cannot start {threads} render threads: {reason}")]
pub struct RenderThreadsError {
    threads: usize,
    reason: String,
}

impl Renderer {
    /// Renders on `threads` threads of its own, this thread the first of
    /// them where it can be (`None`: rayon's global pool, one thread per
    /// CPU).
    pub(crate) fn new(threads: Option<NonZeroUsize>) -> Result<Self, RenderThreadsError> {
        let Some(threads) = threads else {
            return Ok(Self { own: None });
        };
        let threads = threads.get();
        let home = HOME_POOL.with_borrow_mut(|home| match home {
            Some((n, pool)) if *n == threads => Ok(Some(Arc::clone(pool))),
            // This thread is already another pool's first thread.
            Some(_) => Ok(None),
            None => {
                let pool = Arc::new(pool(threads, true)?);
                *home = Some((threads, Arc::clone(&pool)));
                Ok(Some(pool))
            }
        })?;
        let (pool, home) = match home {
            Some(pool) => (pool, Some(std::thread::current().id())),
            None => (Arc::new(pool(threads, false)?), None),
        };
        Ok(Self {
            own: Some(OwnPool {
                pool,
                home,
                elsewhere: OnceLock::new(),
                threads,
            }),
        })
    }

    /// Runs `render` (which renders with rayon's parallel iterators) on
    /// the render threads, the calling thread among them when it is the
    /// pool's first (otherwise it waits for them).
    pub(crate) fn run<R: Send>(&self, render: impl FnOnce() -> R + Send) -> R {
        let Some(own) = &self.own else {
            return render();
        };
        match own.home {
            Some(home) if home != std::thread::current().id() => {
                match own.elsewhere.get_or_init(|| pool(own.threads, false)) {
                    Ok(pool) => pool.install(render),
                    Err(e) => {
                        tracing::warn!("{e}; rendering on rayon's global pool");
                        render()
                    }
                }
            }
            _ => own.pool.install(render),
        }
    }
}

/// A pool of `threads` render threads; with `here`, this thread is the
/// first of them and `threads - 1` are started.
fn pool(threads: usize, here: bool) -> Result<rayon::ThreadPool, RenderThreadsError> {
    let builder = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("simbus-render-{i}"));
    let builder = if here {
        builder.use_current_thread()
    } else {
        builder
    };
    builder.build().map_err(|source| RenderThreadsError {
        threads,
        reason: source.to_string(),
    })
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
    fn a_pool_of_its_own_renders_on_that_many_threads_this_one_the_first() {
        let two = Renderer::new(NonZeroUsize::new(2)).expect("two render threads");
        assert_eq!(two.run(rayon::current_num_threads), 2);
        let here = std::thread::current().id();
        assert_eq!(
            two.run(|| (std::thread::current().id(), rayon::current_thread_index())),
            (here, Some(0)),
            "the opening thread renders its share"
        );
        // A second server on this thread with as many threads shares the
        // pool; with another count it gets workers of its own.
        let again = Renderer::new(NonZeroUsize::new(2)).expect("the same pool");
        assert_eq!(again.run(|| std::thread::current().id()), here);
        let three = Renderer::new(NonZeroUsize::new(3)).expect("three render threads");
        assert_eq!(three.run(rayon::current_num_threads), 3);
        assert_ne!(three.run(|| std::thread::current().id()), here);
        // One render thread, on a thread of its own: that thread alone
        // renders, no worker started.
        let (one, home) = std::thread::scope(|s| {
            s.spawn(|| {
                let one = Renderer::new(NonZeroUsize::new(1)).expect("one render thread");
                let id = std::thread::current().id();
                assert_eq!(one.run(|| std::thread::current().id()), id);
                (one, id)
            })
            .join()
            .expect("one render thread")
        });
        assert_ne!(home, here);
        // Asked from another thread, a pool of workers renders (the first
        // thread of the home pool is busy elsewhere, not waiting for work).
        let name = std::thread::scope(|s| {
            s.spawn(|| one.run(|| std::thread::current().name().map(str::to_owned)))
                .join()
                .expect("a render from another thread")
        });
        assert!(name.unwrap_or_default().starts_with("simbus-render-"));
        let global = Renderer::new(None).expect("the global pool");
        assert_eq!(
            global.run(rayon::current_num_threads),
            rayon::current_num_threads()
        );
    }
}
