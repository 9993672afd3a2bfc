//! `tcp-listen:` with `--keep-listening`: one input made of the senders that connect one
//! after another, as a service on a robot or a recording rig needs (a sender that
//! restarts, several takes sent in turn). When a sender ends (it closes, its connection
//! breaks, or its data goes wrong), the listener waits for the next one; the time in
//! between is a pause of the stream ([`AudioSource::take_pause`]): later results keep
//! their true times, windows across it are skipped, tentative tracks are forgotten.
//! Every sender must send the first one's sampling rate and channel count (a raw
//! input's flags fix both); one that does not is told why on stderr and disconnected.
//! The run ends with Ctrl-C (or SIGTERM), which completes every output.
//!
//! Also `tcp:`'s connection, tried again while the sender is not up yet ([`connect`]).

use soundloc::audio::{AudioFormat, AudioSource};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Opens a sender's connection as an audio stream (WAV/FLAC, or raw PCM by the flags).
pub type Opener = Box<dyn Fn(TcpStream, &Path) -> anyhow::Result<Box<dyn AudioSource>> + Send>;

/// The senders of one listening socket, as one source (module docs).
pub struct Senders {
    listener: TcpListener,
    open: Opener,
    name: PathBuf,
    quiet: bool,
    current: Box<dyn AudioSource>,
    peer: SocketAddr,
    /// The first sender's rate and channels (no length: the input has none).
    format: AudioFormat,
    /// Frames of time without input since the last read (reported once).
    pause: u64,
}

impl Senders {
    /// Wait for the first sender whose audio opens (others are told why and dropped).
    pub fn first(listener: TcpListener, open: Opener, name: PathBuf, quiet: bool) -> anyhow::Result<Self> {
        let (current, peer) = next_sender(&listener, &open, &name, quiet, None)?;
        let format = AudioFormat {
            total_frames: None,
            ..current.format()
        };
        Ok(Senders {
            listener,
            open,
            name,
            quiet,
            current,
            peer,
            format,
            pause: 0,
        })
    }

    fn say(&self, msg: &str) {
        super::localize::note(self.quiet, msg);
    }
}

/// Accept connections until one opens as audio of `want`'s rate and channels (any, for
/// the first); returns it and its peer.
fn next_sender(
    listener: &TcpListener,
    open: &Opener,
    name: &Path,
    quiet: bool,
    want: Option<AudioFormat>,
) -> soundloc::Result<(Box<dyn AudioSource>, SocketAddr)> {
    loop {
        let (s, peer) = listener.accept().map_err(|e| soundloc::Error::io(name, e))?;
        let source = match open(s, name) {
            Ok(src) => src,
            Err(e) => {
                super::localize::note(quiet, &format!("{peer}: {e:#}; waiting for the next sender"));
                continue;
            }
        };
        let f = source.format();
        if let Some(w) = want {
            if (f.sample_rate_hz, f.channels) != (w.sample_rate_hz, w.channels) {
                super::localize::note(
                    quiet,
                    &format!(
                        "{peer}: refused: it sends {} channels at {} Hz, this run's input is {} channels at {} Hz; \
                         waiting for the next sender",
                        f.channels, f.sample_rate_hz, w.channels, w.sample_rate_hz
                    ),
                );
                continue;
            }
        }
        super::localize::note(quiet, &format!("receiving from {peer}"));
        return Ok((source, peer));
    }
}

impl AudioSource for Senders {
    fn format(&self) -> AudioFormat {
        self.format
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn read_interleaved(&mut self, max_frames: usize, buf: &mut Vec<f32>) -> soundloc::Result<usize> {
        loop {
            match self.current.read_interleaved(max_frames, buf) {
                Ok(n) if n > 0 => return Ok(n),
                Ok(_) => self.say(&format!(
                    "{}: the sender closed; waiting for the next one (Ctrl-C ends the run)",
                    self.peer
                )),
                Err(e) => self.say(&format!(
                    "{}: {e}; the sender is dropped, waiting for the next one (Ctrl-C ends the run)",
                    self.peer
                )),
            }
            // The ended sender's own notes (e.g. a frame cut at its end).
            for n in self.current.take_notes() {
                self.say(&n);
            }
            let ended = Instant::now();
            let (source, peer) = next_sender(
                &self.listener,
                &self.open,
                &self.name,
                self.quiet,
                Some(self.format),
            )?;
            self.current = source;
            self.peer = peer;
            let waited = ended.elapsed().as_secs_f64() * self.format.sample_rate_hz as f64;
            self.pause += (waited.round() as u64).max(1);
        }
    }

    fn take_notes(&mut self) -> Vec<String> {
        self.current.take_notes()
    }

    fn take_pause(&mut self) -> u64 {
        std::mem::take(&mut self.pause)
    }
}

/// Connect to `addr` within `timeout_s` seconds: a refused connection (the sender is not
/// listening yet) is tried again every 200 ms, and one not answered is waited for, until
/// then; any other error (a name that does not resolve, an unreachable network) ends it at
/// once. 0 = one try, with the system's own time limit. `timeout_s` is checked by
/// [`super::input::InputArgs::open`] (finite, 0 or more).
pub(super) fn connect(addr: &str, timeout_s: f64, quiet: bool) -> anyhow::Result<TcpStream> {
    use std::time::Duration;
    if timeout_s <= 0.0 {
        return Ok(TcpStream::connect(addr)?);
    }
    let addrs: Vec<SocketAddr> = std::net::ToSocketAddrs::to_socket_addrs(addr)?.collect();
    let deadline = Instant::now() + Duration::from_secs_f64(timeout_s.min(1e6));
    let mut told = false;
    loop {
        let mut last = None;
        for a in &addrs {
            let left = deadline
                .saturating_duration_since(Instant::now())
                .max(Duration::from_millis(100));
            match TcpStream::connect_timeout(a, left) {
                Ok(s) => return Ok(s),
                Err(e) => last = Some(e),
            }
        }
        let e = last.unwrap_or_else(|| std::io::Error::other("the name resolves to no address"));
        let retry = matches!(
            e.kind(),
            std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::TimedOut
        );
        if retry && Instant::now() < deadline {
            if !told && !quiet {
                eprintln!(
                    "soundloc: tcp:{addr} refused the connection (no sender yet); trying again for up to \
                     {timeout_s} s (--connect-timeout)"
                );
            }
            told = true;
            std::thread::sleep(Duration::from_millis(200));
        } else if retry {
            return Err(anyhow::Error::new(e)
                .context(format!("no sender came within {timeout_s} s (--connect-timeout)")));
        } else {
            return Err(e.into());
        }
    }
}
