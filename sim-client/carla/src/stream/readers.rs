//! Who reads which stream, and what each is sent. Three rules keep CARLA's
//! client alive across an episode change: its `reload_world`/`load_world`
//! replace its episode object without a lock as soon as `load_new_episode`
//! is answered, and its streaming client closes sockets without one.
//!
//! - No sensor capture goes out while a world load is in flight, and no
//!   message of an older episode once a newer one began. A sensor message
//!   the client's io thread reads while its main thread swaps the episode
//!   makes that io thread build an episode of its own (`TryLock` in the
//!   sensor callback): a use-after-free, a 10 s wait thrown out of a
//!   `noexcept` function (`terminate`), or two subscriptions of the world
//!   stream stopping each other's socket (`close: Bad file descriptor`).
//!   Captures written just before the load's request may still wait in
//!   the client for an io thread (on a busy machine, or behind Python's
//!   GIL): the load is answered only once the last capture written had
//!   [`CAPTURES_LAND`] to reach its callback. Two such callbacks in the
//!   swap took both io threads of a 2-core machine into a 10 s wait for a
//!   world state that only an io thread could read.
//! - The world stream is quiet while the client swaps its subscription:
//!   from a load's request until a world reader subscribes again, world
//!   states are held (the latest goes out then). The client stops its old
//!   world stream from its main thread while its io thread may be reading
//!   it, which corrupts boost's reactor (a crash in the new stream's reads).
//! - The gateway never closes a stream socket its client still reads: the
//!   client reconnects from its io thread, closing the socket there while
//!   its main thread may close it too (a stopped or collected sensor), and
//!   the second close throws `close: Bad file descriptor` on a thread that
//!   catches nothing. A stream that ended keeps its readers open, unwritten,
//!   until their clients hang up ([`linger`]).
//!
//! CARLA's own server is quiet the same way by accident: it loads a map
//! for seconds without ticking, and keeps a dead sensor's socket open for
//! its session timeout.

use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use tracing::{debug, warn};

use crate::wire::{is_world_stream, WORLD_STREAM_ID};

/// How long a handed-out sensor token waits for its connection.
const PENDING_FOR: Duration = Duration::from_secs(10);
/// Captures kept for a listener between `get_sensor_token` and its
/// connection (the captures of the ticks in between).
const BACKLOG: usize = 32;
/// A stack is enough for a thread that only reads a socket to its end.
const LINGER_STACK: usize = 64 * 1024;
/// How long the world stream stays held after a world load when no CARLA
/// client subscribes to it again (the loading client does, within a few
/// calls): then the clients that did not load get world states again.
const WORLD_HOLD_AT_MOST: Duration = Duration::from_secs(1);
/// How long a capture written before a world load is given to reach the
/// client's sensor callback before the load is answered (see the module's
/// first rule). CARLA's own server answers a load and then loads for
/// seconds; this is the part of that quiet the client's race needs.
pub(super) const CAPTURES_LAND: Duration = Duration::from_millis(100);

/// (run pid, episode): the episode a message belongs to. The run is the
/// server's ([`sim_client::Status::run_pid`]): a server resumed from its
/// journal continues it, and its episodes.
pub(super) type EpisodeKey = (u32, u64);

/// Whether `key` names an episode older than `than`: the same run, an
/// earlier episode (a run's episodes only grow; another run's episode is
/// never older, it replaces the world).
pub(super) fn older(key: EpisodeKey, than: EpisodeKey) -> bool {
    key.0 == than.0 && key.1 < than.1
}

/// One stream's readers, and what waits for a reader about to connect.
#[derive(Debug, Default)]
struct Stream {
    readers: Vec<TcpStream>,
    /// Tokens handed out whose connection has not come yet.
    pending: Vec<Instant>,
    backlog: Vec<Vec<u8>>,
    /// A forwarder feeds it.
    forwarded: bool,
}

impl Stream {
    fn expecting(&mut self) -> bool {
        self.pending.retain(|at| at.elapsed() < PENDING_FOR);
        !self.pending.is_empty()
    }
}

/// The world stream held back across a world load (see the module's
/// rules).
#[derive(Debug)]
struct WorldHold {
    since: Instant,
    /// The latest world state held, sent when the hold ends.
    latest: Option<Vec<u8>>,
}

/// Every stream by id, and which episode they carry. One lock guards it
/// all, so an episode change and every write are ordered: once a change
/// returns, no message it excludes is written.
#[derive(Debug, Default)]
pub(super) struct Streams {
    by_id: HashMap<u32, Stream>,
    /// The newest episode begun: messages of an older one are dropped.
    episode: EpisodeKey,
    /// World loads in flight: while any is, no sensor capture is written.
    changing: usize,
    world_hold: Option<WorldHold>,
    /// When a capture was last written to a reader.
    last_capture: Option<Instant>,
}

impl Streams {
    /// Makes `key` the current episode unless a newer one began; whether
    /// messages of `key` may go out.
    pub(super) fn admit(&mut self, key: EpisodeKey) -> bool {
        if older(key, self.episode) {
            return false;
        }
        if key != self.episode {
            debug!(
                run_pid = key.0,
                episode = key.1,
                "the streams carry a new episode"
            );
        }
        self.episode = key;
        true
    }

    /// A world load is about to be asked for: captures stop, the world
    /// stream is held.
    pub(super) fn change_begins(&mut self) {
        self.changing += 1;
        let hold = self.world_hold.get_or_insert(WorldHold {
            since: Instant::now(),
            latest: None,
        });
        hold.since = Instant::now();
    }

    /// A world load is over: captures flow again once none is in flight.
    /// A load that failed (`began` is `None`) ends the world stream's hold;
    /// one that began an episode keeps it until a world reader subscribes.
    pub(super) fn change_ends(&mut self, began: Option<EpisodeKey>) {
        self.changing = self.changing.saturating_sub(1);
        match began {
            Some(key) => {
                self.admit(key);
                // The loading client subscribes again only now: its wait
                // for the world stream starts here.
                if let Some(hold) = &mut self.world_hold {
                    hold.since = Instant::now();
                }
            }
            None if self.changing == 0 => self.release_world(),
            None => {}
        }
    }

    /// Sends capture `message` of episode `key` to the readers of sensor
    /// stream `stream`, unless a world load is in flight or a newer
    /// episode began. Returns whether it went out (or waits for its
    /// reader).
    pub(super) fn send_capture(&mut self, stream: u32, key: EpisodeKey, message: &[u8]) -> bool {
        if self.changing > 0 || older(key, self.episode) {
            return false;
        }
        if self.send(stream, message) {
            self.last_capture = Some(Instant::now());
        }
        true
    }

    /// How long a world load's answer must still wait for the captures
    /// written before it to reach the client's callbacks
    /// ([`CAPTURES_LAND`] after the last one).
    pub(super) fn captures_land_in(&self) -> Duration {
        self.last_capture.map_or(Duration::ZERO, |at| {
            CAPTURES_LAND.saturating_sub(at.elapsed())
        })
    }

    /// Sends world state `message` of episode `key` unless a newer episode
    /// began (a newer one begins with it); while the world stream is held
    /// it is kept instead, the latest to go out when the hold ends.
    /// Returns whether it went out or is kept.
    pub(super) fn send_world_state(&mut self, key: EpisodeKey, message: &[u8]) -> bool {
        if !self.admit(key) {
            return false;
        }
        let changing = self.changing;
        if let Some(hold) = &mut self.world_hold {
            if changing > 0 || hold.since.elapsed() < WORLD_HOLD_AT_MOST {
                hold.latest = Some(message.to_vec());
                return true;
            }
            debug!("no CARLA client subscribed to the world stream again: its hold ends");
            self.world_hold = None;
        }
        self.send(WORLD_STREAM_ID, message);
        true
    }

    /// Ends the world stream's hold, sending its readers the latest state
    /// held.
    fn release_world(&mut self) {
        if let Some(latest) = self.world_hold.take().and_then(|hold| hold.latest) {
            self.send(WORLD_STREAM_ID, &latest);
        }
    }

    /// Sends `message` to every reader of `stream`; a reader that fails is
    /// dropped. With no reader yet but one expected, the message waits.
    /// Returns whether it was written to a reader.
    fn send(&mut self, stream: u32, message: &[u8]) -> bool {
        let Some(s) = self.by_id.get_mut(&stream) else {
            return false;
        };
        if s.readers.is_empty() {
            if s.expecting() {
                if s.backlog.len() == BACKLOG {
                    s.backlog.remove(0);
                }
                s.backlog.push(message.to_vec());
            }
            return false;
        }
        s.readers
            .retain_mut(|reader| write_message(reader, message, stream));
        true
    }

    /// How long a forwarder of `stream` may wait before it must look again
    /// whether anyone still listens (see [`super::Hub::patience`]).
    pub(super) fn patience(&mut self, stream: u32) -> Option<Duration> {
        let s = self.by_id.get_mut(&stream)?;
        s.expecting();
        s.pending
            .iter()
            .map(|at| PENDING_FOR.saturating_sub(at.elapsed()))
            .min()
    }

    /// Whether a forwarder of `stream` may stop: nobody reads or is about
    /// to. If so it is marked stopped, atomically with the check.
    pub(super) fn retire(&mut self, stream: u32) -> bool {
        let Some(s) = self.by_id.get_mut(&stream) else {
            return true;
        };
        if s.readers.is_empty() && !s.expecting() {
            s.forwarded = false;
            s.backlog.clear();
            return true;
        }
        false
    }

    /// A token for `stream` was handed out: keep its messages until the
    /// connection comes. Returns whether a forwarder must be started.
    pub(super) fn expect(&mut self, stream: u32) -> bool {
        let s = self.by_id.entry(stream).or_default();
        s.pending.push(Instant::now());
        !std::mem::replace(&mut s.forwarded, true)
    }

    /// The forwarder of `stream` could not start.
    pub(super) fn forwarder_failed(&mut self, stream: u32) {
        if let Some(s) = self.by_id.get_mut(&stream) {
            s.forwarded = false;
            s.pending.pop();
        }
    }

    /// Stream `stream` ended: its readers, to keep open until their
    /// clients hang up ([`linger`]).
    pub(super) fn end(&mut self, stream: u32) -> Vec<TcpStream> {
        self.by_id
            .remove(&stream)
            .map(|s| s.readers)
            .unwrap_or_default()
    }

    /// Adds `socket` to the readers of `stream` (every world stream id is
    /// the one world stream), first sending it what waited for it; a world
    /// reader ends the world stream's hold once no load is in flight. A
    /// socket for a sensor stream the gateway does not have (it ended, or
    /// never was) is handed back, to [`linger`]: CARLA's client would
    /// reconnect a stream closed under it.
    pub(super) fn subscribe(&mut self, stream: u32, mut socket: TcpStream) -> Option<TcpStream> {
        let stream = if is_world_stream(stream) {
            WORLD_STREAM_ID
        } else {
            stream
        };
        let s = match self.by_id.entry(stream) {
            Entry::Occupied(s) => s.into_mut(),
            Entry::Vacant(s) if stream == WORLD_STREAM_ID => s.insert(Stream::default()),
            Entry::Vacant(_) => return Some(socket),
        };
        s.pending.pop();
        if !s.backlog.is_empty() && stream != WORLD_STREAM_ID {
            self.last_capture = Some(Instant::now());
        }
        for message in s.backlog.drain(..) {
            if !write_message(&mut socket, &message, stream) {
                return None;
            }
        }
        s.readers.push(socket);
        if stream == WORLD_STREAM_ID && self.changing == 0 {
            self.release_world();
        }
        None
    }
}

/// Keeps `socket`, a reader of `stream` that will get nothing more, open
/// until its client hangs up (see the module's rules: the gateway closing
/// it would make CARLA's client reconnect from its io thread). The client
/// closes it when it stops listening (`sensor.stop()`, `destroy()`, the
/// sensor object collected, the client's end); one small thread per such
/// socket waits for that, reading nothing but the end.
pub(super) fn linger(mut socket: TcpStream, stream: u32) {
    let spawned = std::thread::Builder::new()
        .name(format!("stream-{stream}-linger"))
        .stack_size(LINGER_STACK)
        .spawn(move || {
            let _ = socket.set_read_timeout(None);
            let mut sink = [0u8; 64];
            while matches!(socket.read(&mut sink), Ok(n) if n > 0) {}
            debug!(stream, "the reader of an ended stream hung up");
        });
    if let Err(e) = spawned {
        // The socket went with the closure: closed, as before.
        warn!(stream, "cannot keep an ended stream's reader open: {e}");
    }
}

/// Writes `message` to `reader` as `[u32 length][message]`; whether it
/// went (a reader that failed is dropped by the caller).
fn write_message(reader: &mut TcpStream, message: &[u8], stream: u32) -> bool {
    let length = (message.len() as u32).to_le_bytes();
    let sent = reader
        .write_all(&length)
        .and_then(|()| reader.write_all(message));
    if let Err(e) = &sent {
        debug!(stream, "stream reader dropped: {e}");
    }
    sent.is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// A connected pair: (the gateway's end, the client's end), the
    /// client's reads bounded so a missing message fails the test.
    fn pair() -> (TcpStream, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let client = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (gateway, _) = listener.accept().unwrap();
        client
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        (gateway, client)
    }

    /// The next `[u32 length][message]` frame the client reads.
    fn read_message(client: &mut TcpStream) -> Vec<u8> {
        let mut length = [0u8; 4];
        client.read_exact(&mut length).unwrap();
        let mut message = vec![0u8; u32::from_le_bytes(length) as usize];
        client.read_exact(&mut message).unwrap();
        message
    }

    /// Whether nothing is waiting for the client to read.
    fn nothing_to_read(client: &TcpStream) -> bool {
        client.set_nonblocking(true).unwrap();
        let mut byte = [0u8; 1];
        let empty =
            matches!(client.peek(&mut byte), Err(e) if e.kind() == std::io::ErrorKind::WouldBlock);
        client.set_nonblocking(false).unwrap();
        empty
    }

    const SENSOR: u32 = 1_000_000_007;

    #[test]
    fn an_older_episode_is_an_earlier_one_of_the_same_server() {
        assert!(older((7, 1), (7, 2)));
        assert!(!older((7, 2), (7, 2)));
        assert!(!older((7, 3), (7, 2)));
        assert!(!older((8, 1), (7, 2)), "another server replaces the world");
    }

    #[test]
    fn no_capture_goes_out_during_a_load_nor_an_old_episodes_after_it() {
        let mut streams = Streams::default();
        streams.admit((7, 1));
        streams.expect(SENSOR);
        let (gateway, mut client) = pair();
        assert!(streams.subscribe(SENSOR, gateway).is_none());
        assert!(streams.send_capture(SENSOR, (7, 1), b"before"));
        assert_eq!(read_message(&mut client), b"before");

        streams.change_begins();
        assert!(!streams.send_capture(SENSOR, (7, 1), b"during"));
        streams.change_ends(Some((7, 2)));
        assert!(!streams.send_capture(SENSOR, (7, 1), b"old episode"));
        assert!(streams.send_capture(SENSOR, (7, 2), b"new episode"));
        assert_eq!(read_message(&mut client), b"new episode");
    }

    #[test]
    fn a_load_waits_for_captures_written_to_a_reader_not_for_held_ones() {
        let mut streams = Streams::default();
        streams.admit((7, 1));
        assert_eq!(streams.captures_land_in(), Duration::ZERO, "nothing sent");
        let (world, _world_client) = pair();
        assert!(streams.subscribe(WORLD_STREAM_ID, world).is_none());
        assert!(streams.send_world_state((7, 1), b"frame 1"));
        assert_eq!(streams.last_capture, None, "a world state");

        streams.expect(SENSOR);
        assert!(streams.send_capture(SENSOR, (7, 1), b"backlog"));
        assert_eq!(streams.last_capture, None, "kept, unsent");
        let before = Instant::now();
        let (gateway, mut client) = pair();
        assert!(streams.subscribe(SENSOR, gateway).is_none());
        assert_eq!(read_message(&mut client), b"backlog");
        let flushed = streams.last_capture.expect("the backlog went out");
        assert!(flushed >= before);

        assert!(streams.send_capture(SENSOR, (7, 1), b"capture"));
        assert_eq!(read_message(&mut client), b"capture");
        assert!(streams.last_capture.unwrap() >= flushed);

        // The wait is what is left of CAPTURES_LAND since the last one.
        streams.last_capture = Some(Instant::now() + Duration::from_secs(3600));
        assert_eq!(streams.captures_land_in(), CAPTURES_LAND);
        streams.last_capture = Instant::now().checked_sub(CAPTURES_LAND * 2);
        assert_eq!(streams.captures_land_in(), Duration::ZERO);
    }

    #[test]
    fn world_states_wait_across_a_load_for_a_world_reader_to_subscribe_again() {
        let mut streams = Streams::default();
        let (old_reader, mut old_client) = pair();
        assert!(streams.subscribe(WORLD_STREAM_ID, old_reader).is_none());
        assert!(streams.send_world_state((7, 1), b"frame 9"));
        assert_eq!(read_message(&mut old_client), b"frame 9");

        streams.change_begins();
        assert!(streams.send_world_state((7, 1), b"frame 10"));
        streams.change_ends(Some((7, 2)));
        assert!(
            !streams.send_world_state((7, 1), b"frame 11"),
            "older episode"
        );
        assert!(streams.send_world_state((7, 2), b"frame 0"));
        assert!(nothing_to_read(&old_client), "held while the client swaps");

        // The new episode's subscription comes under its own world id.
        let (new_reader, mut new_client) = pair();
        assert!(streams.subscribe(WORLD_STREAM_ID + 1, new_reader).is_none());
        assert_eq!(read_message(&mut new_client), b"frame 0");
        assert_eq!(read_message(&mut old_client), b"frame 0");
        assert!(streams.send_world_state((7, 2), b"frame 1"));
        assert_eq!(read_message(&mut new_client), b"frame 1");
    }

    #[test]
    fn a_failed_load_lets_the_world_stream_go_at_once() {
        let mut streams = Streams::default();
        let (reader, mut client) = pair();
        assert!(streams.subscribe(WORLD_STREAM_ID, reader).is_none());
        streams.change_begins();
        assert!(streams.send_world_state((7, 1), b"frame 10"));
        assert!(nothing_to_read(&client));
        streams.change_ends(None);
        assert_eq!(read_message(&mut client), b"frame 10");
    }

    #[test]
    fn an_ended_streams_readers_stay_open_until_their_clients_hang_up() {
        let mut streams = Streams::default();
        streams.expect(SENSOR);
        let (gateway, mut client) = pair();
        assert!(streams.subscribe(SENSOR, gateway).is_none());
        let ended = streams.end(SENSOR);
        assert_eq!(ended.len(), 1);
        for reader in ended {
            linger(reader, SENSOR);
        }
        // A reconnection to the ended stream is handed back, to linger too.
        let (again, mut client_again) = pair();
        let again = streams.subscribe(SENSOR, again).expect("an unknown stream");
        linger(again, SENSOR);

        for client in [&mut client, &mut client_again] {
            assert!(nothing_to_read(client), "open, and nothing written");
            // The client hangs up its side: the gateway's side closes.
            client.shutdown(std::net::Shutdown::Write).unwrap();
            let mut byte = [0u8; 1];
            assert_eq!(client.read(&mut byte).unwrap(), 0);
        }
    }
}
