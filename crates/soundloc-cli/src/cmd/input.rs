//! Where `localize` reads audio: a file, standard input (WAV/FLAC or raw PCM), or a TCP
//! peer (connecting or listening). A reader thread delivers blocks to the compute loop
//! through a bounded queue:
//!
//! - files (and stdin redirected from a file) are read as fast as they are localized
//!   (the queue applies back-pressure; nothing is lost);
//! - live inputs (a pipe, a socket, a microphone) never wait for the localizer: when the
//!   queue holds `--max-buffer` seconds the newest block is dropped and counted, and the
//!   localizer is told about the gap (whole windows skipped, times kept true, a warning);
//! - but a pipe or socket that delivers audio well ahead of real time (`cat rec.wav |`,
//!   a file sent over the network) is a file in disguise: when the queue fills that far
//!   ahead ([`faster_than_real_time`]) the input is read like a file from then on,
//!   nothing dropped (and stderr says so).

use anyhow::{bail, Context};
use clap::ValueEnum;
use soundloc::audio::{open_source, open_stream, AudioFormat, AudioSource, RawEncoding, RawSource};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvError, Sender, TryRecvError};
use std::sync::Arc;

#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum RawArg {
    /// 8-bit unsigned (read as value - 128).
    U8,
    /// 16-bit signed little-endian.
    S16le,
    /// 24-bit signed little-endian (packed, 3 bytes).
    S24le,
    /// 32-bit signed little-endian.
    S32le,
    /// 32-bit float little-endian.
    F32le,
    /// 64-bit float little-endian.
    F64le,
}

impl From<RawArg> for RawEncoding {
    fn from(r: RawArg) -> Self {
        match r {
            RawArg::U8 => RawEncoding::U8,
            RawArg::S16le => RawEncoding::S16le,
            RawArg::S24le => RawEncoding::S24le,
            RawArg::S32le => RawEncoding::S32le,
            RawArg::F32le => RawEncoding::F32le,
            RawArg::F64le => RawEncoding::F64le,
        }
    }
}

/// Input options shared by `localize` (and, for the queue, `listen`).
#[derive(clap::Args, Debug, Clone)]
pub struct InputArgs {
    /// Input: a WAV/FLAC file, `-` for standard input, `tcp:HOST:PORT` to connect to a
    /// sender, or `tcp-listen:HOST:PORT` to wait for one.
    pub input: String,
    /// Headerless interleaved PCM on the input (instead of WAV/FLAC), with --raw-channels
    /// and --rate.
    #[arg(long, value_enum, requires_all = ["raw_channels", "rate"])]
    pub raw: Option<RawArg>,
    /// Channels of --raw input.
    #[arg(long, requires = "raw")]
    pub raw_channels: Option<usize>,
    /// Sampling rate of --raw input, Hz.
    #[arg(long, requires = "raw")]
    pub rate: Option<u32>,
    /// Live input: audio buffered while the localizer is behind, seconds; beyond it whole
    /// blocks are dropped (and counted). A pipe or socket more than a quarter of this (and
    /// at least 1 s, or half of it under 2 s) ahead of real time (a file being piped) is
    /// read like a file instead: nothing dropped.
    #[arg(long, default_value_t = 10.0)]
    pub max_buffer: f64,
    /// Read a file at real-time speed (as if it were being recorded), e.g. to review it
    /// in the live view (--serve); without it files are read as fast as they are localized.
    #[arg(long)]
    pub realtime: bool,
    /// With `tcp-listen:`: when a sender ends, wait for the next one instead of ending the
    /// run (Ctrl-C ends it). Each sender must send the first one's rate and channels; the
    /// time between senders is a pause (results keep their true times).
    #[arg(long)]
    pub keep_listening: bool,
    /// With `tcp:`: how long to wait for the sender, seconds: a refused connection (the
    /// sender is not up yet) is tried again, and an unanswered one waited for, until then;
    /// 0 = one try, with the system's own time limit.
    #[arg(long, default_value_t = 10.0, value_name = "SECS")]
    pub connect_timeout: f64,
    /// A WAV/FLAC file cut short (it ends before the length its header declares) is
    /// localized up to the cut, with a warning, instead of failing. Streams (a pipe, a
    /// socket) always are: a recorder stopped early.
    #[arg(long)]
    pub allow_truncated: bool,
}

/// An open input.
pub struct Input {
    pub source: Box<dyn AudioSource>,
    /// Live (drop when behind) rather than a file (wait).
    pub live: bool,
    pub name: PathBuf,
}

fn stdin_is_file() -> bool {
    std::fs::metadata("/dev/stdin")
        .map(|m| m.is_file())
        .unwrap_or(false)
}

impl InputArgs {
    /// Headerless PCM from `r` as the `--raw` flags describe it; `as_file`: read as a
    /// file (a NaN is an error), not as a stream (a NaN becomes 0 with a warning).
    fn raw_source(
        &self,
        r: Box<dyn std::io::Read + Send>,
        name: &Path,
        as_file: bool,
    ) -> anyhow::Result<Box<dyn AudioSource>> {
        let (Some(enc), Some(ch), Some(rate)) = (self.raw, self.raw_channels, self.rate) else {
            bail!("--raw needs --raw-channels and --rate")
        };
        let s = RawSource::new(r, enc.into(), ch, rate, name)?;
        Ok(if as_file {
            Box::new(s.as_file())
        } else {
            Box::new(s)
        })
    }

    /// A stream (stdin, a socket): raw PCM with `--raw`, else WAV/FLAC by its first bytes.
    fn stream_source(
        &self,
        r: Box<dyn std::io::Read + Send>,
        name: &Path,
    ) -> anyhow::Result<Box<dyn AudioSource>> {
        if self.raw.is_some() {
            self.raw_source(r, name, false)
        } else {
            Ok(open_stream(r, name)?)
        }
    }

    /// Open the input (for a listening socket: wait for the sender).
    pub fn open(&self, quiet: bool) -> anyhow::Result<Input> {
        let name = PathBuf::from(&self.input);
        let stream = |r, name: &Path| self.stream_source(r, name);
        check_max_buffer(self.max_buffer)?;
        if !(self.connect_timeout.is_finite() && self.connect_timeout >= 0.0) {
            bail!(
                "--connect-timeout must be a number of seconds, 0 or more (got {})",
                self.connect_timeout
            );
        }
        if self.input.is_empty() {
            bail!("the input's name is empty: give a recording (WAV, FLAC), - for standard input, or a network source (see --help)");
        }
        if self.input == "-" {
            let live = !stdin_is_file();
            if self.realtime && live {
                bail!(
                    "--realtime paces a file; a pipe arrives at its writer's pace (give the file's name, \
                     or redirect it: < rec.wav)"
                );
            }
            // `< rec.raw` is a file, as its name would be (a NaN in it is an error).
            let source = if self.raw.is_some() && !live {
                self.raw_source(Box::new(std::io::stdin()), Path::new("-"), true)?
            } else {
                stream(Box::new(std::io::stdin()), Path::new("-"))?
            };
            return Ok(Input {
                source,
                live,
                name: PathBuf::from("standard input"),
            });
        }
        if self.realtime && (self.input.starts_with("tcp:") || self.input.starts_with("tcp-listen:")) {
            bail!("--realtime paces a file; a network source arrives at its sender's pace");
        }
        if let Some(addr) = self.input.strip_prefix("tcp:") {
            let s = super::senders::connect(addr, self.connect_timeout, quiet)
                .with_context(|| format!("{}: connecting", self.input))?;
            return Ok(Input {
                source: stream(Box::new(s), &name)?,
                live: true,
                name,
            });
        }
        if self.keep_listening && !self.input.starts_with("tcp-listen:") {
            bail!("--keep-listening is for a tcp-listen: input (it waits for the next sender)");
        }
        if let Some(addr) = self.input.strip_prefix("tcp-listen:") {
            let l =
                std::net::TcpListener::bind(addr).with_context(|| format!("{}: listening", self.input))?;
            if !quiet {
                eprintln!("soundloc: waiting for a sender on tcp:{}", l.local_addr()?);
            }
            if self.keep_listening {
                let me = self.clone();
                let open: super::senders::Opener =
                    Box::new(move |s, name| me.stream_source(Box::new(s), name));
                let senders = super::senders::Senders::first(l, open, name.clone(), quiet)?;
                return Ok(Input {
                    source: Box::new(senders),
                    live: true,
                    name,
                });
            }
            let (s, peer) = l.accept().with_context(|| format!("{}: accepting", self.input))?;
            if !quiet {
                eprintln!("soundloc: receiving from {peer}");
            }
            return Ok(Input {
                source: stream(Box::new(s), &name)?,
                live: true,
                name,
            });
        }
        let source = if let Some(enc) = self.raw {
            // A regular file is read as one (a NaN or a cut frame is an error naming it);
            // a FIFO as a stream.
            let (Some(ch), Some(rate)) = (self.raw_channels, self.rate) else {
                bail!("--raw needs --raw-channels and --rate")
            };
            Box::new(soundloc::audio::open_raw_file(&name, enc.into(), ch, rate)?)
        } else {
            open_source(&name)?
        };
        Ok(Input {
            source,
            live: false,
            name,
        })
    }
}

/// What the reader thread sends.
pub enum Msg {
    /// Interleaved frames, after `gap` frames were dropped.
    Block { data: Vec<f32>, gap: u64 },
    /// The input ended (after `gap` more dropped frames).
    End { gap: u64 },
    /// `frames` frames of time passed with no input (between two senders), after `lost`
    /// more dropped frames.
    Pause { lost: u64, frames: u64 },
    /// The input failed.
    Failed(soundloc::Error),
    /// Something the user should know about the input.
    Note(String),
    /// A live input turned out to arrive faster than real time: read like a file from now
    /// on (the note says so).
    LikeAFile(String),
}

/// A localizer behind live input catches up: blocks already queued behind the one at hand
/// (`data`) are appended to it while it holds fewer than `max` samples (up to one block
/// more), so their windows run as one batch — fewer passes over the steering vectors. The
/// first message that is not a plain block (a gap, a note, the end, a failure) is put in
/// `held`, to be handled next, in order.
pub fn catch_up(rx: &Queue, data: &mut Vec<f32>, max: usize, held: &mut Option<Msg>) {
    while data.len() < max {
        match rx.try_recv() {
            Ok(Msg::Block { data: more, gap: 0 }) => data.extend_from_slice(&more),
            Ok(other) => {
                *held = Some(other);
                return;
            }
            Err(_) => return,
        }
    }
}

/// Frames per block read from a file.
const FILE_BLOCK: usize = 1 << 15;

/// The reader's queue, bounded in samples of audio (`--max-buffer` seconds for a live
/// input, four file blocks otherwise), not in reads: a socket or pipe read returns what
/// has arrived, one packet of a few milliseconds or a whole block, so a bound in reads
/// would hold anything from a fraction of `--max-buffer` to all of it.
pub struct Queue {
    rx: Receiver<Msg>,
    /// None for a channel bounded by its sender (`listen`'s).
    queued: Option<Arc<AtomicUsize>>,
}

impl Queue {
    /// A channel whose sender bounds it itself (`listen`: blocks of a fixed size).
    #[cfg(feature = "capture")]
    pub fn bounded_by_sender(rx: Receiver<Msg>) -> Self {
        Queue { rx, queued: None }
    }

    /// The next message, waiting for it.
    pub fn recv(&self) -> Result<Msg, RecvError> {
        self.rx.recv().map(|m| self.taken(m))
    }

    /// The next message if one is waiting.
    pub fn try_recv(&self) -> Result<Msg, TryRecvError> {
        self.rx.try_recv().map(|m| self.taken(m))
    }

    fn taken(&self, m: Msg) -> Msg {
        if let (Msg::Block { data, .. }, Some(q)) = (&m, &self.queued) {
            q.fetch_sub(data.len(), Ordering::AcqRel);
        }
        m
    }
}

/// The reader's end of a [`Queue`], holding at most `cap` samples.
struct QueueTx {
    tx: Sender<Msg>,
    queued: Arc<AtomicUsize>,
    cap: usize,
}

impl QueueTx {
    /// A block of `data.len()` samples if it fits (or the queue is empty), else it back.
    fn try_block(&self, data: Vec<f32>, gap: u64) -> Result<Result<(), Vec<f32>>, ()> {
        let n = data.len();
        let before = self.queued.fetch_add(n, Ordering::AcqRel);
        if before > 0 && before + n > self.cap {
            self.queued.fetch_sub(n, Ordering::AcqRel);
            return Ok(Err(data));
        }
        self.tx.send(Msg::Block { data, gap }).map(Ok).map_err(|_| ())
    }

    /// A block, waiting while the queue is full (back-pressure). Err: the receiver is gone.
    fn block(&self, mut data: Vec<f32>, gap: u64) -> Result<(), ()> {
        loop {
            match self.try_block(data, gap)? {
                Ok(()) => return Ok(()),
                Err(d) => data = d,
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }

    /// Anything but a block (notes, the end, a failure): never waits.
    fn send(&self, m: Msg) -> Result<(), ()> {
        self.tx.send(m).map_err(|_| ())
    }
}

/// Longest `--max-buffer` accepted, seconds. The queue holds messages in a list, so only
/// the audio waiting in it takes memory (an hour of 8 channels at 48 kHz is 5.5 GB: a
/// bound a user chooses, not one reserved up front).
pub const MAX_BUFFER_S: f64 = 3600.0;

/// `--max-buffer` above 0 and at most [`MAX_BUFFER_S`].
pub fn check_max_buffer(seconds: f64) -> anyhow::Result<()> {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= MAX_BUFFER_S) {
        bail!("--max-buffer must be a number of seconds above 0 and at most {MAX_BUFFER_S} (an hour), got {seconds}");
    }
    Ok(())
}

/// Start reading `source` on its own thread. Live inputs drop blocks beyond
/// `max_buffer_s` seconds of queued audio (unless they turn out to arrive faster than real
/// time: [`faster_than_real_time`]); `realtime` paces a file at real-time speed.
/// Ctrl-C ends the input of live, paced or `serving` sessions (see [`stop_on_ctrl_c`]).
pub fn spawn_reader(
    mut source: Box<dyn AudioSource>,
    live: bool,
    args: &InputArgs,
    serving: bool,
) -> (AudioFormat, Queue) {
    let (max_buffer_s, realtime) = (args.max_buffer, args.realtime);
    let keep_cut = live || args.allow_truncated;
    let fmt = source.format();
    let block = if live || realtime {
        // ~20 ms blocks: results as soon as their window is complete.
        (fmt.sample_rate_hz as usize / 50).max(1)
    } else {
        FILE_BLOCK
    };
    let cap = if live {
        (max_buffer_s * fmt.sample_rate_hz as f64).ceil() as usize * fmt.channels
    } else {
        4 * block * fmt.channels
    };
    let (tx, rx) = channel();
    if live || realtime || serving {
        stop_on_ctrl_c(EndInput::Queue(tx.clone()));
    }
    let queued = Arc::new(AtomicUsize::new(0));
    let tx = QueueTx {
        tx,
        queued: queued.clone(),
        cap: cap.max(1),
    };
    let pace = (realtime && !live).then_some(fmt.sample_rate_hz as f64);
    let live = live.then_some(max_buffer_s);
    std::thread::spawn(move || reader_loop(&mut *source, &tx, block, live, pace, keep_cut));
    (
        fmt,
        Queue {
            rx,
            queued: Some(queued),
        },
    )
}

/// Whether a live input that has delivered `frames` frames at `rate_hz` in `elapsed` is
/// ahead of real time by more than a quarter of the queue (`max_buffer_s`), and by at
/// least [`AHEAD_S`] or half the queue, whichever is less: a capture is ahead only by what
/// sat in its pipe or socket when the run began (a fraction of a second), so the producer
/// is delivering faster than real time (a file being piped), and waiting for the localizer
/// loses nothing. (Half the queue for queues under 2 s: the queue is full, and this is
/// asked, before a piped file gets further ahead than the queue holds; with a second
/// required a piped file lost most of its audio at `--max-buffer 1`.)
pub fn faster_than_real_time(
    frames: u64,
    rate_hz: u32,
    elapsed: std::time::Duration,
    max_buffer_s: f64,
) -> bool {
    let lead = frames as f64 / rate_hz.max(1) as f64 - elapsed.as_secs_f64();
    lead > (0.25 * max_buffer_s).max(AHEAD_S.min(0.5 * max_buffer_s))
}

/// The least lead over real time that marks a live input as a file in disguise, seconds.
pub const AHEAD_S: f64 = 1.0;

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Whether a Ctrl-C (or SIGTERM, SIGHUP) ended a live session's input.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

/// Block until Ctrl-C (after [`stop_on_ctrl_c`] was installed).
pub fn wait_for_ctrl_c() {
    while !INTERRUPTED.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Where the first Ctrl-C (or SIGTERM, SIGHUP) of a live session sends the end of input.
static STOP: std::sync::Mutex<Option<EndInput>> = std::sync::Mutex::new(None);

/// A live input's queue, to end it with [`Msg::End`].
pub enum EndInput {
    /// [`spawn_reader`]'s queue (bounded in audio, not in messages: sending never blocks).
    Queue(Sender<Msg>),
    /// A bounded channel (`listen`'s), which may be full.
    #[cfg(feature = "capture")]
    Bounded(std::sync::mpsc::SyncSender<Msg>),
}

/// The first interrupt of a live session: end its input. False when none is running.
fn stop_live_session() -> bool {
    let Some(tx) = STOP.lock().unwrap_or_else(|e| e.into_inner()).take() else {
        return false;
    };
    INTERRUPTED.store(true, Ordering::Relaxed);
    match tx {
        EndInput::Queue(tx) => {
            let _ = tx.send(Msg::End { gap: 0 });
        }
        // Never block here: the queue may be full, or nobody reads it any more.
        #[cfg(feature = "capture")]
        EndInput::Bounded(tx) => {
            std::thread::spawn(move || {
                let _ = tx.send(Msg::End { gap: 0 });
            });
        }
    }
    // stderr may be a closed terminal (SIGHUP): never fail on it.
    let _ = writeln!(
        std::io::stderr(),
        "soundloc: stopping (interrupt again to quit at once)"
    );
    true
}

/// Installed once at start, for Ctrl-C (SIGINT), SIGTERM and SIGHUP — those not set to be
/// ignored by whoever started soundloc (`nohup`, a shell's background job). In a live,
/// paced or serving session ([`stop_on_ctrl_c`]) the first one ends the input (what is
/// queued is localized, outputs are completed and `-o` renamed into place); otherwise, or
/// the second time, the temporary files of outputs being written are deleted (their
/// targets keep their old content, or stay absent) and soundloc dies of that signal, as it
/// would have without a handler (so a shell loop stops on Ctrl-C).
#[cfg(unix)]
pub fn install_signal_handler() {
    use signal_hook::consts::signal::{SIGHUP, SIGINT, SIGTERM};
    let ignored = |sig: libc::c_int| {
        // SAFETY: a query (null new action) into a zeroed, caller-owned struct.
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
        }
    };
    let wanted: Vec<libc::c_int> = [SIGINT, SIGTERM, SIGHUP]
        .into_iter()
        .filter(|&s| !ignored(s))
        .collect();
    let Ok(mut signals) = signal_hook::iterator::Signals::new(&wanted) else {
        return;
    };
    let _ = std::thread::Builder::new()
        .name("soundloc-signals".into())
        .spawn(move || {
            for sig in signals.forever() {
                if !stop_live_session() {
                    soundloc::output::atomic::remove_temporary_files();
                    let _ = signal_hook::low_level::emulate_default_handler(sig);
                    std::process::exit(128 + sig);
                }
            }
        });
}

/// Ctrl-C only, elsewhere (see the Unix version).
#[cfg(not(unix))]
pub fn install_signal_handler() {
    let _ = ctrlc::set_handler(|| {
        if !stop_live_session() {
            soundloc::output::atomic::remove_temporary_files();
            std::process::exit(130);
        }
    });
}

/// A live session ends with Ctrl-C (see [`install_signal_handler`]).
pub fn stop_on_ctrl_c(tx: EndInput) {
    *STOP.lock().unwrap_or_else(|e| e.into_inner()) = Some(tx);
}

/// `live`: the input's `--max-buffer` (seconds) where it is live. `keep_cut`: a stream
/// cut short ends with a warning (what arrived is localized) instead of an error.
fn reader_loop(
    source: &mut dyn AudioSource,
    tx: &QueueTx,
    block: usize,
    live: Option<f64>,
    pace_hz: Option<f64>,
    keep_cut: bool,
) {
    let rate = source.format().sample_rate_hz;
    // A pipe, socket or device (even once read like a file).
    let stream = live.is_some();
    // Live until the queue first fills ahead of real time (module docs).
    let mut live = live;
    let mut gap = 0u64;
    let start = std::time::Instant::now();
    let mut frames = 0u64;
    loop {
        if let Some(fs) = pace_hz {
            // A block is handed over once its audio has "been recorded".
            let due = std::time::Duration::from_secs_f64((frames + block as u64) as f64 / fs);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        let mut buf = Vec::new();
        let r = source.read_interleaved(block, &mut buf);
        for n in source.take_notes() {
            if tx.send(Msg::Note(n)).is_err() {
                return;
            }
        }
        let pause = source.take_pause();
        if pause > 0 {
            if tx
                .send(Msg::Pause {
                    lost: gap,
                    frames: pause,
                })
                .is_err()
            {
                return;
            }
            // Real time went on: the lead over it (`faster_than_real_time`) counts it.
            frames += pause;
            gap = 0;
        }
        match r {
            Ok(0) => {
                let _ = tx.send(Msg::End { gap });
                return;
            }
            Ok(n) => {
                frames += n as u64;
                let mut buf = buf;
                if let Some(max_buffer_s) = live {
                    match tx.try_block(buf, gap) {
                        Ok(Ok(())) => {
                            gap = 0;
                            continue;
                        }
                        Ok(Err(b))
                            if gap == 0
                                && faster_than_real_time(frames, rate, start.elapsed(), max_buffer_s) =>
                        {
                            let note = format!(
                                "the input arrives faster than real time ({:.1} s of audio in {:.1} s): read like a file, nothing dropped",
                                frames as f64 / rate.max(1) as f64,
                                start.elapsed().as_secs_f64()
                            );
                            if tx.send(Msg::LikeAFile(note)).is_err() {
                                return;
                            }
                            live = None;
                            buf = b;
                        }
                        Ok(Err(_)) => {
                            gap += n as u64;
                            continue;
                        }
                        Err(()) => return,
                    }
                }
                if tx.block(buf, gap).is_err() {
                    return;
                }
                gap = 0;
            }
            // A file cut short with audio before the cut: the error says how to keep it.
            Err(soundloc::Error::Truncated { path, message }) if !keep_cut && frames > 0 => {
                let hint = format!("{message} (--allow-truncated localizes the audio before the cut)");
                let _ = tx.send(Msg::Failed(soundloc::Error::truncated(path, hint)));
                return;
            }
            Err(e @ soundloc::Error::Truncated { .. }) if keep_cut && frames > 0 => {
                let note = format!(
                    "warning: {e}; the {:.2} s before the cut are localized",
                    frames as f64 / rate.max(1) as f64
                );
                if tx.send(Msg::Note(note)).is_ok() {
                    let _ = tx.send(Msg::End { gap });
                }
                return;
            }
            // A sender that goes away abruptly (a reset connection, a crashed writer) ends a
            // stream as a close would: what arrived is localized and every output completed.
            Err(e) if stream && frames > 0 && connection_lost(&e) => {
                let note =
                    format!("{e}: the sender went away; the input ends here (what arrived is localized)");
                if tx.send(Msg::Note(note)).is_ok() {
                    let _ = tx.send(Msg::End { gap });
                }
                return;
            }
            Err(e) => {
                let _ = tx.send(Msg::Failed(e));
                return;
            }
        }
    }
}

/// Whether a read failed because the other end went away (not because of the data).
fn connection_lost(e: &soundloc::Error) -> bool {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset};
    matches!(e, soundloc::Error::Io { err, .. } if matches!(err.kind(), ConnectionReset | ConnectionAborted | BrokenPipe))
}

#[cfg(test)]
mod tests {
    use super::faster_than_real_time;
    use std::time::Duration;

    #[test]
    fn a_capture_stays_live_and_a_piped_file_does_not() {
        let s = |x: f64| (x * 16000.0) as u64;
        // A capture 30 s in, 0.3 s ahead (what sat in its pipe when the run began).
        assert!(!faster_than_real_time(
            s(30.3),
            16000,
            Duration::from_secs(30),
            10.0
        ));
        // A capture behind a slow localizer: never ahead at all.
        assert!(!faster_than_real_time(
            s(29.0),
            16000,
            Duration::from_secs(30),
            10.0
        ));
        // `cat rec.wav |`: 10 s of audio in 50 ms.
        assert!(faster_than_real_time(
            s(10.0),
            16000,
            Duration::from_millis(50),
            10.0
        ));
        // A piped file behind a localizer slower than real time: 12 s of audio in 2 s.
        assert!(faster_than_real_time(
            s(12.0),
            16000,
            Duration::from_secs(2),
            10.0
        ));
        // The line: a quarter of the queue ahead is still live, a little more is not.
        assert!(!faster_than_real_time(
            s(12.0),
            16000,
            Duration::from_secs(10),
            8.0
        ));
        assert!(faster_than_real_time(
            s(12.1),
            16000,
            Duration::from_secs(10),
            8.0
        ));
        // A small queue: half of it (a capture's start-up backlog of 0.1 s with
        // --max-buffer 0.25 stays live; a file piped into it is read as one, also at
        // --max-buffer 1 and 1.5, where a second was required and the queue was full
        // before the input got that far ahead).
        let ms = Duration::from_millis;
        assert!(!faster_than_real_time(s(0.35), 16000, ms(250), 0.25));
        assert!(faster_than_real_time(s(0.40), 16000, ms(250), 0.25));
        assert!(faster_than_real_time(s(1.0), 16000, ms(1), 0.25));
        assert!(!faster_than_real_time(s(0.45), 16000, ms(1), 1.0));
        assert!(faster_than_real_time(s(0.55), 16000, ms(1), 1.0));
        assert!(faster_than_real_time(s(0.8), 16000, ms(1), 1.5));
        // From 2 s on, a second at least; from 4 s on, a quarter of the queue.
        assert!(!faster_than_real_time(s(0.95), 16000, ms(1), 3.0));
        assert!(faster_than_real_time(s(1.05), 16000, ms(1), 3.0));
    }
}
