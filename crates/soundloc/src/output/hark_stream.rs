//! Live network output in HARK's `HarkDataStreamSender` protocol (source information only).
//!
//! [`HarkStreamSender`] is a TCP client: it connects to a receiver at `host:port` (HARK's
//! default port is [`DEFAULT_PORT`], 5530) and sends one message per localization result.
//! Byte order is little-endian (HARK sends native order; x86-64 is little-endian).
//!
//! A message is a 32-byte header followed by the `SRC_INFO` body:
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | i32 | data-type bit flags: [`SRC_INFO`] (0x4) only |
//! | 4 | i32 | `advance`: frame shift in samples (HARK's `ADVANCE`, 160) |
//! | 8 | i32 | `count`: frame count (the result's STFT frame index by convention) |
//! | 12 | 4 bytes | zero padding (aligns the `timeval` to 8 bytes, as on x86-64) |
//! | 16 | i64 | `tv_sec`: time stamp, seconds since the Unix epoch |
//! | 24 | i64 | `tv_usec`: microseconds, 0 ≤ tv_usec < 1 000 000 |
//! | 32 | i32 | number of sources n |
//! | 36 + 20·s | i32, f32 ×3, f32 | source s: id (−1 when untracked), x, y, z, power (dB) |
//!
//! The header layout (padding after `count`) is inferred from HARK's C struct on x86-64,
//! not verified against a HARK receiver. The other flag bits (MIC_WAVE 0x1, MIC_FFT 0x2,
//! SRC_WAVE 0x8, SRC_FFT 0x10, SRC_FEATURE 0x20, SRC_RELIABILITY 0x40, TEXT 0x80,
//! MATRIX 0x100, VECTOR 0x200) are listed for receivers' reference; only SRC_INFO is sent.
//!
//! Each message is assembled in a buffer and written with one `write_all` (TCP_NODELAY on),
//! so a receiver never sees half a header followed by a stall. The connection is a
//! [`NetSender`]: an absent or vanished receiver is retried, never waited for.

use std::time::{SystemTime, UNIX_EPOCH};

use super::netsink::{NetSender, NetStats};

use crate::error::{Error, Result};
use crate::result::LocalizationResult;

/// HARK's default HarkDataStreamSender port.
pub const DEFAULT_PORT: u16 = 5530;
/// Flag: microphone waveforms.
pub const MIC_WAVE: i32 = 0x1;
/// Flag: microphone spectra.
pub const MIC_FFT: i32 = 0x2;
/// Flag: source information (id, position, power) — the one this sender writes.
pub const SRC_INFO: i32 = 0x4;
/// Flag: separated waveforms.
pub const SRC_WAVE: i32 = 0x8;
/// Flag: separated spectra.
pub const SRC_FFT: i32 = 0x10;
/// Flag: source features.
pub const SRC_FEATURE: i32 = 0x20;
/// Flag: source reliability.
pub const SRC_RELIABILITY: i32 = 0x40;
/// Flag: text.
pub const TEXT: i32 = 0x80;
/// Flag: matrix.
pub const MATRIX: i32 = 0x100;
/// Flag: vector.
pub const VECTOR: i32 = 0x200;
/// Header size in bytes.
pub const HEADER_BYTES: usize = 32;
/// Bytes per source in the SRC_INFO body.
pub const SRC_INFO_BYTES: usize = 20;

/// Appends one message (header + SRC_INFO body) for `result` to `buf`.
///
/// Fails (appending nothing) when an id does not fit in i32 or there are more than
/// i32::MAX sources.
pub fn encode(
    result: &LocalizationResult,
    advance: i32,
    count: i32,
    tv_sec: i64,
    tv_usec: i64,
    buf: &mut Vec<u8>,
) -> Result<()> {
    let n = i32::try_from(result.sources.len()).map_err(|_| {
        Error::Mismatch(format!(
            "hark stream: {} sources do not fit the i32 count",
            result.sources.len()
        ))
    })?;
    let mut ids = Vec::with_capacity(result.sources.len());
    for s in &result.sources {
        let id = match s.id {
            None => -1,
            Some(id) => i32::try_from(id)
                .map_err(|_| Error::Mismatch(format!("hark stream: source id {id} does not fit in i32")))?,
        };
        ids.push(id);
    }
    buf.reserve(HEADER_BYTES + 4 + SRC_INFO_BYTES * result.sources.len());
    buf.extend_from_slice(&SRC_INFO.to_le_bytes());
    buf.extend_from_slice(&advance.to_le_bytes());
    buf.extend_from_slice(&count.to_le_bytes());
    buf.extend_from_slice(&[0u8; 4]);
    buf.extend_from_slice(&tv_sec.to_le_bytes());
    buf.extend_from_slice(&tv_usec.to_le_bytes());
    buf.extend_from_slice(&n.to_le_bytes());
    for (s, id) in result.sources.iter().zip(ids) {
        buf.extend_from_slice(&id.to_le_bytes());
        for v in [s.x, s.y, s.z, s.power_db] {
            buf.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    Ok(())
}

/// A TCP client speaking HarkDataStreamSender's SRC_INFO messages. See the
/// [module docs](self). It never stalls localization: it retries while the receiver is
/// absent, reconnects when it goes away, and drops (and counts) what cannot be sent
/// ([`NetSender`]).
#[derive(Debug)]
pub struct HarkStreamSender {
    net: NetSender,
    advance: i32,
}

/// The receiver's `HOST:PORT` for `--hark-stream` ADDR: HOST alone gets port
/// [`DEFAULT_PORT`]; a bare number is a port, not a host name (it resolved as the IPv4
/// address 0.0.21.154), and is refused, as the ODAS outputs refuse half an address.
pub fn peer_address(addr: &str) -> Result<String> {
    if !addr.is_empty() && addr.bytes().all(|b| b.is_ascii_digit()) {
        return Err(Error::Config(format!(
            "HARK stream {addr:?}: a port without a host; write HOST:PORT (e.g. 127.0.0.1:{addr}), \
             or HOST alone for port {DEFAULT_PORT}"
        )));
    }
    Ok(if addr.contains(':') {
        addr.to_string()
    } else {
        format!("{addr}:{DEFAULT_PORT}")
    })
}

impl HarkStreamSender {
    /// Starts sending to `addr` (`host:port`; a bare host gets [`DEFAULT_PORT`]). `advance`
    /// is the frame shift in samples written into every header. Fails only on an address
    /// that does not resolve.
    pub fn connect(addr: &str, advance: i32) -> Result<Self> {
        Ok(HarkStreamSender {
            net: NetSender::start("HARK stream", &peer_address(addr)?)?,
            advance,
        })
    }

    /// The receiver's address as given (with the default port added when missing).
    pub fn peer(&self) -> &str {
        self.net.peer()
    }

    /// The connection (notes, counts, finishing).
    pub fn net(&self) -> &NetSender {
        &self.net
    }

    /// [`NetSender::close`]: start winding down, `grace` from now.
    pub fn close(&mut self, grace: std::time::Duration) {
        self.net.close(grace);
    }

    /// Stop, sending what is queued within `grace`; the final counts.
    pub fn finish(self, grace: std::time::Duration) -> NetStats {
        self.net.finish(grace)
    }

    /// [`NetSender::finish_noted`].
    pub fn finish_noted(self, grace: std::time::Duration) -> (NetStats, Vec<String>) {
        self.net.finish_noted(grace)
    }

    /// Sends `result` with frame count `count`, time-stamped with the current wall clock.
    pub fn send(&mut self, result: &LocalizationResult, count: i32) -> Result<()> {
        let now = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
        let sec = i64::try_from(now.as_secs()).unwrap_or(i64::MAX);
        self.send_with_timestamp(result, count, sec, i64::from(now.subsec_micros()))
    }

    /// Sends `result` with an explicit `timeval` (e.g. the capture time of its frame).
    /// Fails only when the result cannot be encoded ([`encode`]).
    pub fn send_with_timestamp(
        &mut self,
        result: &LocalizationResult,
        count: i32,
        tv_sec: i64,
        tv_usec: i64,
    ) -> Result<()> {
        // Each message is its own buffer: the sender's queue owns it.
        let mut buf = Vec::new();
        encode(result, self.advance, count, tv_sec, tv_usec, &mut buf)?;
        self.net.send(buf);
        Ok(())
    }
}
