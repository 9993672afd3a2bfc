//! The live outputs' arguments and the ODAS message outputs (a TCP server or a file), with
//! the network senders' end-of-run report. [`super::sinks`] drives them.

use anyhow::{bail, Context};
use soundloc::output::atomic::AtomicFile;
use soundloc::output::netsink::NetSender;
use soundloc::output::odas;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use super::localize::note;

/// Live outputs: the browser view and ODAS's JSON messages.
#[derive(clap::Args, Debug, Clone)]
pub struct LiveArgs {
    /// Serve a live view (spectrum, peaks, tracks) to browsers at HOST:PORT, e.g.
    /// 127.0.0.1:8080, or a bare PORT on loopback (port 0 picks one). After the input ends
    /// the view stays up until Ctrl-C.
    #[arg(long, value_name = "[HOST:]PORT")]
    pub serve: Option<String>,
    /// A name browsers use for this machine besides its IP addresses, localhost and its
    /// own host name (repeatable): the live view answers only requests whose Host is one
    /// of these (a page of another site re-pointed at this address is refused).
    #[arg(long, value_name = "NAME", requires = "serve")]
    pub serve_host: Vec<String>,
    /// ODAS SSL messages (potential sources) to a TCP server HOST:PORT (odas_web listens
    /// on 9001; retried while absent, never blocking) or to a file.
    #[arg(long, value_name = "HOST:PORT|FILE")]
    pub odas_ssl: Option<String>,
    /// ODAS SST messages (tracked sources; needs --track) to a TCP server HOST:PORT
    /// (odas_web listens on 9000) or to a file.
    #[arg(long, value_name = "HOST:PORT|FILE")]
    pub odas_sst: Option<String>,
    /// Potential sources per ODAS SSL message (ODAS's nPots).
    #[arg(long, default_value_t = odas::DEFAULT_POTS, requires = "odas_ssl")]
    pub odas_pots: usize,
    /// Track slots per ODAS SST message (ODAS's nTracks).
    #[arg(long, default_value_t = odas::DEFAULT_TRACKS, requires = "odas_sst")]
    pub odas_tracks: usize,
}

/// Where ODAS messages go: `tcp:HOST:PORT` or `HOST:PORT` (a name with no `/` ending in
/// `:digits`) is a TCP server; anything else is a file.
pub(super) enum OdasOut {
    Net(NetSender),
    File(AtomicFile, PathBuf),
}

/// `Some(address)` for a TCP server, `None` for a file. A name with no `/` that has a `:`
/// but is not `HOST:PORT` (`localhost:9000x`, a trailing space, `127.0.0.1:`) is refused,
/// and so is half an address (a bare port `9001`, `localhost`, an IP address): a
/// mistyped address would silently become a file (`--serve 9001` means a port).
pub(super) fn odas_target<'a>(v: &'a str, what: &str) -> anyhow::Result<Option<&'a str>> {
    if let Some(a) = v.strip_prefix("tcp:") {
        return Ok(Some(a));
    }
    match v.rsplit_once(':') {
        Some(_) if v.contains('/') => Ok(None),
        Some((_, port)) if !port.is_empty() && port.bytes().all(|b| b.is_ascii_digit()) => Ok(Some(v)),
        Some(_) => bail!(
            "{what} {v:?}: neither HOST:PORT nor a file name (write tcp:HOST:PORT for a server, ./{v} for a file)"
        ),
        None if v.bytes().all(|b| b.is_ascii_digit())
            || v.eq_ignore_ascii_case("localhost")
            || v.parse::<std::net::IpAddr>().is_ok() =>
        {
            bail!(
                "{what} {v:?}: half an address, not HOST:PORT (write 127.0.0.1:9001 for a server, ./{v} for a file)"
            )
        }
        None => Ok(None),
    }
}

impl OdasOut {
    pub(super) fn open(v: &str, what: &str) -> anyhow::Result<Self> {
        Ok(match odas_target(v, what)? {
            Some(addr) => OdasOut::Net(NetSender::start(what, addr)?),
            None => OdasOut::File(AtomicFile::create(v)?, PathBuf::from(v)),
        })
    }
    pub(super) fn write(&mut self, text: &str) -> anyhow::Result<()> {
        match self {
            OdasOut::Net(n) => n.send(text.as_bytes().to_vec()),
            // A FIFO or device is followed live: each message flushed as it is written.
            OdasOut::File(f, p) => f
                .write_all(text.as_bytes())
                .and_then(|_| if f.is_special() { f.flush() } else { Ok(()) })
                .with_context(|| format!("{}: writing ODAS messages", p.display()))?,
        }
        Ok(())
    }
    pub(super) fn notes(&self) -> Vec<String> {
        match self {
            OdasOut::Net(n) => n.take_notes(),
            OdasOut::File(..) => Vec::new(),
        }
    }
    pub(super) fn finish(self, quiet: bool) -> anyhow::Result<()> {
        match self {
            OdasOut::Net(n) => {
                let what = n.what().to_string();
                let peer = n.peer().to_string();
                let (stats, notes) = n.finish_noted(NET_GRACE);
                for m in notes {
                    note(quiet, &m);
                }
                report(quiet, &what, &peer, stats);
            }
            OdasOut::File(mut f, p) => {
                f.flush()
                    .with_context(|| format!("{}: writing ODAS messages", p.display()))?;
                f.commit()?;
            }
        }
        Ok(())
    }
}

/// How long network outputs may keep sending what is queued once the run ends.
pub(super) const NET_GRACE: Duration = Duration::from_secs(2);

pub(super) fn report(quiet: bool, what: &str, peer: &str, s: soundloc::output::netsink::NetStats) {
    if s.dropped > 0 {
        note(
            quiet,
            &format!(
                "warning: {what}: {} of {} messages to {peer} dropped (receiver absent, gone or too slow)",
                s.dropped,
                s.sent + s.dropped
            ),
        );
    }
}
