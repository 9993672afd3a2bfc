//! A network output that never stalls localization: [`NetSender`] is a TCP client on its
//! own thread that connects to a receiver, retries while the receiver is absent, and
//! reconnects when it goes away. The localizer hands it finished messages
//! ([`NetSender::send`]) and returns at once:
//!
//! - messages wait in a bounded queue ([`QUEUE_MESSAGES`]); when it is full (the receiver is
//!   absent or slower than the results) the new message is **dropped and counted**;
//! - a message being written when the connection breaks is dropped and counted too, and
//!   so are those written after the receiver shut its side (TCP takes a write or two
//!   after the peer left without a word; a receiver that only half-closed still gets
//!   them); the next one goes to the new connection (messages are never split across
//!   connections);
//! - the kernel's send buffer is kept small ([`SEND_BUFFER_BYTES`]), so a receiver that
//!   stalls and reads again gets recent messages, not the backlog of the whole stall;
//! - what happened (connected, lost, how many dropped) is reported as notes
//!   ([`NetSender::take_notes`]) and in the final [`NetStats`].
//!
//! HARK's stream, ODAS's SSL/SST sinks and any later network output use it.

use std::io::Write;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Messages queued while the receiver is slow or absent; beyond, new ones are dropped.
pub const QUEUE_MESSAGES: usize = 1024;

/// Wait between connection attempts.
pub const RETRY: Duration = Duration::from_millis(250);

/// A write that makes no progress for this long counts as a lost connection.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// The kernel's send buffer asked for on each connection (Linux doubles it). Its default
/// grows to 4 MB, which a stalled receiver fills silently with a minute of messages at
/// 100 per second and then gets them all, a minute late, when it reads again; with this
/// one, writes stall after a few seconds of backlog, [`WRITE_TIMEOUT`] counts the
/// connection as lost, and what the receiver reads on its return is recent.
pub const SEND_BUFFER_BYTES: usize = 64 * 1024;

/// What a sender did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NetStats {
    /// Messages written to a receiver.
    pub sent: u64,
    /// Messages dropped (queue full, no receiver, or the connection broke while writing).
    pub dropped: u64,
    /// Connections made (1 when the receiver was there throughout).
    pub connections: u64,
}

#[derive(Default)]
struct Shared {
    sent: AtomicU64,
    dropped: AtomicU64,
    connections: AtomicU64,
    notes: Mutex<Vec<String>>,
    connected: AtomicBool,
    /// Set by [`NetSender::finish`]: send what is queued until then, drop the rest.
    deadline: Mutex<Option<Instant>>,
}

impl Shared {
    fn note(&self, s: String) {
        if let Ok(mut n) = self.notes.lock() {
            n.push(s);
        }
    }
    fn stats(&self) -> NetStats {
        NetStats {
            sent: self.sent.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            connections: self.connections.load(Ordering::Relaxed),
        }
    }
}

/// A reconnecting, never-blocking TCP client. See the [module docs](self).
pub struct NetSender {
    what: String,
    peer: String,
    tx: Option<SyncSender<Vec<u8>>>,
    shared: Arc<Shared>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl std::fmt::Debug for NetSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NetSender")
            .field("what", &self.what)
            .field("peer", &self.peer)
            .finish()
    }
}

impl NetSender {
    /// Start sending to `peer` (`host:port`). `what` names the output in notes (e.g.
    /// "ODAS SSL"). Fails only when `peer` is not a valid address; an absent receiver is
    /// retried.
    pub fn start(what: &str, peer: &str) -> crate::Result<Self> {
        let addrs: Vec<SocketAddr> = peer
            .to_socket_addrs()
            .map_err(|e| {
                // A HOST:PORT whose host does not resolve is named as such, not as a bad form.
                let form_ok = peer
                    .rsplit_once(':')
                    .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
                crate::Error::Config(if form_ok {
                    format!("{what}: cannot resolve the host of {peer:?} ({e})")
                } else {
                    format!("{what}: {peer:?} is not a HOST:PORT address ({e})")
                })
            })?
            .collect();
        if addrs.is_empty() {
            return Err(crate::Error::Config(format!(
                "{what}: {peer:?} resolves to no address"
            )));
        }
        let (tx, rx) = sync_channel(QUEUE_MESSAGES);
        let shared = Arc::new(Shared::default());
        let (s, w, p) = (shared.clone(), what.to_string(), peer.to_string());
        let thread = std::thread::Builder::new()
            .name(format!("soundloc {what}"))
            .spawn(move || run(&w, &p, &addrs, &rx, &s))
            .map_err(|e| crate::Error::Config(format!("{what}: cannot start its thread: {e}")))?;
        Ok(NetSender {
            what: what.to_string(),
            peer: peer.to_string(),
            tx: Some(tx),
            shared,
            thread: Some(thread),
        })
    }

    /// The receiver's address as given.
    pub fn peer(&self) -> &str {
        &self.peer
    }

    /// Whether a receiver is connected now.
    pub fn is_connected(&self) -> bool {
        self.shared.connected.load(Ordering::Relaxed)
    }

    /// Queue one message (returns at once; a full queue drops it and counts it). Empty
    /// messages are ignored.
    pub fn send(&self, msg: Vec<u8>) {
        let Some(tx) = &self.tx else { return };
        if msg.is_empty() {
            return;
        }
        match tx.try_send(msg) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Notes since the last call (connected, connection lost, ...).
    pub fn take_notes(&self) -> Vec<String> {
        self.shared
            .notes
            .lock()
            .map(|mut n| std::mem::take(&mut *n))
            .unwrap_or_default()
    }

    /// Counts so far.
    pub fn stats(&self) -> NetStats {
        self.shared.stats()
    }

    /// Stop: what is queued is sent if a receiver is connected within `grace`; the rest is
    /// dropped and counted. Returns the final counts.
    pub fn finish(self, grace: Duration) -> NetStats {
        self.finish_noted(grace).0
    }

    /// [`NetSender::finish`], with the notes raised until it stopped (a connection lost
    /// while sending what was queued).
    pub fn finish_noted(mut self, grace: Duration) -> (NetStats, Vec<String>) {
        self.stop(grace);
        (self.shared.stats(), self.take_notes())
    }

    /// Start shutting down without waiting: nothing more is queued, and the sender gives
    /// up `grace` from now. Outputs closed together wind down at the same time (a run with
    /// several stalled receivers waits for the slowest, not for their sum);
    /// [`NetSender::finish`] then waits.
    pub fn close(&mut self, grace: Duration) {
        let Some(tx) = self.tx.take() else { return };
        // Tell the thread when to give up, then close the queue.
        if let Ok(mut d) = self.shared.deadline.lock() {
            *d = Some(Instant::now() + grace);
        }
        drop(tx);
    }

    fn stop(&mut self, grace: Duration) {
        self.close(grace);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    /// The output's name, as given to [`NetSender::start`].
    pub fn what(&self) -> &str {
        &self.what
    }
}

impl Drop for NetSender {
    /// Sends what is queued if a receiver is connected (up to [`WRITE_TIMEOUT`]).
    fn drop(&mut self) {
        self.stop(WRITE_TIMEOUT);
    }
}

fn connect(addrs: &[SocketAddr]) -> std::io::Result<TcpStream> {
    let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "no address");
    for a in addrs {
        match TcpStream::connect_timeout(a, Duration::from_secs(1)) {
            Ok(s) => {
                s.set_nodelay(true)?;
                s.set_write_timeout(Some(WRITE_TIMEOUT))?;
                limit_send_buffer(&s)?;
                return Ok(s);
            }
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Sets the connection's send buffer to [`SEND_BUFFER_BYTES`] (`SO_SNDBUF`): what a
/// stalled reader finds waiting when it reads again is then a few seconds of messages,
/// not the kernel's default of up to 4 MB. Also for the live view's WebSocket clients.
#[cfg(unix)]
pub fn limit_send_buffer(s: &TcpStream) -> std::io::Result<()> {
    use std::os::fd::AsRawFd;
    let size = SEND_BUFFER_BYTES as libc::c_int;
    // SAFETY: a valid socket descriptor (borrowed from `s`, open for the call) and a
    // c_int option value of the size passed.
    let r = unsafe {
        libc::setsockopt(
            s.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_SNDBUF,
            (&size as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Elsewhere the system's send buffer stays.
#[cfg(not(unix))]
pub fn limit_send_buffer(_: &TcpStream) -> std::io::Result<()> {
    Ok(())
}

/// Read what the receiver sent, without waiting, and throw it away (receivers send
/// nothing that matters; unread, it would hide their end of file): `Ok(true)` once they
/// have shut their side (end of file), `Err` when the connection is broken.
fn peer_shut(s: &TcpStream) -> std::io::Result<bool> {
    use std::io::Read;
    s.set_nonblocking(true)?;
    let mut buf = [0u8; 4096];
    let shut = loop {
        match (&*s).read(&mut buf) {
            Ok(0) => break Ok(true),
            Ok(_) => continue,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break Ok(false),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => break Err(e),
        }
    };
    s.set_nonblocking(false)?;
    shut
}

fn run(what: &str, peer: &str, addrs: &[SocketAddr], rx: &Receiver<Vec<u8>>, sh: &Shared) {
    let mut conn: Option<TcpStream> = None;
    // Messages written since the receiver shut its side: it may still read (a half-close,
    // e.g. `ncat` at the end of its input) or be gone, in which case TCP took them without
    // a word. Counted as sent, and moved to dropped if the connection then breaks.
    let mut unconfirmed = 0u64;
    let mut next_try = Instant::now();
    let mut said_absent = false;
    let drop_one = || {
        sh.dropped.fetch_add(1, Ordering::Relaxed);
    };
    loop {
        let deadline = sh.deadline.lock().ok().and_then(|d| *d);
        if deadline.is_some_and(|d| Instant::now() >= d) {
            break;
        }
        if conn.is_none() && Instant::now() >= next_try {
            match connect(addrs) {
                Ok(s) => {
                    let n = sh.connections.fetch_add(1, Ordering::Relaxed);
                    sh.connected.store(true, Ordering::Relaxed);
                    sh.note(if n == 0 {
                        format!("{what}: connected to {peer}")
                    } else {
                        format!("{what}: reconnected to {peer}")
                    });
                    said_absent = false;
                    conn = Some(s);
                    unconfirmed = 0;
                }
                Err(e) => {
                    if !said_absent {
                        sh.note(format!(
                            "{what}: {peer} not reachable ({e}); retrying, results are dropped (and counted) until it is"
                        ));
                        said_absent = true;
                    }
                    next_try = Instant::now() + RETRY;
                }
            }
        }
        let wait = match (deadline, conn.is_some()) {
            (Some(d), _) => d.saturating_duration_since(Instant::now()).min(RETRY),
            (None, true) => Duration::from_secs(3600),
            (None, false) => next_try.saturating_duration_since(Instant::now()),
        };
        match rx.recv_timeout(wait) {
            Ok(msg) => match &mut conn {
                Some(s) => {
                    // A receiver that has closed takes one more write without an error
                    // (the refusal comes back later): ask the socket first, so that the
                    // message is counted as dropped instead of lost unseen.
                    let sent = peer_shut(s).and_then(|shut| {
                        s.write_all(&msg).and_then(|_| s.flush())?;
                        Ok(shut)
                    });
                    match sent {
                        Err(e) => {
                            drop_one();
                            // What TCP took after the receiver left never arrived.
                            sh.sent.fetch_sub(unconfirmed, Ordering::Relaxed);
                            sh.dropped.fetch_add(unconfirmed, Ordering::Relaxed);
                            unconfirmed = 0;
                            sh.connected.store(false, Ordering::Relaxed);
                            let why = match e.kind() {
                                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => format!(
                                    "a write timed out after {} s: the receiver is not reading",
                                    WRITE_TIMEOUT.as_secs()
                                ),
                                _ => e.to_string(),
                            };
                            sh.note(format!("{what}: connection to {peer} lost ({why}); reconnecting"));
                            conn = None;
                            next_try = Instant::now();
                        }
                        Ok(shut) => {
                            sh.sent.fetch_add(1, Ordering::Relaxed);
                            if shut || unconfirmed > 0 {
                                unconfirmed += 1;
                            }
                        }
                    }
                }
                None => drop_one(),
            },
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    // Whatever is still queued is lost.
    while rx.try_recv().is_ok() {
        drop_one();
    }
    sh.connected.store(false, Ordering::Relaxed);
}
