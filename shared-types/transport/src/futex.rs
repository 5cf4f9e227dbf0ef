//! A futex as iceoryx2's event trigger: the wake-up under every blocking
//! wait in simbus.
//!
//! iceoryx2-cal keeps an event's state (which event ids fired, whether a
//! notification is pending) in shared memory and delegates only the sleeping
//! and the waking to a *trigger*. Its triggers are a Unix datagram socket
//! (the default: a `sendto` and a `recvfrom` per hop) and an unnamed
//! semaphore whose timed wait, on a monotonic clock, is a yield-and-sleep
//! loop rather than a wait in the kernel. This trigger is two 32-bit words
//! in the event's shared memory:
//!
//! - `posts` counts notifications not yet taken by the listener;
//! - `sleepers` counts listeners inside `futex(FUTEX_WAIT)` on `posts`.
//!
//! A notify adds to `posts` and calls `futex(FUTEX_WAKE)` only when
//! `sleepers` is non-zero, so notifying a listener that is busy or polling
//! costs an atomic add and no system call. A wait takes the posts if there
//! are any and otherwise sleeps on `posts` with a relative timeout on the
//! monotonic clock. Both sides use sequentially consistent operations on the
//! two words (the waiter raises `sleepers` then reads `posts`; the notifier
//! raises `posts` then reads `sleepers`), so at least one sees the other and
//! no wake-up is lost. The futex is shared, not `FUTEX_PRIVATE_FLAG`: the
//! two sides are different processes.

use core::fmt::Debug;
use core::marker::PhantomData;
use core::mem::MaybeUninit;
use core::ptr::NonNull;
use core::sync::atomic::{AtomicU32, Ordering};
use core::time::Duration;
use std::time::Instant;

use iceoryx2_bb_elementary_traits::testing::abandonable::Abandonable;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use iceoryx2_bb_lock_free::mpmc::counting_bit_set::RelocatableCountingBitSet;
use iceoryx2_bb_system_types::file_name::FileName;
use iceoryx2_bb_system_types::path::Path;
use iceoryx2_cal::dynamic_storage::{posix_shared_memory, DynamicStorage};
use iceoryx2_cal::event::common::EventImpl;
use iceoryx2_cal::event::event_state::EventState;
use iceoryx2_cal::event::trigger::{Configuration, HandlerInterface, State, WaiterInterface};
use iceoryx2_cal::event::{
    ListenerCreateError, ListenerWaitError, NotifierNotifyError, NotifierOpenError,
};
use iceoryx2_cal::named_concept::{NamedConceptPathHintRemoveError, NamedConceptRemoveError};

/// iceoryx2-cal's counting event with the futex trigger, its state in POSIX
/// shared memory like the default event's.
pub type FutexShmCountingBitSet = EventImpl<
    RelocatableCountingBitSet,
    FutexMgmt,
    Storage,
    FutexHandle<RelocatableCountingBitSet, Storage>,
    FutexWaiter<RelocatableCountingBitSet, Storage>,
>;

/// Where the event's state and the trigger's words live.
pub type Storage = posix_shared_memory::Storage<State<RelocatableCountingBitSet, FutexMgmt>>;

/// The trigger's two words, inside the event's shared memory.
#[derive(Debug)]
#[repr(C)]
pub struct FutexMgmt {
    posts: AtomicU32,
    sleepers: AtomicU32,
}

// SAFETY: two `AtomicU32`s (the layout of two `u32`s, `#[repr(C)]`), no
// pointers and no process-local resources: valid in any process that maps it.
unsafe impl ZeroCopySend for FutexMgmt {}

/// `futex(FUTEX_WAIT)` on a word every process maps; `timeout` is relative,
/// on the monotonic clock. `Err` carries the errno.
fn futex_wait(word: &AtomicU32, expected: u32, timeout: Option<Duration>) -> Result<(), i32> {
    let spec = timeout.map(|t| libc::timespec {
        tv_sec: t.as_secs().min(libc::time_t::MAX as u64) as libc::time_t,
        tv_nsec: libc::c_long::from(t.subsec_nanos() as i32),
    });
    let spec_ptr = spec
        .as_ref()
        .map_or(core::ptr::null(), |s| s as *const libc::timespec);
    // SAFETY: `word` is a live, aligned 32-bit atomic for the whole call;
    // `spec_ptr` is null or points at a timespec in this frame. FUTEX_WAIT
    // only reads the word and sleeps.
    let rc = unsafe {
        libc::syscall(
            libc::SYS_futex,
            word.as_ptr(),
            libc::FUTEX_WAIT,
            expected,
            spec_ptr,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error().raw_os_error().unwrap_or(0))
    }
}

/// `futex(FUTEX_WAKE)`: wakes every sleeper on `word`.
fn futex_wake(word: &AtomicU32) {
    // SAFETY: `word` is a live, aligned 32-bit atomic; FUTEX_WAKE touches no
    // memory, it wakes the threads sleeping on that address.
    unsafe {
        libc::syscall(libc::SYS_futex, word.as_ptr(), libc::FUTEX_WAKE, i32::MAX);
    }
}

/// The notifier's side: posts and wakes.
#[derive(Debug)]
pub struct FutexHandle<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> {
    mgmt: NonNull<FutexMgmt>,
    _state: PhantomData<(E, S)>,
}

// SAFETY: the handle reaches nothing but two atomics in shared memory.
unsafe impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Send for FutexHandle<E, S> {}
// SAFETY: as for `Send`: every access is atomic.
unsafe impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Sync for FutexHandle<E, S> {}

impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Abandonable for FutexHandle<E, S> {
    unsafe fn abandon_in_place(_this: NonNull<Self>) {}
}

impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> HandlerInterface<E, FutexMgmt, S>
    for FutexHandle<E, S>
{
    fn open(
        _name: &FileName,
        _config: &Configuration,
        mgmt: &FutexMgmt,
    ) -> Result<Self, NotifierOpenError> {
        Ok(Self {
            mgmt: NonNull::from(mgmt),
            _state: PhantomData,
        })
    }

    fn notify(&self) -> Result<(), NotifierNotifyError> {
        // SAFETY: iceoryx2's notifier owns the storage these words live in
        // and keeps it mapped for as long as it owns this handle; the
        // listener initialised them before the storage could be opened.
        let mgmt = unsafe { self.mgmt.as_ref() };
        // Saturating: the count only has to say "there were posts".
        let _ = mgmt
            .posts
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |p| {
                Some(p.saturating_add(1))
            });
        if mgmt.sleepers.load(Ordering::SeqCst) != 0 {
            futex_wake(&mgmt.posts);
        }
        Ok(())
    }
}

/// The listener's side: takes the posts, or sleeps until there are some.
#[derive(Debug)]
pub struct FutexWaiter<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> {
    mgmt: NonNull<FutexMgmt>,
    _state: PhantomData<(E, S)>,
}

// SAFETY: as for `FutexHandle`: every access is atomic.
unsafe impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Send for FutexWaiter<E, S> {}
// SAFETY: as for `FutexHandle`: every access is atomic.
unsafe impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Sync for FutexWaiter<E, S> {}

impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> Abandonable for FutexWaiter<E, S> {
    unsafe fn abandon_in_place(_this: NonNull<Self>) {}
}

impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> FutexWaiter<E, S> {
    fn mgmt(&self) -> &FutexMgmt {
        // SAFETY: iceoryx2's listener owns the storage these words live in,
        // keeps it mapped for as long as it owns this waiter, and `create`
        // initialised them.
        unsafe { self.mgmt.as_ref() }
    }

    /// Takes every post; true when there was at least one.
    fn take(&self) -> bool {
        self.mgmt().posts.swap(0, Ordering::SeqCst) != 0
    }

    /// Returns at the first post or at the timeout (`None`: none).
    fn sleep(&self, timeout: Option<Duration>) -> Result<(), ListenerWaitError> {
        let mgmt = self.mgmt();
        let deadline = timeout.map(|t| Instant::now() + t);
        mgmt.sleepers.fetch_add(1, Ordering::SeqCst);
        let result = loop {
            if self.take() {
                break Ok(());
            }
            let left = match deadline {
                None => None,
                Some(deadline) => match deadline.checked_duration_since(Instant::now()) {
                    Some(left) if !left.is_zero() => Some(left),
                    _ => break Ok(()),
                },
            };
            match futex_wait(&mgmt.posts, 0, left) {
                // Woken, the word moved before we slept, the timeout, or a
                // signal: each ends in another look at `posts` and the clock.
                Ok(()) | Err(libc::EAGAIN | libc::ETIMEDOUT | libc::EINTR) => continue,
                Err(_) => break Err(ListenerWaitError::InternalFailure),
            }
        };
        mgmt.sleepers.fetch_sub(1, Ordering::SeqCst);
        result
    }
}

impl<E: EventState, S: DynamicStorage<State<E, FutexMgmt>>> WaiterInterface<E, FutexMgmt, S>
    for FutexWaiter<E, S>
{
    const IS_FILE_DESCRIPTOR_BASED: bool = false;

    unsafe fn remove(
        _name: &FileName,
        _config: &Configuration,
    ) -> Result<bool, NamedConceptRemoveError> {
        // Nothing lives outside the event's storage, which iceoryx2 removes.
        Ok(true)
    }

    fn remove_path_hint(_value: &Path) -> Result<(), NamedConceptPathHintRemoveError> {
        Ok(())
    }

    fn create(
        _name: &FileName,
        _config: &Configuration,
        mgmt: &mut MaybeUninit<FutexMgmt>,
    ) -> Result<Self, ListenerCreateError> {
        let mgmt = mgmt.write(FutexMgmt {
            posts: AtomicU32::new(0),
            sleepers: AtomicU32::new(0),
        });
        Ok(Self {
            mgmt: NonNull::from(&*mgmt),
            _state: PhantomData,
        })
    }

    fn try_wait(&self) -> Result<(), ListenerWaitError> {
        self.take();
        Ok(())
    }

    fn timed_wait(&self, timeout: Duration) -> Result<(), ListenerWaitError> {
        self.sleep(Some(timeout))
    }

    fn blocking_wait(&self) -> Result<(), ListenerWaitError> {
        self.sleep(None)
    }

    fn empty_buffer(&self) -> Result<(), ListenerWaitError> {
        self.take();
        Ok(())
    }
}
