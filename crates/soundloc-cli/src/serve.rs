//! `--serve ADDR`: the live view. A small HTTP server on its own threads serves one
//! self-contained page (`assets/view.html` and `assets/view.js`, embedded in the binary; no
//! network needed) and streams the run to every page over a WebSocket (`/ws`) in the
//! messages of [`soundloc::output::live`].
//!
//! The engine never waits for a browser: each client has a bounded queue
//! ([`CLIENT_QUEUE`] messages); when it is full the client's new messages are dropped and
//! counted (the page shows the count), and a client whose socket accepts nothing for
//! [`WRITE_TIMEOUT`] is disconnected. A page that connects late first receives the
//! `hello` and the last [`HISTORY`] results and spectra, so a finished file can still be
//! reviewed. At most [`MAX_CLIENTS`] connections are served at once (one thread each);
//! more are answered 503 and closed.

use anyhow::Context;
use soundloc::output::live;
use std::collections::VecDeque;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tungstenite::Message;

const PAGE: &str = include_str!("../assets/view.html");
const SCRIPT: &str = include_str!("../assets/view.js");

/// Messages queued per client before its new ones are dropped.
pub const CLIENT_QUEUE: usize = 512;
/// Results (with their spectra) replayed to a page that connects late.
pub const HISTORY: usize = 450;
/// Connections served at once (pages, scripts, WebSockets): one thread each.
pub const MAX_CLIENTS: usize = 64;
/// A client socket that accepts nothing for this long is disconnected.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(5);
/// Longest HTTP request head read.
const MAX_HEAD: usize = 16 * 1024;

struct Client {
    tx: SyncSender<Message>,
    dropped: Arc<AtomicU64>,
}

#[derive(Default)]
struct State {
    clients: Vec<Client>,
    hello: Option<Message>,
    /// Result and spectrum messages, oldest first; `results` of them are results.
    history: VecDeque<Message>,
    results: usize,
    /// The latest status, replayed to late pages.
    status: Option<live::Status>,
}

impl State {
    /// Queue `m` for every client; full queues drop it (counted), gone clients are removed.
    fn broadcast(&mut self, m: &Message) {
        self.clients.retain(|c| match c.tx.try_send(m.clone()) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                c.dropped.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        });
    }
}

/// The running live-view server.
pub struct LiveServer {
    addr: SocketAddr,
    state: Arc<Mutex<State>>,
    /// Audio time of the last spectrum sent (spectra are thinned to [`MAX_SPECTRA_PER_S`]).
    last_spectrum_s: f64,
    last_status: Option<Instant>,
}

/// Spectra sent per second of audio at most (a page cannot show more).
pub const MAX_SPECTRA_PER_S: f64 = 50.0;

impl LiveServer {
    /// Whether `addr` can be listened on (the error `bind` would give), checked before a
    /// run's slow steps; the port is free again when this returns.
    pub fn check(addr: &str) -> anyhow::Result<()> {
        listen(addr).map(drop)
    }

    /// Listen on `addr` (`HOST:PORT`; port 0 picks a free one). Requests must name the
    /// server in their Host as [`host_allowed`] says, with `hosts` the names given with
    /// `--serve-host`.
    pub fn bind(addr: &str, hosts: &[String]) -> anyhow::Result<Self> {
        let hosts: Arc<[String]> = server_names(hosts).into();
        let l = listen(addr)?;
        let addr = l.local_addr()?;
        let state = Arc::new(Mutex::new(State::default()));
        let s = state.clone();
        std::thread::Builder::new()
            .name("soundloc view".into())
            .spawn(move || {
                let active = Arc::new(AtomicUsize::new(0));
                for mut conn in l.incoming().flatten() {
                    if active.load(Ordering::Acquire) >= MAX_CLIENTS {
                        let _ = conn.set_write_timeout(Some(Duration::from_secs(1)));
                        let _ = conn.write_all(
                            b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                        );
                        continue;
                    }
                    active.fetch_add(1, Ordering::AcqRel);
                    let (s, mine, hosts) = (s.clone(), active.clone(), hosts.clone());
                    let spawned = std::thread::Builder::new()
                        .name("soundloc view client".into())
                        .spawn(move || {
                            // The place is given back however the client ends (a panic too).
                            struct Place(Arc<AtomicUsize>);
                            impl Drop for Place {
                                fn drop(&mut self) {
                                    self.0.fetch_sub(1, Ordering::AcqRel);
                                }
                            }
                            let _place = Place(mine);
                            handle(conn, &s, &hosts);
                        });
                    if spawned.is_err() {
                        active.fetch_sub(1, Ordering::AcqRel);
                    }
                }
            })?;
        Ok(LiveServer {
            addr,
            state,
            last_spectrum_s: f64::NEG_INFINITY,
            last_status: None,
        })
    }

    /// Where it listens.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        let mut g = self.state.lock().unwrap_or_else(|p| p.into_inner());
        f(&mut g)
    }

    /// Send the `hello` (to pages now and later).
    pub fn hello(&self, text: String) {
        let m = Message::text(text);
        self.with(|s| {
            s.broadcast(&m);
            s.hello = Some(m);
        });
    }

    /// Whether the spectrum of a result at `time_s` is to be sent (spectra are thinned to
    /// [`MAX_SPECTRA_PER_S`] per second of audio); `true` books it.
    pub fn spectrum_due(&mut self, time_s: f64) -> bool {
        let due = time_s - self.last_spectrum_s >= 1.0 / MAX_SPECTRA_PER_S - 1e-9;
        if due {
            self.last_spectrum_s = time_s;
        }
        due
    }

    /// Send one result and, when given, its spectrum (kept for late pages).
    pub fn result(&mut self, text: String, spectrum: Option<Vec<u8>>) {
        self.with(|s| {
            let m = Message::text(text);
            s.broadcast(&m);
            s.history.push_back(m);
            s.results += 1;
            if let Some(b) = spectrum {
                let m = Message::binary(b);
                s.broadcast(&m);
                s.history.push_back(m);
            }
            while s.results > HISTORY {
                if let Some(Message::Text(_)) = s.history.pop_front() {
                    s.results -= 1;
                }
                // Drop the spectrum that followed the result too.
                while matches!(s.history.front(), Some(Message::Binary(_))) {
                    s.history.pop_front();
                }
            }
        });
    }

    /// Send the run's status (at most about twice a second unless `force`).
    pub fn status(&mut self, st: live::Status, force: bool) {
        if !force
            && self
                .last_status
                .is_some_and(|t| t.elapsed() < Duration::from_millis(500))
        {
            return;
        }
        self.last_status = Some(Instant::now());
        self.with(|s| {
            s.status = Some(st);
            s.clients.retain(|c| {
                let mut st = st;
                st.view_dropped = c.dropped.load(Ordering::Relaxed);
                match c.tx.try_send(Message::text(live::status(&st))) {
                    Ok(()) => true,
                    Err(TrySendError::Full(_)) => {
                        c.dropped.fetch_add(1, Ordering::Relaxed);
                        true
                    }
                    Err(TrySendError::Disconnected(_)) => false,
                }
            });
        });
    }
}

/// Read the request head without consuming it (a WebSocket handshake reads it again):
/// its text (invalid UTF-8 replaced), its length in bytes, and whether it was UTF-8.
fn peek_head(c: &TcpStream) -> Option<(String, usize, bool)> {
    let mut buf = vec![0u8; MAX_HEAD];
    let t = Instant::now();
    loop {
        let n = c.peek(&mut buf).ok()?;
        if n == 0 {
            return None;
        }
        if let Some(end) = buf[..n].windows(4).position(|w| w == b"\r\n\r\n") {
            let head = &buf[..end + 4];
            return Some((
                String::from_utf8_lossy(head).into_owned(),
                end + 4,
                std::str::from_utf8(head).is_ok(),
            ));
        }
        if n == MAX_HEAD || t.elapsed() > Duration::from_secs(5) {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The names besides IP addresses and localhost that a request's Host may give, lower
/// case: `extra` (`--serve-host`), this machine's own name and NAME.local (its mDNS name).
fn server_names(extra: &[String]) -> Vec<String> {
    let mut v: Vec<String> = extra
        .iter()
        .map(|h| h.trim_end_matches('.').to_ascii_lowercase())
        .collect();
    let me = own_name().to_ascii_lowercase();
    if !me.is_empty() {
        v.push(format!("{me}.local"));
        v.push(me);
    }
    v
}

/// Whether a request's Host header names this server as a browser reaches it: an IP
/// address, `localhost` (or a name under it), or one of `names` ([`server_names`]). A page
/// of another site whose name was re-pointed at this address (DNS rebinding) sends its own
/// name and is refused, so it cannot read the stream as a same-origin page would.
pub fn host_allowed(host: &str, names: &[String]) -> bool {
    let name = match host.strip_prefix('[') {
        // [IPv6]:port
        Some(rest) => {
            return rest
                .split(']')
                .next()
                .is_some_and(|a| a.parse::<std::net::Ipv6Addr>().is_ok())
        }
        None => match host.rsplit_once(':') {
            Some((n, port)) if port.bytes().all(|b| b.is_ascii_digit()) => n,
            _ => host,
        },
    };
    let name = name.trim_end_matches('.').to_ascii_lowercase();
    if name.parse::<std::net::Ipv4Addr>().is_ok() || name == "localhost" || name.ends_with(".localhost") {
        return true;
    }
    names.contains(&name)
}

/// This machine's host name (empty when unknown).
fn own_name() -> String {
    #[cfg(unix)]
    {
        let mut buf = [0u8; 256];
        // SAFETY: a buffer of the length given; the name is NUL-terminated within it or
        // truncated, which the search for the first NUL handles.
        if unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0 {
            let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
            return String::from_utf8_lossy(&buf[..end]).into_owned();
        }
        String::new()
    }
    #[cfg(not(unix))]
    {
        std::env::var("COMPUTERNAME").unwrap_or_default()
    }
}

fn handle(conn: TcpStream, state: &Mutex<State>, hosts: &[String]) {
    let _ = conn.set_read_timeout(Some(Duration::from_secs(5)));
    let _ = conn.set_write_timeout(Some(WRITE_TIMEOUT));
    let Some((head, head_len, utf8)) = peek_head(&conn) else {
        return;
    };
    let mut first = head.lines().next().unwrap_or("").split_whitespace();
    let (method, path) = (first.next().unwrap_or(""), first.next().unwrap_or(""));
    let upgrade = head.lines().any(|l| {
        l.to_ascii_lowercase().starts_with("upgrade:") && l.to_ascii_lowercase().contains("websocket")
    });
    let key = head
        .lines()
        .any(|l| l.to_ascii_lowercase().starts_with("sec-websocket-key:"));
    let route = path.split('?').next().unwrap_or("");
    // A page of another site open in the same browser may not read the stream: a
    // WebSocket request that carries an Origin must come from this server's own page.
    let header = |name: &str| {
        head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim().to_string())
        })
    };
    let foreign = match (header("origin"), header("host")) {
        // Host names compare without regard to case (RFC 3986 §3.2.2).
        (Some(o), Some(h)) => !o
            .split_once("://")
            .is_some_and(|(_, a)| a.eq_ignore_ascii_case(&h)),
        (Some(_), None) => true,
        _ => false,
    };
    let host = header("host");
    let stranger = host.as_deref().filter(|h| !host_allowed(h, hosts));
    if method == "GET" && route == "/ws" && upgrade && key && !foreign && stranger.is_none() {
        websocket(conn, state);
        return;
    }
    // A plain request: consume the head, answer, close.
    let mut conn = conn;
    let mut sink = vec![0u8; head_len];
    if conn.read_exact(&mut sink).is_err() {
        return;
    }
    // HEAD is GET without the body (RFC 9110 §9.3.2).
    let get = matches!(method, "GET" | "HEAD");
    let refused;
    let (status, ctype, body) = match (get, route) {
        _ if !utf8 => ("400 Bad Request", "text/plain; charset=utf-8", "not UTF-8\n"),
        _ if stranger.is_some() => {
            refused = format!(
                "Host {} is not a name of this server (an IP address, localhost or this machine's name); \
                 if it is one, start soundloc with --serve-host {}\n",
                stranger.unwrap_or_default(),
                stranger.unwrap_or_default().split(':').next().unwrap_or_default()
            );
            ("403 Forbidden", "text/plain; charset=utf-8", refused.as_str())
        }
        (true, "/ws") if foreign => (
            "403 Forbidden",
            "text/plain; charset=utf-8",
            "the live view's stream is served to its own page only (Origin differs from Host)\n",
        ),
        (true, "/ws") => (
            "400 Bad Request",
            "text/plain; charset=utf-8",
            "a WebSocket upgrade with Sec-WebSocket-Key is expected here\n",
        ),
        (true, "/" | "/index.html") => ("200 OK", "text/html; charset=utf-8", PAGE),
        (true, "/view.js") => ("200 OK", "text/javascript; charset=utf-8", SCRIPT),
        (true, _) => ("404 Not Found", "text/plain; charset=utf-8", "not found\n"),
        (false, _) => (
            "405 Method Not Allowed",
            "text/plain; charset=utf-8",
            "GET or HEAD only\n",
        ),
    };
    let allow = if get { "" } else { "Allow: GET, HEAD\r\n" };
    let _ = write!(
        conn,
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n{allow}Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n\r\n{}",
        body.len(),
        if method == "HEAD" { "" } else { body }
    );
    let _ = conn.flush();
}

fn listen(addr: &str) -> anyhow::Result<TcpListener> {
    TcpListener::bind(addr).with_context(|| {
        use std::net::ToSocketAddrs;
        let form = if addr.to_socket_addrs().is_err() {
            " (expected [HOST:]PORT: 8080, 127.0.0.1:8080, 0.0.0.0:8080)"
        } else {
            ""
        };
        format!("--serve {addr}: cannot listen{form}")
    })
}

fn websocket(conn: TcpStream, state: &Mutex<State>) {
    // A page back from a stall (a hidden tab, a laptop lid) then finds a little of what
    // it missed and is live again, instead of megabytes of stale frames in the kernel.
    let _ = soundloc::output::netsink::limit_send_buffer(&conn);
    // Pages send nothing but control frames: a small limit on what is read from them.
    let config = tungstenite::protocol::WebSocketConfig::default()
        .max_message_size(Some(64 << 10))
        .max_frame_size(Some(64 << 10));
    let Ok(mut ws) = tungstenite::accept_with_config(conn, Some(config)) else {
        return;
    };
    let (tx, rx): (SyncSender<Message>, Receiver<Message>) = sync_channel(CLIENT_QUEUE);
    // Register and take the replay under one lock: nothing missed, nothing twice.
    let replay: Vec<Message> = {
        let mut s = state.lock().unwrap_or_else(|p| p.into_inner());
        s.clients.push(Client {
            tx,
            dropped: Arc::new(AtomicU64::new(0)),
        });
        let status = s.status.map(|st| Message::text(live::status(&st)));
        s.hello
            .iter()
            .chain(s.history.iter())
            .cloned()
            .chain(status)
            .collect()
    };
    for m in replay {
        if ws.send(m).is_err() {
            return;
        }
    }
    // While nothing is queued (after the input ends, or in a stall) the page's own frames
    // are read: a page that closed frees its place within IDLE_CHECK. Every PING_EVERY of
    // idleness it is pinged; one that has not answered by the next ping (its network went
    // away without a word) is let go.
    let (mut idle, mut unanswered) = (Duration::ZERO, false);
    loop {
        match rx.recv_timeout(IDLE_CHECK) {
            Ok(m) => {
                idle = Duration::ZERO;
                if ws.send(m).is_err() {
                    return;
                }
            }
            Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => {
                idle += IDLE_CHECK;
                match page_is_there(&mut ws) {
                    None => return,
                    Some(true) => unanswered = false,
                    Some(false) => {}
                }
                if idle >= PING_EVERY {
                    if unanswered {
                        return;
                    }
                    idle = Duration::ZERO;
                    unanswered = true;
                    if ws.send(Message::Ping(Vec::new().into())).is_err() {
                        return;
                    }
                }
            }
        }
    }
    let _ = ws.close(None);
}

/// How often an idle WebSocket reads what its page sent.
const IDLE_CHECK: Duration = Duration::from_millis(500);
/// How long a WebSocket stays idle before it pings its page.
const PING_EVERY: Duration = Duration::from_secs(10);

/// Read what the page sent without waiting: `None` once it closed (its close answered),
/// hung up or broke the protocol; else whether any frame came (its pings are answered
/// with the next write).
fn page_is_there(ws: &mut tungstenite::WebSocket<TcpStream>) -> Option<bool> {
    ws.get_mut().set_nonblocking(true).ok()?;
    let mut heard = false;
    let there = loop {
        match ws.read() {
            Ok(Message::Close(_)) => break false,
            Ok(_) => heard = true,
            Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => break true,
            Err(_) => break false,
        }
    };
    ws.get_mut().set_nonblocking(false).ok()?;
    if !there {
        // The reply to a close the page sent (queued by the read).
        let _ = ws.flush();
        return None;
    }
    Some(heard)
}

#[cfg(test)]
mod tests;
