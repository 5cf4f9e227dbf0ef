//! What the docs say of the handles and threads: `Client`, `Ticker`,
//! `Participant` and `Sensor` are neither `Send` nor `Sync` (their iceoryx2
//! ports belong to the thread that opened them); the plain values they hand
//! out are both. A type that changes side fails to compile here, and its
//! docs must change with it. (A client per thread against a real server:
//! `tests/tests/client_api.rs`.)

use sim_client::{
    Client, ClientBuilder, Participant, Sensor, Status, Ticker, WaitError, WorldSnapshot,
};

fn assert_send_sync<T: Send + Sync>() {}

/// Compiles only when `$ty` does not implement `$bound`: with the bound,
/// both impls apply and the call is ambiguous (the `static_assertions`
/// crate's trick).
macro_rules! assert_not {
    ($ty:ty: $bound:path) => {{
        trait AmbiguousIfImpl<A> {
            fn some_item() {}
        }
        impl<T: ?Sized> AmbiguousIfImpl<()> for T {}
        #[allow(dead_code)]
        struct Invalid;
        impl<T: ?Sized + $bound> AmbiguousIfImpl<Invalid> for T {}
        let _ = <$ty as AmbiguousIfImpl<_>>::some_item;
    }};
}

#[test]
fn handles_with_ports_stay_on_their_thread() {
    assert_not!(Client: Send);
    assert_not!(Client: Sync);
    assert_not!(Ticker: Send);
    assert_not!(Ticker: Sync);
    assert_not!(Participant: Send);
    assert_not!(Participant: Sync);
    assert_not!(Sensor: Send);
    assert_not!(Sensor: Sync);
}

#[test]
fn values_and_errors_cross_threads() {
    assert_send_sync::<Status>();
    assert_send_sync::<WorldSnapshot>();
    assert_send_sync::<ClientBuilder>();
    assert_send_sync::<WaitError>();
    assert_send_sync::<sim_client::RequestError>();
    assert_send_sync::<sim_client::ConnectError>();
}
