//! `soundloc listen`: localize a live microphone array (cpal; ALSA on Linux). Built with
//! the `capture` feature; without it the command says how to get it.
//!
//! The device's default input configuration is used unless `--rate`/`--channels-in` ask
//! for another; samples reach the localizer on the int16 scale whatever the device's
//! format (float × 32768, i32 / 65536), so dB values compare with 16-bit recordings. The
//! audio callback never waits: blocks beyond `--max-buffer` seconds are dropped and
//! counted (see `cmd::input`). Ctrl-C (or `--seconds`) ends the session cleanly.

use super::run_args::RunArgs;
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture device name (substring match; default: the system's default input).
    #[arg(long)]
    pub input_device: Option<String>,
    /// List capture devices with their default channel count and rate, and exit.
    #[arg(long)]
    pub list_devices: bool,
    /// Capture rate in Hz (default: the device's default).
    #[arg(long)]
    pub rate: Option<u32>,
    /// Capture channels (default: an ODAS --geometry file's raw.nChannels, else the device's default).
    #[arg(long)]
    pub channels_in: Option<u16>,
    /// Audio buffered while the localizer is behind, seconds; beyond it blocks are dropped.
    #[arg(long, default_value_t = 10.0)]
    pub max_buffer: f64,
    /// Stop after this many seconds (default: until interrupted).
    #[arg(long)]
    pub seconds: Option<f64>,
    #[command(flatten)]
    pub run: RunArgs,
}

#[cfg(not(feature = "capture"))]
pub fn run(_a: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!(
        "this soundloc was built without microphone capture: rebuild with `cargo build --release --features capture` \
         (needs libasound2-dev), or pipe a recorder into `soundloc localize -` (e.g. arecord -f S16_LE -t wav)"
    )
}

#[cfg(feature = "capture")]
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    capture::run(a)
}

#[cfg(feature = "capture")]
mod capture {
    use super::super::input::Msg;
    use super::super::localize::drive;
    use super::*;
    use anyhow::{anyhow, bail, Context};
    use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
    use soundloc::audio::AudioFormat;
    use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
    use std::sync::{Arc, Mutex};

    /// Convert and queue one callback's samples; drop (and count) when the queue is full.
    struct Feed {
        tx: SyncSender<Msg>,
        gap: u64,
        channels: usize,
        left: Option<u64>,
    }

    impl Feed {
        fn send(&mut self, data: Vec<f32>) {
            let frames = (data.len() / self.channels) as u64;
            if let Some(l) = &mut self.left {
                if *l == 0 {
                    return;
                }
                if frames >= *l {
                    let keep = *l as usize * self.channels;
                    *l = 0;
                    let _ = self.tx.try_send(Msg::Block {
                        data: data[..keep].to_vec(),
                        gap: self.gap,
                    });
                    let _ = self.tx.send(Msg::End { gap: 0 });
                    return;
                }
                *l -= frames;
            }
            match self.tx.try_send(Msg::Block { data, gap: self.gap }) {
                Ok(()) => self.gap = 0,
                Err(TrySendError::Full(_)) => self.gap += frames,
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
    }

    /// An input stream of sample type `S` whose callback converts with `scale` and queues.
    fn input_stream<S: cpal::SizedSample + Copy + 'static>(
        device: &cpal::Device,
        config: &cpal::StreamConfig,
        feed: &Arc<Mutex<Feed>>,
        on_err: impl FnMut(cpal::StreamError) + Send + 'static,
        scale: fn(S) -> f32,
    ) -> Result<cpal::Stream, cpal::BuildStreamError> {
        let f = feed.clone();
        device.build_input_stream(
            config,
            move |d: &[S], _: &cpal::InputCallbackInfo| {
                if let Ok(mut f) = f.lock() {
                    f.send(d.iter().map(|&v| scale(v)).collect());
                }
            },
            on_err,
            None,
        )
    }

    pub fn run(a: Args) -> anyhow::Result<ExitCode> {
        let host = cpal::default_host();
        if a.list_devices {
            let devices = host.input_devices().context("listing capture devices")?;
            let mut n = 0;
            for d in devices {
                let name = d.name().unwrap_or_else(|_| "?".into());
                match d.default_input_config() {
                    Ok(c) => outln!(
                        "{name}\t{} channels\t{} Hz\t{:?}",
                        c.channels(),
                        c.sample_rate().0,
                        c.sample_format()
                    ),
                    Err(e) => outln!("{name}\t(no default input configuration: {e})"),
                }
                n += 1;
            }
            if n == 0 {
                eprintln!("soundloc: no capture device found");
            }
            return Ok(ExitCode::SUCCESS);
        }
        super::super::sinks::Sinks::check_paths(&a.run, None)?;
        super::super::sinks::Sinks::check_addresses(&a.run)?;
        super::super::input::check_max_buffer(a.max_buffer)?;
        // The arguments' own errors (no array, a bad geometry file or range) before the
        // device's (the rate is the device's; 16 kHz stands in for it here).
        let spec = a.run.spec(a.rate.unwrap_or(16000))?;
        let no_device = || {
            anyhow!("no capture device found (`soundloc listen --list-devices` lists them; on Linux, ALSA's `arecord -l`)")
        };
        let device = match &a.input_device {
            None => host.default_input_device().ok_or_else(no_device)?,
            Some(want) => host
                .input_devices()
                .context("listing capture devices")?
                .find(|d| d.name().map(|n| n.contains(want.as_str())).unwrap_or(false))
                .ok_or_else(|| anyhow!("no capture device named like {want:?} (see --list-devices)"))?,
        };
        let dname = device.name().unwrap_or_else(|_| "capture device".into());
        let def = device.default_input_config().with_context(|| {
            format!(
                "{dname}: cannot capture from it (no input configuration; is a microphone connected? \
                     `soundloc listen --list-devices` lists the devices)"
            )
        })?;
        let mut config: cpal::StreamConfig = def.config();
        if let Some(r) = a.rate {
            config.sample_rate = cpal::SampleRate(r);
        }
        // An array file with a device layout (ODAS's raw.nChannels) asks for the device's
        // channel count, unless --channels-in or --input-channels choose.
        let layout = spec
            .raw_mapping
            .as_ref()
            .filter(|_| spec.input_channels.is_empty())
            .and_then(|r| u16::try_from(r.channels).ok());
        if let Some(c) = a.channels_in.or(layout) {
            config.channels = c;
        }
        let channels = config.channels as usize;
        let rate = config.sample_rate.0;
        // Integer formats first (mic arrays deliver S16/S32; no scaling guesswork).
        let supported: Vec<cpal::SupportedStreamConfigRange> = device
            .supported_input_configs()
            .map(|c| c.collect())
            .unwrap_or_default();
        let fits = |f: cpal::SampleFormat| {
            supported.iter().any(|c| {
                c.sample_format() == f
                    && c.channels() == config.channels
                    && c.min_sample_rate().0 <= rate
                    && rate <= c.max_sample_rate().0
            })
        };
        let format = [
            cpal::SampleFormat::I16,
            cpal::SampleFormat::I32,
            cpal::SampleFormat::F32,
        ]
        .into_iter()
        .find(|&f| fits(f))
        .unwrap_or(def.sample_format());
        let slots = ((a.max_buffer * rate as f64) / 320.0).ceil().max(4.0) as usize;
        let (tx, rx) = sync_channel(slots);
        let feed = Arc::new(Mutex::new(Feed {
            tx: tx.clone(),
            gap: 0,
            channels,
            left: a.seconds.map(|s| (s * rate as f64) as u64),
        }));
        super::super::input::stop_on_ctrl_c(super::super::input::EndInput::Bounded(tx.clone()));
        let err_tx = tx.clone();
        let on_err = move |e: cpal::StreamError| {
            let _ = err_tx.send(Msg::Failed(soundloc::Error::Device(format!("capture: {e}"))));
        };
        // Samples reach the localizer on the int16 scale whatever the device's format.
        let stream = match format {
            cpal::SampleFormat::I16 => input_stream(&device, &config, &feed, on_err, |v: i16| v as f32),
            cpal::SampleFormat::I32 => {
                input_stream(&device, &config, &feed, on_err, |v: i32| v as f32 / 65536.0)
            }
            cpal::SampleFormat::F32 => input_stream(&device, &config, &feed, on_err, |v: f32| v * 32768.0),
            other => bail!("{dname}: unsupported sample format {other:?} (i16, i32 or f32 needed)"),
        }
        .with_context(|| format!("{dname}: opening a {channels}-channel {rate} Hz input"))?;
        stream
            .play()
            .with_context(|| format!("{dname}: starting capture"))?;
        if !a.run.quiet {
            eprintln!("soundloc: listening on {dname} ({channels} channels, {rate} Hz)");
        }
        drop(tx);
        let fmt = AudioFormat {
            sample_rate_hz: rate,
            channels,
            total_frames: None,
        };
        let rx = super::super::input::Queue::bounded_by_sender(rx);
        let code = drive(&a.run, std::path::Path::new(&dname), true, fmt, rx, None);
        drop(stream);
        code
    }
}
