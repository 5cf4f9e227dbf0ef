//! # simbus transport
//!
//! How simbus's wire types travel: the iceoryx2 service type every simbus
//! port is built on ([`Bus`]), the one description of every service of a
//! world ([`spec`]), and the machine-wide iceoryx2 setup a process needs
//! before it creates a node ([`environment`]).
//!
//! ## The service type
//!
//! iceoryx2's own `ipc::Service` wakes a blocked listener through a Unix
//! datagram socket: a `sendto` on one side and a `recvfrom` on the other per
//! hop. [`Bus`] is the same service with one concept swapped: the event's
//! trigger is a futex in the event's shared memory ([`futex`]). A notify of
//! a listener that is not asleep is then an atomic add and no system call; a
//! wake-up is one `futex` call on each side. Everything else (shared memory,
//! connections, dead-node monitoring and cleanup) is `ipc::Service`'s,
//! unchanged.
//!
//! Every simbus process must use this type: a port of another service type
//! does not find simbus's services.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

mod bus;
pub mod environment;
mod event_spec;
pub mod frame_sample;
pub mod futex;
pub mod hybrid;
mod limit;
pub mod spec;
pub mod stamps;

pub use bus::{node, sender_pid, Bus, EarlierClients, NodeError};
